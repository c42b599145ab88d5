"""A box dropped across two parallel cables lying on a table (docs/concepts/contact.md, "A body on two cables"): each
cable's step moves a body they share with its share of the mass (``--condensed``: the condensed contact instead, as
before 2026-12-05, which sinks by about g h^2, 2.7 mm at 60 Hz). Prints, per run, the box's lowest gap to the cables
(negative: into them), where it ends (z of its centre against resting on the cables), its highest point against its
release, the table's support over all the weights, and the cables' status.

    python demos/box_on_two_cables.py
    python demos/box_on_two_cables.py --hz 60 240 --mass 0.03 0.3 --offset 0 0.008 --condensed
"""
from __future__ import annotations

import argparse
import itertools
import warnings

import numpy as np
import pybullet as pb

from bullet_dlo.bullet import held_bodies
from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

G = 9.81
HALF = (0.02, 0.02, 0.01)  # [m] the box's half extents


def run(hz: float, n: int, mass: float, drop: float, offset: float, sep: float, seconds: float) -> str:
    spec = CableSpec.lv2017(n_masses=n, damping=0.02)
    r = spec.diameter / 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with BulletWorld(dt=1.0 / hz, ground=False) as world:
            table = world.add_box((0.3, 0.2, 0.05), (0.0, 0.0, -0.05), friction=0.5, name="table")
            cables = [world.add_cable(spec, start=(-0.15, y, r), direction=(1, 0, 0), name=f"c{k}")
                      for k, y in enumerate((-sep / 2, sep / 2))]
            world.run(0.2)
            z_on = 2 * r + HALF[2]
            box = world.add_box(HALF, (0.0, offset, z_on + drop), mass=mass, friction=0.5)
            gap, top = 0.0, -1.0
            for _ in range(round(seconds * hz)):
                world.step()
                top = max(top, pb.getBasePositionAndOrientation(box, physicsClientId=world.client)[0][2])
                for c in cables:
                    cf = c.contact_forces()
                    on = cf["body"] == box
                    if on.any():
                        gap = min(gap, float(cf["gap"][on].min()))
                if not all(c.stable for c in cables):
                    break
            z = pb.getBasePositionAndOrientation(box, physicsClientId=world.client)[0][2]
            support = sum(float(c.contact_forces()["force"][c.contact_forces()["body"] == table][:, 2].sum())
                          for c in cables)
            support += sum(cp[9] for cp in pb.getContactPoints(box, table, physicsClientId=world.client))
            weight = (2 * spec.mass + mass) * G
            status = "; ".join(f"{c.name}: {c.reason}" for c in cables if not c.stable) or "stable"
    return (f"{hz:5.0f} Hz, {mass:6.3f} kg, offset {1e3 * offset:4.1f} mm: lowest gap {1e3 * gap:7.2f} mm, "
            f"ends at z {1e3 * z:6.2f} mm (on the cables: {1e3 * z_on:.2f}), highest {1e3 * (top - z_on - drop):+.2f} "
            f"mm from its release, support {support / weight:.4f} of both weights, {status}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hz", type=float, nargs="+", default=[60.0, 240.0])
    parser.add_argument("--mass", type=float, nargs="+", default=[0.03, 0.3])
    parser.add_argument("--offset", type=float, nargs="+", default=[0.0, 0.008], help="[m] off the middle, along y")
    parser.add_argument("--n", type=int, default=15)
    parser.add_argument("--drop", type=float, default=0.005, help="[m] above resting on the cables")
    parser.add_argument("--sep", type=float, default=0.02, help="[m] between the cables' axes")
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--condensed", action="store_true",
                        help="a shared body keeps the condensed contact (held_bodies.SPLIT_SHARED = False)")
    args = parser.parse_args()
    held_bodies.SPLIT_SHARED = not args.condensed
    for hz, mass, offset in itertools.product(args.hz, args.mass, args.offset):
        print(run(hz, args.n, mass, args.drop, offset, args.sep, args.seconds), flush=True)


if __name__ == "__main__":
    main()
