"""A box dropped across two (or ``--cables``) parallel cables lying on a table (docs/concepts/contact.md, "A body on
two cables"): each cable's step moves a body they share with its whole mass and the other cables' reactions, and
their reactions are combined before Bullet's step (bullet/held_bodies.py, "Bodies on several cables"; ``--split``:
each step with its share of the mass instead, as in the morning of 2026-12-05; ``--condensed``: the condensed contact, as before
2026-12-05, which sinks by about g h^2, 2.7 mm at 60 Hz). Prints, per run, the box's lowest gap to the cables
(negative: into them), where it ends (z of its centre against resting on the cables), its highest point against its
release, its speed at the end, each cable's share of its weight, the table's support over all the weights, and the
cables' status.

    python demos/box_on_two_cables.py
    python demos/box_on_two_cables.py --hz 60 240 --mass 0.03 0.3 --offset 0 0.008 --split
    python demos/box_on_two_cables.py --cables 3 --sep 0.015 --offset 0 0.01
"""
from __future__ import annotations

import argparse
import itertools
import math
import warnings

import numpy as np
import pybullet as pb

from bullet_dlo.bullet import held_bodies
from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

G = 9.81
HALF = (0.02, 0.02, 0.01)  # [m] the box's half extents


def drop(hz: float, mass: float, offset: float = 0.0, n: int = 15, height: float = 0.005, sep: float = 0.02,
         seconds: float = 2.0, count: int = 2) -> dict:
    """Drop the box (``mass`` [kg], ``offset`` [m] off the middle towards the last cable) ``height`` [m] above
    resting on ``count`` parallel cables ``sep`` [m] apart lying on the table, and step ``seconds`` [s] at ``hz``.
    Returns, in m, m/s and rad: z (its centre against resting on the cables), y (its centre across the cables, the
    middle at 0) and tilt (its turn off level), lowest (deepest gap to a cable, negative: into it), top (its highest
    point against its release), speed at the end, ys (the cables' axes across), carried (each cable's upward force on
    it over its weight), table (the table's support over all the weights) and stopped (the reasons of the cables that
    stopped)."""
    spec = CableSpec.lv2017(n_masses=n, damping=0.02)
    r = spec.diameter / 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with BulletWorld(dt=1.0 / hz, ground=False) as world:
            cid = world.client
            table = world.add_box((0.3, 0.2, 0.05), (0.0, 0.0, -0.05), friction=0.5, name="table")
            ys = [sep * (k - (count - 1) / 2) for k in range(count)]
            cables = [world.add_cable(spec, start=(-0.15, y, r), direction=(1, 0, 0), name=f"c{k}")
                      for k, y in enumerate(ys)]
            world.run(0.2)
            z_on = 2 * r + HALF[2]
            box = world.add_box(HALF, (0.0, offset, z_on + height), mass=mass, friction=0.5)
            lowest, top = 0.0, -1.0
            for _ in range(round(seconds * hz)):
                world.step()
                top = max(top, pb.getBasePositionAndOrientation(box, physicsClientId=cid)[0][2])
                for c in cables:
                    cf = c.contact_forces()
                    on = cf["body"] == box
                    if on.any():
                        lowest = min(lowest, float(cf["gap"][on].min()))
                if not all(c.stable for c in cables):
                    break
            table_load = -sum(float(c.body_forces().get(table, np.zeros(3))[2]) for c in cables)  # (on it: down)
            table_load += sum(cp[9] for cp in pb.getContactPoints(box, table, physicsClientId=cid))
            pos, turn = pb.getBasePositionAndOrientation(box, physicsClientId=cid)
            return {"z": pos[2] - z_on, "y": pos[1], "tilt": 2.0 * math.acos(min(abs(turn[3]), 1.0)),
                    "lowest": lowest, "top": top - z_on - height, "z_on": z_on, "ys": ys,
                    "speed": float(np.linalg.norm(pb.getBaseVelocity(box, physicsClientId=cid)[0])),
                    "carried": [float(c.body_forces().get(box, np.zeros(3))[2]) / (mass * G) for c in cables],
                    "table": table_load / ((count * spec.mass + mass) * G),
                    "stopped": [f"{c.name}: {c.reason}" for c in cables if not c.stable]}


def run(hz: float, n: int, mass: float, height: float, offset: float, sep: float, seconds: float,
        count: int = 2) -> str:
    """One line of the printed table (:func:`drop`)."""
    out = drop(hz, mass, offset, n, height, sep, seconds, count)
    status = "; ".join(out["stopped"]) or "stable"
    return (f"{hz:5.0f} Hz, {mass:6.3f} kg, offset {1e3 * offset:4.1f} mm: lowest gap {1e3 * out['lowest']:7.2f} mm, "
            f"ends at z {1e3 * (out['z'] + out['z_on']):6.2f} mm (on the cables: {1e3 * out['z_on']:.2f}), highest "
            f"{1e3 * out['top']:+.2f} mm from its release, speed {out['speed']:.1e} m/s, cables carry "
            f"{' + '.join(f'{c:.3f}' for c in out['carried'])} of its weight, support {out['table']:.4f} of all "
            f"weights, {status}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hz", type=float, nargs="+", default=[60.0, 240.0])
    parser.add_argument("--mass", type=float, nargs="+", default=[0.03, 0.3])
    parser.add_argument("--offset", type=float, nargs="+", default=[0.0, 0.008], help="[m] off the middle, along y")
    parser.add_argument("--n", type=int, default=15)
    parser.add_argument("--drop", type=float, default=0.005, help="[m] above resting on the cables")
    parser.add_argument("--sep", type=float, default=0.02, help="[m] between the cables' axes")
    parser.add_argument("--cables", type=int, default=2, help="how many parallel cables the box lands across")
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--condensed", action="store_true",
                        help="a shared body keeps the condensed contact (held_bodies.SPLIT_SHARED = False)")
    parser.add_argument("--split", action="store_true",
                        help="a shared body moves in each cable's step with its share of the mass, without the other "
                             "cables' reactions (held_bodies.COUPLE_SHARED = False)")
    args = parser.parse_args()
    held_bodies.SPLIT_SHARED = not args.condensed
    held_bodies.COUPLE_SHARED = not args.split
    for hz, mass, offset in itertools.product(args.hz, args.mass, args.offset):
        print(run(hz, args.n, mass, args.drop, offset, args.sep, args.seconds, args.cables), flush=True)


if __name__ == "__main__":
    main()
