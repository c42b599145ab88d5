"""The beam_handling strip's damping against its vibration amplitude, and the rectangle strip's step.

Damping: the measured damping ratio over successive windows after each motion
(:func:`bullet_dlo.reality.vibration.damping_by_amplitude`) against the strip's tip amplitude, which the
torque does not show directly: each recording's predicted torque amplitude per predicted tip amplitude
(planar-pair model, 1 ms, damping_rate 0.24 1/s) converts the measured torque amplitude into a tip
amplitude. A straight line zeta = zeta0 + k A is fitted over all windows; quadratic air drag on the strip's
face gives k = 2 rho_air C_d kappa / (3 pi rho_s t) (:func:`~bullet_dlo.reality.vibration.drag_damping_ratio`),
so k says which drag coefficient C_d the data ask for.

Step (``--dt-check FILE``): the rectangle strip's band-passed torque peak-to-peak on one recording at
dt 1, 0.5, 0.25 and 0.1 ms against the planar pair's (BDF2 solves the twist in its Newton step: converged at 1 ms).

    python demos/beam_damping.py ../shared/data/beam_handling
    python demos/beam_damping.py ../shared/data/beam_handling --dt-check ocp_Z_15cm_0.42s_1
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from bullet_dlo.reality.beam import (EstimateFilter, Mounting, Numerics, Strip, beam_files, predict_torques,
                                     read_beam_csv)
from bullet_dlo.reality.beam_validate import measure, predicted_vibration
from bullet_dlo.reality.panda import Panda
from bullet_dlo.reality.vibration import damping_by_amplitude, drag_damping_ratio, fit_damped_sine, window

ESTIMATE = EstimateFilter(4.2, 0.0065, "the filter identified on the recordings (validate beam)")
DAMPING = {"damping_rate": 0.24}
SPANS = ((1.0, 2.5), (2.5, 4.0), (4.0, 5.5), (5.5, 7.0), (7.0, 9.0))  # [s] after the motion's end


def torque_per_tip(rec, m, panda: Panda) -> float:
    """Predicted torque amplitude on the measured joint per tip amplitude along the strip's normal [N m / m]."""
    pred = predict_torques(rec, panda, damping=DAMPING, numerics=Numerics(strip_model="planes"), estimate=ESTIMATE,
                           duration=m.t_end + 6.05)
    normal = Mounting().axes(panda.flange_path(rec.q[:1])[1][0])[2]
    y = (pred.tip - pred.tip[0]) @ normal
    w = window(pred.t, m.t_end + 1.0, m.t_end + 6.0)
    tip_amp = fit_damped_sine(pred.t[w], y[w] - y[w].mean())[2]
    return predicted_vibration(pred, m).amplitude / tip_amp


def damping_vs_amplitude(folder: Path) -> None:
    strip = Strip()
    rows = []
    with Panda() as panda:
        for path in beam_files(folder):
            rec = read_beam_csv(path)
            m = measure(rec)
            ratio = torque_per_tip(rec, m, panda)
            for w in damping_by_amplitude(rec.t, m.dev[:, m.joint], m.t_end, SPANS):
                decay = w["damping_ratio"] * 2 * math.pi * w["frequency_hz"] * (w["to_s"] - w["from_s"]) / 2
                rows.append((rec.name, w["from_s"], w["amplitude"] * math.exp(-decay) / ratio, w["damping_ratio"]))
                print(f"{rec.name:24s} {w['from_s']:4.1f}-{w['to_s']:3.1f} s  tip amplitude {1e3 * rows[-1][2]:5.1f} mm"
                      f"  damping ratio {w['damping_ratio']:.4f}")
    amp, zeta = np.array([r[2] for r in rows]), np.array([r[3] for r in rows])
    keep = zeta < 0.05  # one window (Xup_35cm, 1-2.5 s) still carries the motion's transient
    (zeta0, slope), *_ = np.linalg.lstsq(np.c_[np.ones(keep.sum()), amp[keep]], zeta[keep], rcond=None)
    per_cd = drag_damping_ratio(1.0, 1.0, strip)
    print(f"\n{keep.sum()} windows: zeta = {zeta0:.4f} + {slope:.3f} A_tip [m] (r = "
          f"{np.corrcoef(amp[keep], zeta[keep])[0, 1]:.2f}), tip amplitudes {1e3 * amp[keep].min():.1f}-"
          f"{1e3 * amp[keep].max():.1f} mm")
    print(f"quadratic face drag: zeta = {per_cd:.4f} C_d A_tip; the slope asks for C_d = {slope / per_cd:.1f}")
    for a in (0.005, 0.01, 0.02, 0.04):
        kc = 2 * math.pi * a / strip.width
        cd = 8.0 * kc ** (-1 / 3)
        print(f"  A_tip {1e3 * a:4.0f} mm: KC {kc:.2f}, C_d = 8 KC^-1/3 = {cd:.1f} -> drag zeta "
              f"{drag_damping_ratio(cd, a, strip):.4f}; measured excess over zeta0 {slope * a:.4f}")


def dt_check(folder: Path, stem: str) -> None:
    from bullet_dlo.reality.vibration import band

    rec = read_beam_csv(folder / f"{stem}.csv")
    m = measure(rec)
    with Panda() as panda:
        for model, dt in (("planes", 1e-3), ("rectangle", 1e-3), ("rectangle", 5e-4), ("rectangle", 2.5e-4),
                          ("rectangle", 1e-4)):
            pred = predict_torques(rec, panda, damping=DAMPING, numerics=Numerics(strip_model=model, dt=dt),
                                   estimate=ESTIMATE, duration=m.t_end + 2.05)
            w = window(pred.t, m.t_end + 1.0, m.t_end + 2.0)
            p2p = np.ptp(band(pred.torques_filtered[:, m.joint], 1000.0)[w])
            print(f"{model:9s} dt {dt:.2e} s: torque p2p (joint {m.joint}, 1.5-8 Hz, end + 1-2 s) {p2p:.3f} N m, "
                  f"{pred.cpu_s:.1f} CPU s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", type=Path, help="folder of beam_handling *.csv recordings")
    parser.add_argument("--dt-check", metavar="STEM", help="compare the strip models' step on this recording")
    args = parser.parse_args()
    if args.dt_check:
        dt_check(args.folder, args.dt_check)
    else:
        damping_vs_amplitude(args.folder)


if __name__ == "__main__":
    main()
