"""The planes against the rectangle strip on a recorded motion with a turn of one joint added (``--strip-model auto``).

Takes a beam_handling recording, adds to one joint's measured and desired angle a minimum-jerk turn over the
motion's own span (from dq_d), and predicts the torques on the measured path (rigid clamp, BDF2, n 20, dt 1 ms,
damping_rate 0.28 1/s, the default estimate filter) with the planes and with the rectangle strip. Per turn it prints
the flange's turn out of the weak plane, the band's peak-to-peak over the first 0.5 s after the motion per joint for
both models, and the RMS difference of their filtered torques per joint [N m]. At the beam_handling start pose joint 6
turns the flange about the strip's thickness normal, joint 5 about its axis (both out of the weak plane: the planes
keep their start axes), joint 4 about its width (within it).

    python demos/beam_turn.py ../shared/data/beam_handling/ocp_Z_25cm_0.50s_1.csv --joint 6 --degrees 1 2 4 10 30
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import time

import numpy as np

from bullet_dlo.reality.beam import (Mounting, Numerics, flange_motion, off_plane_turn, predict_torques,
                                     read_beam_csv)
from bullet_dlo.reality.beam_validate import measure, p2p_at_end
from bullet_dlo.reality.panda import Panda
from bullet_dlo.reality.vibration import motion_span

DAMPING = {"damping_rate": 0.28}


def with_turn(rec, joint: int, angle: float):
    """``rec`` with ``angle`` [rad] added to joint ``joint`` (q, q_d and their rates) on a minimum-jerk path over the
    motion's span."""
    s, e = motion_span(rec.dq_d)
    t0, t1 = rec.t[s], rec.t[e]
    u = np.clip((rec.t - t0) / (t1 - t0), 0.0, 1.0)
    path, rate = u**3 * (10 - 15 * u + 6 * u * u), 30 * u**2 * (1 - u) ** 2 / (t1 - t0)
    q, q_d, dq, dq_d = (a.copy() for a in (rec.q, rec.q_d, rec.dq, rec.dq_d))
    for a, b in ((q, path), (q_d, path), (dq, rate), (dq_d, rate)):
        a[:, joint] += angle * b
    return dataclasses.replace(rec, q=q, q_d=q_d, dq=dq, dq_d=dq_d)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("csv", help="a beam_handling recording")
    ap.add_argument("--joint", type=int, default=6, help="the joint turned, 0-6 (6)")
    ap.add_argument("--degrees", type=float, nargs="+", default=[1.0, 10.0], help="the turns added [deg]")
    args = ap.parse_args()
    rec0 = read_beam_csv(args.csv)
    m = measure(rec0)
    with Panda() as panda:
        for deg in args.degrees:
            rec = with_turn(rec0, args.joint, math.radians(deg))
            rot = flange_motion(rec, panda, Numerics(), float(rec.t[-1]))[2]
            print(f"joint {args.joint} + {deg:g} deg: the flange turns "
                  f"{math.degrees(off_plane_turn(rot, Mounting())):.2f} deg out of the weak plane")
            out = {}
            for model in ("planes", "rectangle"):
                tic = time.thread_time()
                out[model] = pred = predict_torques(rec, panda, damping=DAMPING, numerics=Numerics(strip_model=model),
                                                    duration=m.t_end + 2.5)
                p2p = [p2p_at_end(pred.t, pred.torques_filtered[:, j], m.t_end) for j in range(7)]
                print(f"  {model:9s} p2p over end + 0-0.5 s per joint [N m] " + " ".join(f"{v:6.3f}" for v in p2p)
                      + f"  ({time.thread_time() - tic:.1f} CPU s)")
            d = out["planes"].torques_filtered - out["rectangle"].torques_filtered
            print("  RMS planes - rectangle per joint [N m]          " + " ".join(
                f"{v:6.3f}" for v in np.sqrt(np.mean(d**2, axis=0))))


if __name__ == "__main__":
    main()
