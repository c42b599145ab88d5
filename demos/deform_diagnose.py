"""Where the DEFORM prediction errs (issue 21): by direction, over time, after restarts, at the grip, along the cable.

    python demos/deform_diagnose.py ../shared/data/deform/DLO2 --values 0.0742 0.5 0.026 --trials 4

``--values``: EI/(rho A) [m^4/s^2], damping_rate [1/s], internal_damping [s] (e.g. the fitted ones of
``bullet-dlo validate deform``). For a few eval trials it prints:

* the free markers' mean absolute error [mm] along the chord between the clamps, up (vertical, normal to the
  chord) and sideways (horizontal, normal to the chord), and per second of the 5 s;
* restarts: the model started from the measured state at frames 0, 50, ..., 350 and its error after
  0.05 / 0.1 / 0.2 / 0.5 s (an error that is there within 0.1-0.2 s is the model's shape or forcing, not
  a drift);
* the angle [deg] between the held pair's direction and the cable's tangent at the inner held marker
  (spline through the markers), in the pair's parallel-transported frame: mean and spread;
* the mean turning angle [deg] between marker chords at every free marker, measured minus model, and its
  spread over the trials (a consistent excess is a set the straight model lacks).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

from bullet_dlo.reality import deform as D
from bullet_dlo.reality.recording import MarkerRecording


def chord_axes(rec: MarkerRecording) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit chord (first to last clamp), up (vertical normal to it), side (chord x up), each (k, 3)."""
    a, _ = rec.clamp("first")
    b, _ = rec.clamp("last")
    ch = (b - a) / np.linalg.norm(b - a, axis=1, keepdims=True)
    up = np.array([0.0, 0.0, 1.0]) - ch[:, 2:3] * ch
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    return ch, up, np.cross(ch, up)


def grip_angles(rec: MarkerRecording) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per end: mean and spread [deg] of the tangent's two angles off the pair direction."""
    out = []
    for end, pair in (("first", rec.first_pair), ("last", rec.last_pair)):
        _, d = D.cleaned(rec, pair, 5).clamp(end)
        frames = D.transported_frames(d).as_matrix()
        i = pair[1] % rec.n_markers if end == "first" else pair[0] % rec.n_markers
        idx = np.arange(i - 1, i + 4) if end == "first" else np.arange(i - 3, i + 2)
        tang = np.array([CubicSpline(rec.s[idx], rec.markers[k, idx], axis=0)(rec.s[i], 1) for k in range(len(rec.t))])
        comp = np.einsum("kji,kj->ki", frames, tang / np.linalg.norm(tang, axis=1, keepdims=True))
        ang = np.degrees(np.arctan2(comp[:, 1:], comp[:, :1]))
        out.append((ang.mean(axis=0), ang.std(axis=0)))
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("dlo_dir")
    p.add_argument("--values", nargs=3, type=float, required=True, metavar=("EI_PER_RHOA", "DAMPING_RATE", "TAU"))
    p.add_argument("--trials", type=int, default=4, help="eval trials, evenly spread (4)")
    args = p.parse_args()
    values = dict(zip(D.PARAMETERS, args.values))
    num = D.Numerics()
    evals = [D.load_trial(f) for f in D.pick(D.trial_files(Path(args.dlo_dir) / "eval", "eval"), args.trials)]
    horizons = (5, 10, 20, 50)
    restart = {h: [] for h in horizons}
    turn = []
    for rec in evals:
        pred, _ = D.predict(rec, values, num)
        e = (pred - rec.markers)[:, rec.free]
        axes = chord_axes(rec)
        comp = [1e3 * np.abs(np.einsum("kmj,kj->km", e, a)).mean() for a in axes]
        per_s = [1e3 * np.abs(e[i:i + 100]).mean() for i in range(0, len(rec.t) - 1, 100)]
        print(f"trial {rec.name}: L1 {1e3 * D.l1(pred, rec):.1f} mm; free markers chord/up/side "
              f"{comp[0]:.1f}/{comp[1]:.1f}/{comp[2]:.1f} mm; per second {' '.join(f'{x:.1f}' for x in per_s)} mm")
        for (mean, sd), end in zip(grip_angles(rec), ("first", "last")):
            print(f"  {end} grip: tangent off the pair {mean.round(1)} +- {sd.round(1)} deg")
        for k in range(0, 400, 50):
            sub = MarkerRecording(rec.name, rec.t[k:k + 51] - rec.t[k], rec.markers[k:k + 51], rec.s)
            sp, _ = D.predict(sub, values, num)
            for h in horizons:
                restart[h].append(np.abs(sp[h] - sub.markers[h])[sub.free].mean())
        cols = rec.free - 1
        turn.append(np.degrees(D.turning_angles(rec.markers)[:, cols].mean(axis=0)
                               - D.turning_angles(pred)[:, cols].mean(axis=0)))
    print("restarts from the measured state, error after " + ", ".join(
        f"{h / 100:.2f} s: {1e3 * np.mean(restart[h]):.1f} mm" for h in horizons))
    t = np.array(turn)
    print("mean turning at the free markers, measured - model [deg]: " + " ".join(f"{x:+.1f}" for x in t.mean(axis=0)))
    print("  spread over trials [deg]:                                 " + " ".join(f"{x:.1f}" for x in t.std(axis=0)))


if __name__ == "__main__":
    main()
