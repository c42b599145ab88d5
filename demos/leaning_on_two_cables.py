"""A box leaning on the table and on one of two parallel cables lying on it (issue 23 item 2: bodies that rest on the
cable and on something else come to rest; docs/concepts/contact.md, "A body on two cables").

Two Lv cables (15 masses) lie on a table 5 and ``--second`` mm to the side of the middle; a 40 x 40 x 20 mm box is
dropped 4 mm above them, tips and ends leaning with one edge on the table and its bottom face on the first cable.
The second cable lies under the box's raised side, within the contact's reach but carrying nothing (at 15 mm, the
default; at 60 mm it is out of reach). Statics: the box at rest, the table and the first cable carrying its weight.
Printed per case: ``rest`` when the box last moved faster than 1e-4 m/s [s], ``creep`` its largest speed over the
last second [m/s], ``kick`` its largest speed after the first second [m/s] and when, ``support`` (cables' and table's
push on the box) / its weight at the end, and the cables' status.

``--scene crossing``: the same box dropped onto two cables crossing at right angles (the second over the first), 10
mm off the crossing along both, so that it tips an edge onto the table and ends on the table and the cables
(``--second`` unused).

Usage: python demos/leaning_on_two_cables.py [--scene lean] [--hz 60 240] [--mass 0.003 0.03 0.3 3]
[--friction 0.5 2] [--second 0.015] [--seconds 5]
"""
from __future__ import annotations

import argparse

import numpy as np
import pybullet as pb

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

G = 9.81
HALF = (0.02, 0.02, 0.01)  # [m] the box


def build(world: BulletWorld, mass: float, friction: float, scene: str = "lean", second: float = 0.015):
    """The scene in ``world`` (no ground of its own): the table, the two cables (Lv, 15 masses) settled 0.5 s, and the
    box 4 mm above them. Returns (table, cables, box)."""
    spec = CableSpec.lv2017(n_masses=15, damping=0.02)
    r = spec.diameter / 2
    table = world.add_box((0.3, 0.3, 0.05), (0.0, 0.0, -0.05), friction=friction, name="table")
    if scene == "crossing":
        cables = [world.add_cable(spec, start=(-0.15, 0.0, r), direction=(1, 0, 0), name="c0"),
                  world.add_cable(spec, start=(0.0, -0.15, 3 * r + 5e-4), direction=(0, 1, 0), name="c1")]
        at = (0.01, 0.01)
    else:
        cables = [world.add_cable(spec, start=(x, -0.15, r), direction=(0, 1, 0), name=f"c{k}")
                  for k, x in enumerate((0.005, second))]
        at = (0.0, 0.0)
    world.run(0.5)
    top = max(float(c.x[:, 2].max()) for c in cables)
    box = world.add_box(HALF, (*at, top + r + 0.014), mass=mass, friction=friction)
    return table, cables, box


def lean(hz: float, mass: float, friction: float, second: float, seconds: float, scene: str = "lean") -> dict:
    """Run one case; the box's speeds [m/s] after each step, and the supports at the end over its weight."""
    with BulletWorld(dt=1.0 / hz, ground=False) as world:
        cid = world.client
        table, cables, box = build(world, mass, friction, scene, second)
        speeds = []
        for _ in range(world.steps_in(seconds)):
            world.step()
            speeds.append(float(np.linalg.norm(pb.getBaseVelocity(box, physicsClientId=cid)[0])))
        weight = mass * G
        cables_push = sum(float(c.body_forces().get(box, np.zeros(3))[2]) for c in cables)
        table_push = sum(cp[9] for cp in pb.getContactPoints(box, table, physicsClientId=cid))
        return {"speeds": np.array(speeds), "support": (cables_push + table_push) / weight,
                "stopped": [f"{c.name}: {c.reason}" for c in cables if not c.stable]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hz", type=float, nargs="+", default=[60.0, 240.0], help="Bullet step rates [Hz]")
    ap.add_argument("--mass", type=float, nargs="+", default=[0.003, 0.03, 0.3, 3.0], help="box masses [kg]")
    ap.add_argument("--friction", type=float, nargs="+", default=[0.5, 2.0],
                    help="the table's and the box's friction coefficient (Bullet combines them as a product)")
    ap.add_argument("--second", type=float, default=0.015, help="[m] the second cable's offset from the middle")
    ap.add_argument("--seconds", type=float, default=5.0, help="[s] simulated after the drop")
    ap.add_argument("--scene", choices=("lean", "crossing"), default="lean",
                    help="lean: two parallel cables, the box leaning on the first; crossing: two crossing cables")
    args = ap.parse_args()
    for hz in args.hz:
        for mass in args.mass:
            for friction in args.friction:
                out = lean(hz, mass, friction, args.second, args.seconds, args.scene)
                sp, n1 = out["speeds"], int(round(hz))
                moving = np.flatnonzero(sp > 1e-4)
                rest = (moving[-1] + 1) / hz if moving.size else 0.0
                late = int(np.argmax(sp[n1:])) + n1
                print(f"{hz:5.0f} Hz, {mass:6.3f} kg, friction {friction:3.1f}: rest {rest:5.2f} s, creep "
                      f"{sp[-n1:].max():.1e} m/s, kick {sp[late]:.1e} m/s at {(late + 1) / hz:4.2f} s, support "
                      f"{out['support']:.4f}, {'; '.join(out['stopped']) or 'stable'}", flush=True)


if __name__ == "__main__":
    main()
