"""Routing-v0's final pull into the clip's slot, across the end of a clip box's top edges (issue 23, edges).

The scripted policy (``RoutingPolicy``) pulls the cable down into the clip's slot at the end of an episode. Until
2026-12-06 a few episodes (seed 2 with Newton's tolerance x1.25, seed 3 with x0.5) ended with the step that threads
the clip also stopped as unstable: the cable crosses the end of a clip box's top edges, and the wraps round them
were kept round the edges' whole lines beyond the box; a node reached the line past the edge's end and the rows blew
up at 1e12 N (docs/concepts/contact.md, "The wrap ends at the edge's end"). This script scales Newton's tolerance
(``NewtonOptions.tolerance``, patched for the run) and prints each episode's end; with ``--trace`` the four largest
contact rows (body, segment nodes, normal force [N], normal, gap [mm]) of the last ``--last`` physics steps.

    python demos/clip_edge_stall.py --seed 2 3 --tolerance 0.5 1 1.25
    python demos/clip_edge_stall.py --seed 2 --tolerance 1.25 --trace
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

from bullet_dlo.core.integrators import NewtonOptions
from bullet_dlo.envs.routing import RoutingEnv, RoutingPolicy


def episode(seed: int, scale: float, trace: bool, last: int) -> None:
    """One scripted episode with Newton's tolerance times ``scale``; prints its end (and the contact rows)."""
    default = NewtonOptions.tolerance
    NewtonOptions.tolerance = lambda self, integrator: scale * default(self, integrator)
    env = RoutingEnv()
    rows: list = []
    try:
        obs, _ = env.reset(seed=seed)
        world, cable = env.physics.world, env.physics.cable

        def record() -> None:
            c = cable.contact_forces()
            top = np.argsort(-c["normal_force"])[:4]
            rows.append((world.time, [(world.bodies.get(int(c["body"][k])), tuple(int(i) for i in c["node"][k]),
                                       float(c["normal_force"][k]), np.round(c["normal"][k], 2).tolist(),
                                       round(1e3 * float(c["gap"][k]), 2)) for k in top]))
            del rows[:-last]

        if trace:
            world.after_step.append(record)
        policy, info, steps = RoutingPolicy(), {}, 0
        for steps in range(1, 251):
            obs, _, terminated, _, info = env.step(policy(obs))
            if terminated:
                break
        print(f"seed {seed}, tolerance x{scale:g}: {steps} env steps, success {info['is_success']}, unstable "
              f"{info['unstable']} ({info['reason']}), wraps {np.degrees(info['wraps']).round(1).tolist()} deg")
        for t, top in rows:
            print(f"  t {t:.4f} s: " + "; ".join(f"{b} {n} {f:.3g} N n {nrm} gap {g} mm" for b, n, f, nrm, g in top))
    finally:
        NewtonOptions.tolerance = default
        env.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, nargs="+", default=[2], help="reset seeds (default 2)")
    parser.add_argument("--tolerance", type=float, nargs="+", default=[1.25],
                        help="factors on Newton's default tolerance, each > 0 (default 1.25)")
    parser.add_argument("--trace", action="store_true", help="print the largest contact rows of the last steps")
    parser.add_argument("--last", type=int, default=8, help="physics steps traced with --trace, >= 1 (default 8)")
    args = parser.parse_args()
    if min(args.tolerance) <= 0 or args.last < 1:
        sys.exit(print("--tolerance must be > 0 and --last >= 1", file=sys.stderr) or 2)
    for seed in args.seed:
        for scale in args.tolerance:
            episode(seed, scale, args.trace, args.last)


if __name__ == "__main__":
    main()
