"""A cable laid across pybullet_data's duck mesh (duck.obj scaled 0.08, a static body made with PyBullet's own
createCollisionShape: its convex hull, or with --concave the triangle mesh), on the ground: every 0.5 s the range of
the supports over the cable's weight, its largest speed and kinetic energy (docs/concepts/contact.md, "A cable on a
finely faceted hull"). A cable at rest reads 1.0000 and a kinetic energy that decays to nothing: the hull does from
2-2.5 s on, on the hull and on the triangle mesh.

    python demos/cable_on_duck.py
    python demos/cable_on_duck.py --hz 60 240 1000 --n 12 33 --seconds 4 --concave
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "bullet"))
from test_fine_hull import add_mesh, lay_across  # noqa: E402  (the tests' duck and cable placement)


def duck(world: BulletWorld, concave: bool) -> int:
    """pybullet_data's duck scaled 0.08 (its hull, or its triangle mesh if ``concave``), a static body on its side."""
    return add_mesh(world, "duck.obj", 0.08, concave)


def run(hz: float, n: int, seconds: float, concave: bool) -> None:
    spec = CableSpec.lv2017(n_masses=n, damping=0.02)
    with BulletWorld(dt=1.0 / hz, ground=True) as world:
        cable = lay_across(world, duck(world, concave), spec)
        weight = spec.mass * 9.81
        print(f"{'concave' if concave else 'hull'}, n {n}, {hz:.0f} Hz:")
        for k in range(round(seconds / 0.5)):
            sup, ke = [], []
            for _ in range(round(0.5 * hz)):
                world.step()
                sup.append(float(cable.contact_forces()["force"][:, 2].sum()) / weight)
                ke.append(0.5 * float((cable.model.arrays.mass[:, None] * cable.v ** 2).sum()))
            print(f"  t {0.5 * (k + 1):4.1f} s: supports {min(sup):.4f}-{max(sup):.4f} of the weight, largest speed "
                  f"{np.abs(cable.v).max():.2e} m/s, kinetic energy up to {max(ke):.2e} J, "
                  f"{'stable' if cable.stable else cable.reason}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hz", type=float, nargs="+", default=[240.0])
    parser.add_argument("--n", type=int, nargs="+", default=[33])
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--concave", action="store_true", help="the triangle mesh instead of its convex hull")
    args = parser.parse_args()
    for hz in args.hz:
        for n in args.n:
            run(hz, n, args.seconds, args.concave)


if __name__ == "__main__":
    main()
