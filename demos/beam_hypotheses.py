"""Where the beam_handling peak-to-peak misses come from: each hypothesis measured on the nine recordings.

The planar-pair strip (BDF2, n 20, dt 1 ms, damping_rate 0.24 1/s, Franka's filter 4.2 Hz + 6.5 ms) predicts each
recording; per variant of the model the predicted / measured ratios of the most affected joint's 1.5-8 Hz band
peak-to-peak over windows after the motion's end (0-0.5, 0.5-1, 1-2 = the goal's window, 2-3, 4-5 s), of the
damping ratio and of the frequency (damped sine over end + 1-6 s):

* ``base``: the model of ``validate beam`` (the clamp follows the flange path of the measured q);
* ``payload``: plus a clamp payload m J_c^T (a - g) (:func:`~bullet_dlo.reality.beam.payload_torques`), m fitted on
  all nine recordings (:func:`~bullet_dlo.reality.beam_validate.fit_clamp_mass`; per-file values printed);
* ``q+10ms`` / ``q-10ms``: the joint angles shifted in time against the torques (timing of q and tau);
* ``E x0.98``: the strip's E lowered by 2 % (its frequency then matches the measured within 0.5 %);
* ``q_d``: the clamp driven by the desired joints q_d instead of the measured q (no arm reaction to the strip);
* ``compliant`` / ``loop``: the strip on the arm's joint impedance identified on all nine recordings
  (:mod:`bullet_dlo.reality.beam_arm`), substituted about the measured q / in the full loop from q_d.

Then, from the recordings alone: the measured frequency and damping ratio over successive windows (does the
frequency move with the amplitude, as a slipping or yielding clamp would make it?), the damped-sine fit over the
first second (0.15-1.15 s) measured and predicted, the goal's window moved by +-0.2 s, and the arm's tracking
error q - q_d against the joint torques at 3 Hz (how compliant and lossy the arm is while the strip rings).

    python demos/beam_hypotheses.py ../shared/data/beam_handling
"""
from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.signal import csd, welch

from bullet_dlo.reality.beam import (EstimateFilter, Mounting, Numerics, Strip, beam_files, predict_torques,
                                     read_beam_csv)
from bullet_dlo.reality.beam_arm import identify_arm, predict_torques_compliant
from bullet_dlo.reality.beam_validate import fit_clamp_mass, measure
from bullet_dlo.reality.panda import Panda
from bullet_dlo.reality.vibration import band, damping_by_amplitude, fit_damped_sine, residual_vibration, window

ESTIMATE = EstimateFilter(4.2, 0.0065, "the filter identified on the recordings (validate beam)")
DAMPING = {"damping_rate": 0.24}
WINDOWS = ((0.0, 0.5), (0.5, 1.0), (1.0, 2.0), (2.0, 3.0), (4.0, 5.0))  # [s] after the motion's end
SPANS = ((0.5, 1.5), (1.5, 2.5), (2.5, 4.0), (4.0, 5.5), (5.5, 7.0))  # [s] frequency vs amplitude windows


def p2p(t: np.ndarray, y: np.ndarray, t_end: float, a: float, b: float) -> float:
    """Peak-to-peak [N m] of y's 1.5-8 Hz band over [t_end + a, t_end + b]."""
    return float(np.ptp(band(y, 1000.0)[window(t, t_end + a, t_end + b)]))


def shifted(rec, seconds: float):
    """The recording with q delayed by ``seconds`` (held at its first / last value at the edges)."""
    k = int(round(seconds * 1000.0))
    q = np.roll(rec.q, k, axis=0)
    if k > 0:
        q[:k] = rec.q[0]
    elif k < 0:
        q[k:] = rec.q[-1]
    return replace(rec, q=q)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path, help="the beam_handling folder")
    args = ap.parse_args()
    recs = [read_beam_csv(p) for p in beam_files(args.folder)]
    meas = [measure(r) for r in recs]
    numerics = Numerics(strip_model="planes")
    variants = {"base": {}, "q+10ms": {"shift": 0.01}, "q-10ms": {"shift": -0.01},
                "E x0.98": {"strip": Strip(youngs_modulus=0.98 * Strip().youngs_modulus)}, "q_d": {"q_d": True}}
    results = {}
    with Panda() as panda:
        base = []
        for rec, m in zip(recs, meas):
            base.append(predict_torques(rec, panda, Strip(), DAMPING, numerics, ESTIMATE, duration=m.t_end + 6.05))
        mass = fit_clamp_mass(recs, base, panda, numerics, ESTIMATE)
        print(f"clamp payload over the whole recordings, all joints: {mass.value:.3f} kg pooled; per file "
              + ", ".join(f"{k[4:-3]} {v:.2f}" for k, v in mass.per_file.items())
              + f"; band residual {mass.residual_rms_without:.3f} -> {mass.residual_rms_with:.3f} N m")
        variants["payload"] = {"mounting": Mounting(clamp_mass=mass.value)}
        variants["compliant"] = {"arm": "measured"}
        variants["loop"] = {"arm": "desired"}
        impedance = identify_arm(recs)
        for name, v in variants.items():
            preds = []
            for rec, m, b in zip(recs, meas, base):
                if name == "base":
                    preds.append(b)
                    continue
                if "arm" in v:
                    preds.append(predict_torques_compliant(rec, panda, impedance, Strip(), DAMPING, numerics, ESTIMATE,
                                                           duration=m.t_end + 6.05, drive=v["arm"]))
                    continue
                r = shifted(rec, v["shift"]) if "shift" in v else replace(rec, q=rec.q_d.copy()) if "q_d" in v else rec
                preds.append(predict_torques(r, panda, v.get("strip", Strip()), DAMPING, numerics, ESTIMATE,
                                             v.get("mounting", Mounting()), duration=m.t_end + 6.05))
            results[name] = preds
    print("\npredicted / measured: p2p over " + ", ".join(f"{a:g}-{b:g}" for a, b in WINDOWS)
          + " s after the end | damping ratio | frequency")
    for name, preds in results.items():
        print(f"== {name}")
        for rec, m, pred in zip(recs, meas, preds):
            j = m.joint
            pm = [p2p(rec.t, m.dev[:, j], m.t_end, a, b) for a, b in WINDOWS]
            pp = [p2p(pred.t, pred.torques_filtered[:, j], m.t_end, a, b) for a, b in WINDOWS]
            v = residual_vibration(pred.t, pred.torques_filtered[:, j], m.t_end)
            print(f"{rec.name[4:-3]:14s} " + " ".join(f"{b / a:5.2f}" for a, b in zip(pm, pp))
                  + f" | {v.damping_ratio / m.vibration.damping_ratio:5.2f}"
                  + f" | {v.frequency_hz / m.vibration.frequency_hz:6.3f}")
    print("\nmeasured frequency [Hz] and damping ratio over windows " + ", ".join(f"{a:g}-{b:g}" for a, b in SPANS)
          + " s (base model's frequency beside)")
    for rec, m, pred in zip(recs, meas, results["base"]):
        wm = damping_by_amplitude(rec.t, m.dev[:, m.joint], m.t_end, SPANS)
        wp = damping_by_amplitude(pred.t, pred.torques_filtered[:, m.joint], m.t_end, SPANS)
        print(f"{rec.name[4:-3]:14s} f " + " ".join(f"{w['frequency_hz']:.3f}" for w in wm)
              + "  z " + " ".join(f"{w['damping_ratio']:.3f}" for w in wm)
              + "  amplitude " + " ".join(f"{w['amplitude']:.2f}" for w in wm)
              + " | model f " + " ".join(f"{w['frequency_hz']:.3f}" for w in wp))
    print("\nfirst second (0.15-1.15 s) damped sine: measured f, zeta, residual/amplitude | predicted; "
          "goal-window p2p ratio with the window moved by -0.2, 0, +0.2 s")
    for rec, m, pred in zip(recs, meas, results["base"]):
        j = m.joint
        wm, wp = window(rec.t, m.t_end + 0.15, m.t_end + 1.15), window(pred.t, m.t_end + 0.15, m.t_end + 1.15)
        fm, fp = fit_damped_sine(rec.t[wm], m.dev[wm, j]), fit_damped_sine(pred.t[wp], pred.torques_filtered[wp, j])
        moved = [p2p(pred.t, pred.torques_filtered[:, j], m.t_end, 1 + s, 2 + s)
                 / p2p(rec.t, m.dev[:, j], m.t_end, 1 + s, 2 + s) for s in (-0.2, 0.0, 0.2)]
        print(f"{rec.name[4:-3]:14s} {fm[0]:.2f} Hz {fm[1]:.3f} {fm[3] / fm[2]:.2f} | {fp[0]:.2f} Hz {fp[1]:.3f} "
              f"{fp[3] / fp[2]:.2f} | " + " ".join(f"{x:.2f}" for x in moved))
    print("\nthe arm at 3 Hz after the motion (joints 0-4): tracking error q - q_d against tau_J, apparent stiffness "
          "-1/Re(H) [N m/rad] and lag [deg] of H = (q - q_d) / tau_J at the spectral peak of tau_J in 2-4 Hz")
    for rec, m in zip(recs, meas):
        s = slice(m.end + 1000, m.end + 6000)
        row = []
        for j in range(5):
            u, y = band(rec.tau_J[:, j], 1000.0)[s], band(rec.q[:, j] - rec.q_d[:, j], 1000.0)[s]
            f, puy = csd(u, y, fs=1000.0, nperseg=2048)
            _, puu = welch(u, fs=1000.0, nperseg=2048)
            i = int(np.argmax(puu * ((f > 2) & (f < 4))))
            h = puy[i] / puu[i]
            row.append(f"j{j} {-1 / h.real:7.0f} {np.degrees(np.angle(-h)):4.0f}")
        print(f"{rec.name[4:-3]:14s} " + "  ".join(row))


if __name__ == "__main__":
    main()
