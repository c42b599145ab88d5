"""A cable resting over a box edge at 1 kHz: Newton iterations and failures per step (docs/concepts/contact.md,
the caps' fixed point). An independent check's case (0.8 m, 6 mm, 24 g, n 11, 65 % hanging, friction 1.06: it
holds); before 2026-12-04 its solves cycled between two friction caps of the edge-wrap row and the resting cable
was stopped as "contact Newton stalled far from convergence".

    python demos/edge_stall.py
    python demos/edge_stall.py --mu 0.9 1.0 1.1 --hz 240 1000 --seconds 2
"""
from __future__ import annotations

import argparse
import math

import numpy as np

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.model import CableState
from bullet_dlo.core.spec import CableSpec

TABLE = (0.6, 0.15, 0.1)  # [m] half extents; top face at z = 0, the edge along y at x = 0


def draped(spec: CableSpec, hanging: float, place: float) -> np.ndarray:
    """Nodes (n, 3) draped over the edge at rest length, about ``hanging`` of the cable beyond it, the last node on
    the table ``place`` segments before the edge, the segment across it wrapped round the edge."""
    n, L, l, r = spec.n_masses, spec.length, spec.rest_length, spec.diameter / 2
    a = place * l
    i = round(((1.0 - hanging) * L - a) / l)
    depth = l - a - r * math.pi / 2
    return np.array([(-a - (i - j) * l, 0.0, r) if j <= i else (r, 0.0, -depth - (j - i - 1) * l) for j in range(n)])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mu", type=float, nargs="+", default=[1.0555621339364663, 1.0])
    parser.add_argument("--hz", type=float, nargs="+", default=[1000.0])
    parser.add_argument("--n", type=int, default=11)
    parser.add_argument("--hanging", type=float, default=0.65)
    parser.add_argument("--seconds", type=float, default=2.0)
    args = parser.parse_args()
    for hz in args.hz:
        for mu in args.mu:
            spec = CableSpec(length=0.8, diameter=0.006, mass=0.024, youngs_modulus=4e6, n_masses=args.n,
                             dynamic_friction=mu, static_friction=mu)
            x0 = draped(spec, args.hanging, 0.6)
            with BulletWorld(dt=1.0 / hz, ground=False) as world:
                world.add_box(TABLE, (-TABLE[0], 0.0, -TABLE[2]), friction=mu)
                cable = world.add_cable(spec, state=CableState(x0.copy(), np.zeros_like(x0)))
                cable.set_parameters(damp=5.0 * cable.model.arrays.mass)
                steps = round(args.seconds * hz)
                for _ in range(steps):
                    world.step()
                    if not cable.stable:
                        break
                s = cable.solver
                state = "stable" if cable.stable else f"stopped at {cable.time_to_instability:.3g} s ({cable.reason})"
                print(f"{hz:6.0f} Hz, mu {mu:.4f}: {state}; Newton failed {s.newton_failures} of {s.steps_planned} "
                      f"solves, {s.newton_iterations / max(s.steps_planned, 1):.1f} iterations a step; table end "
                      f"moved {1e3 * (cable.x[0, 0] - x0[0, 0]):.2f} mm", flush=True)


if __name__ == "__main__":
    main()
