"""Steady (shape) error hypotheses for the DEFORM prediction (issue 21): marker placement, the cable's
length, and how much of the error is a steady per-marker offset at all.

    python demos/deform_hypotheses.py ../shared/data/deform/DLO3 --values 0.0750 0.5 0.028

``--values``: EI/(rho A) [m^4/s^2], damping_rate [1/s], internal_damping [s] (``validate deform``'s fit).
It prints, for the eval trials (``--trials``, evenly spread; default all) with the train trials where said:

* the markers' arc lengths: from frame 0 (what ``validate deform`` uses), from each trial's median
  neighbour distances over its 500 frames, from the train trials' median (the cable's), and from the
  90th percentile (the chord is shortest when the cable bends between markers): eval L1 of each;
* the cable's length between the clamps scaled by 0.97 / 0.985 / 1 / 1.015 (all free markers' arc
  lengths scaled with it): eval L1 of each;
* per free marker, the time-mean signed error [mm] along the chord between the clamps / up / sideways,
  its mean over the trials and its spread (a mean large against the spread is a steady shape error);
* the eval L1 with the train trials' mean error per free marker (in the chord/up/side frame) removed:
  the most any steady correction fixed in that frame (a set, a tilted gravity, misplaced markers)
  could gain, learned on train.
"""
from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np

from bullet_dlo.reality import deform as D
from bullet_dlo.reality.recording import MarkerRecording


def chord_frame(rec: MarkerRecording) -> np.ndarray:
    """Unit chord (first to last clamp), up (vertical normal to it), side (chord x up), (k, 3, 3)."""
    a, _ = rec.clamp("first")
    b, _ = rec.clamp("last")
    ch = (b - a) / np.linalg.norm(b - a, axis=1, keepdims=True)
    up = np.array([0.0, 0.0, 1.0]) - ch[:, 2:3] * ch
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    return np.stack([ch, up, np.cross(ch, up)], axis=1)


def in_chord_frame(rec: MarkerRecording, pred: np.ndarray) -> np.ndarray:
    """The free markers' error [m] (k, f, 3) along chord / up / side."""
    return np.einsum("kmj,kaj->kma", (pred - rec.markers)[:, rec.free], chord_frame(rec))


def scaled_length(rec: MarkerRecording, factor: float) -> MarkerRecording:
    """``rec`` with the arc lengths between the inner held markers scaled by ``factor`` (the held pairs kept)."""
    i0, i1 = rec.first_pair[1] % rec.n_markers, rec.last_pair[0] % rec.n_markers
    s = rec.s.copy()
    s[i0:i1 + 1] = s[i0] + factor * (rec.s[i0:i1 + 1] - rec.s[i0])
    s[i1 + 1:] = s[i1] + rec.s[i1 + 1:] - rec.s[i1]
    return replace(rec, s=s)


def mean_l1(recs: list[MarkerRecording], values: dict[str, float], num: D.Numerics) -> float:
    return float(np.mean([D._l1_or_nan(D.predict(r, values, num)[0], r) for r in recs]))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("dlo_dir")
    p.add_argument("--values", nargs=3, type=float, required=True, metavar=("EI_PER_RHOA", "DAMPING_RATE", "TAU"))
    p.add_argument("--trials", type=int, help="eval trials, evenly spread (default: all)")
    p.add_argument("--train-trials", type=int, default=8, help="train trials, evenly spread (8)")
    args = p.parse_args()
    values = dict(zip(D.PARAMETERS, args.values))
    num = D.Numerics()
    root = Path(args.dlo_dir)
    train = [D.load_trial(f) for f in D.pick(D.trial_files(root / "train", "train"), args.train_trials)]
    evals = [D.load_trial(f) for f in D.pick(D.trial_files(root / "eval", "eval"), args.trials)]

    gaps = lambda r: np.linalg.norm(np.diff(r.markers, axis=1), axis=2)
    cable = np.median([np.median(gaps(r), axis=0) for r in train], axis=0)
    variants = {
        "frame 0": lambda r: r,
        "trial median": lambda r: replace(r, s=np.r_[0.0, np.cumsum(np.median(gaps(r), axis=0))]),
        "train median": lambda r: replace(r, s=np.r_[0.0, np.cumsum(cable)]),
        "90th percentile": lambda r: replace(r, s=np.r_[0.0, np.cumsum(np.percentile(gaps(r), 90, axis=0))]),
    }
    print("arc lengths from: " + ", ".join(f"{k} {1e3 * mean_l1([f(r) for r in evals], values, num):.2f} mm"
                                            for k, f in variants.items()))
    print("length x " + ", ".join(f"{x}: {1e3 * mean_l1([scaled_length(r, x) for r in evals], values, num):.2f} mm"
                                  for x in (0.97, 0.985, 1.0, 1.015)))

    preds = [D.predict(r, values, num)[0] for r in evals]
    steady = np.array([in_chord_frame(r, q).mean(axis=0) for r, q in zip(evals, preds)])  # (trials, f, 3)
    size = np.array([np.abs(in_chord_frame(r, q)).mean(axis=0) for r, q in zip(evals, preds)])
    for a, name in enumerate(("chord", "up", "side")):
        print(f"{name:5} time-mean signed error per free marker [mm]: "
              f"{' '.join(f'{x:+.1f}' for x in 1e3 * steady[:, :, a].mean(axis=0))}; spread "
              f"{' '.join(f'{x:.1f}' for x in 1e3 * steady[:, :, a].std(axis=0))}; mean |error| "
              f"{' '.join(f'{x:.1f}' for x in 1e3 * size[:, :, a].mean(axis=0))}")

    offset = np.mean([in_chord_frame(r, D.predict(r, values, num)[0]).mean(axis=0) for r in train], axis=0)
    before, after = [], []
    for r, q in zip(evals, preds):
        fixed = q.copy()
        fixed[:, r.free] -= np.einsum("ma,kaj->kmj", offset, chord_frame(r))
        before.append(D.l1(q, r))
        after.append(D.l1(fixed, r))
    print(f"eval L1 {1e3 * np.mean(before):.2f} mm; with the train trials' mean error per free marker removed "
          f"{1e3 * np.mean(after):.2f} mm (better in {int(np.sum(np.array(after) < np.array(before)))} of {len(evals)} trials)")


if __name__ == "__main__":
    main()
