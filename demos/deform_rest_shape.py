"""A curved rest shape for a DEFORM cable (issue 21): fitted on train from given straight-model parameters,
eval L1 with and without it, every eval trial.

    python demos/deform_rest_shape.py ../shared/data/deform/DLO2 --values 0.0742 0.5 0.026

``--values``: EI/(rho A) [m^4/s^2], damping_rate [1/s], internal_damping [s] of the straight model (the
optimum ``bullet-dlo validate deform`` reports); from there :func:`bullet_dlo.reality.deform.fit_rest_shape`
fits the rest curvature at the free markers' places and then the three parameters again, on
``--train`` trials (8) with about ``--max-evaluations`` runs of the set (60). This is what
``bullet-dlo validate deform DLO_DIR --json OUT --rest-shape`` does after its own straight fit.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from bullet_dlo.reality import deform as D


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("dlo_dir")
    p.add_argument("--values", nargs=3, type=float, required=True, metavar=("EI_PER_RHOA", "DAMPING_RATE", "TAU"))
    p.add_argument("--train", type=int, default=8)
    p.add_argument("--max-evaluations", type=int, default=60)
    args = p.parse_args()
    root = Path(args.dlo_dir)
    values = dict(zip(D.PARAMETERS, args.values))
    num = D.Numerics()
    train = [D.load_trial(f) for f in D.pick(D.trial_files(root / "train", "train"), args.train)]
    evals = [D.load_trial(f) for f in D.trial_files(root / "eval", "eval")]
    tic = time.thread_time()
    rest, f, info = D.fit_rest_shape(train, values, num, max_evaluations=args.max_evaluations)
    print(f"{root.name}: rest curvature [1/m] {' '.join(f'{k:.2f}' for k in rest.kappa)} at sigma "
          f"{' '.join(f'{s:.2f}' for s in rest.sigma)}; parameters {({k: round(v, 4) for k, v in f.values.items()})}; "
          f"{info['evaluations']} runs of the train set, {time.thread_time() - tic:.0f} CPU s")
    for name, recs in (("train", train), ("eval", evals)):
        straight = [D.l1(D.predict(r, values, num)[0], r) for r in recs]
        curved = [D.l1(D.predict(r, f.values, num, rest=rest)[0], r) for r in recs]
        print(f"{name} L1 [mm]: straight {1e3 * np.mean(straight):.2f}, rest shape {1e3 * np.mean(curved):.2f}")
        print("  per trial straight   " + " ".join(f"{1e3 * x:5.1f}" for x in straight))
        print("  per trial rest shape " + " ".join(f"{1e3 * x:5.1f}" for x in curved))


if __name__ == "__main__":
    main()
