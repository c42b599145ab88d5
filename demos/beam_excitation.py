"""What the beam_handling motions leave in the strip's first mode: the path, the window, the initial state.

For each recording (the motion's end from dq_d, the most affected joint, as ``validate beam``):

* ``R`` [mm]: the first-mode amplitude that the flange path leaves at the motion's end
  (:func:`~bullet_dlo.reality.vibration.residual_excitation`: the normal motion of the strip point 0.7264 L from the
  clamp, which carries the translation and the rotation's lever), undamped, at the measured frequency and at
  +-1 % of it, from the measured q, from q low-passed at 40 Hz (the model's path) and from the desired q_d;
* ``A_end`` [N m]: the measured vibration's amplitude at the end, the damped sine fitted over end + 1-6 s
  extrapolated back (its damping ratio); the same for the model (the rigid clamp on the measured path, planes,
  BDF2, n 20, dt 1 ms, damping_rate 0.24 1/s, Franka's filter 4.2 Hz + 6.5 ms);
* ``gain``: A_end per R of the model (its own frequency and damping ratio) and of the recording (measured frequency,
  damping ratio zeta_m during the motion 0, 0.01, 0.02, 0.03); ``real / model``: their ratio. A linear strip on the
  measured path has ``real / model`` 1 whatever the path; where it is not 1 the real strip did not get the
  excitation the measured path implies;
* the initial state: the torque deviation's range over the rest before the motion (a ringing strip would show);
* the level measure: the goal's band peak-to-peak (end + 1-2 s) over twice the fitted sine's amplitude at end + 1.5 s.

    python demos/beam_excitation.py ../shared/data/beam_handling
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from bullet_dlo.reality.beam import (EstimateFilter, Mounting, Numerics, Strip, beam_files, low_passed_q,
                                     predict_torques, read_beam_csv)
from bullet_dlo.reality.beam_validate import measure, predicted_vibration
from bullet_dlo.reality.panda import Panda
from bullet_dlo.reality.vibration import MODE_FORCING_LEVER, residual_excitation

ESTIMATE = EstimateFilter(4.2, 0.0065, "the filter identified on the recordings (validate beam)")
DAMPING = {"damping_rate": 0.24}
ZETA_MOTION = (0.0, 0.01, 0.02, 0.03)


def mode_forcing_path(panda: Panda, q: np.ndarray, mounting: Mounting, length: float) -> np.ndarray:
    """Normal displacement [m] (k,) of the strip point MODE_FORCING_LEVER * length from the clamp along the flange
    path of joint angles q (k, 7), projected on the strip's normal at rest (q[0])."""
    pos, rot = panda.flange_path(q)
    clamp = mounting.clamp_point(pos, rot)
    axis = np.array([mounting.axes(r)[0] for r in rot])
    normal0 = mounting.axes(rot[0])[2]
    return (clamp + MODE_FORCING_LEVER * length * axis) @ normal0


def amplitude_at_end(v, t_end_offset: float = 1.0) -> float:
    """The fitted sine's amplitude extrapolated from end + 1 s back to the end [N m]."""
    return v.amplitude * np.exp(v.damping_ratio * 2 * np.pi * v.frequency_hz * t_end_offset)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path, help="the beam_handling folder")
    args = ap.parse_args()
    strip, mounting, numerics = Strip(), Mounting(), Numerics(strip_model="planes")
    print("R [mm] at f_meas x (1, 1.01, 0.99): q | q 40 Hz | q_d;  A_end [N m] measured, model;  "
          "real/model gain at zeta_m " + ", ".join(f"{z:g}" for z in ZETA_MOTION)
          + ";  rest range [N m];  p2p / 2A")
    with Panda() as panda:
        for p in beam_files(args.folder):
            rec = read_beam_csv(p)
            m = measure(rec)
            rows = slice(0, m.end + 1)
            t = rec.t[rows]
            f = m.vibration.frequency_hz
            paths = {"q": rec.q, "q40": low_passed_q(rec, numerics), "q_d": rec.q_d}
            x = {k: mode_forcing_path(panda, q[rows], mounting, strip.length) for k, q in paths.items()}
            r = {k: [residual_excitation(t, x[k], m.t_end, f * s) for s in (1.0, 1.01, 0.99)] for k in x}
            pred = predict_torques(rec, panda, strip, DAMPING, numerics, ESTIMATE, mounting, duration=m.t_end + 6.05)
            pv = predicted_vibration(pred, m)
            a_meas, a_pred = amplitude_at_end(m.vibration), amplitude_at_end(pv)
            gain_model = a_pred / residual_excitation(t, x["q40"], m.t_end, pv.frequency_hz, pv.damping_ratio)
            real = [a_meas / residual_excitation(t, x["q"], m.t_end, f, z) / gain_model for z in ZETA_MOTION]
            rest = float(np.ptp(m.dev[:m.start, m.joint]))
            a15 = m.vibration.amplitude * np.exp(-m.vibration.damping_ratio * 2 * np.pi * f * 0.5)
            print(f"{rec.name[4:-3]:15s} j{m.joint} f {f:.3f} | "
                  + " | ".join(" ".join(f"{v * 1e3:5.1f}" for v in r[k]) for k in ("q", "q40", "q_d"))
                  + f" | A_end {a_meas:.3f} {a_pred:.3f} | real/model " + " ".join(f"{v:4.2f}" for v in real)
                  + f" | rest {rest:.3f} | p2p/2A {m.vibration.p2p_torque / (2 * a15):.2f}")


if __name__ == "__main__":
    main()
