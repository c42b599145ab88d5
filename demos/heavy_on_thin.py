"""Issue 23 item 2: heavy bodies on a thin light cable, how deep the rows under them are pressed.

A box (4 x 10 x 1 cm) laid across a cable lying on the table, its far end on the table (it leans on the cable and the
table; the cable carries 5/8 of its weight), at each mass, number of masses and step rate. The cable is thin and light
(0.25 m, 2.5 mm, 8 g, E 2 GPa): its rows under a 10 kg box carry up to 10^4 times their node's weight. Printed per run,
at the end of ``--seconds``: the box's face inside the cable's surface and the deepest node inside the table, both in
cable radii (the contact model bounds a row's depth at rest by ``bullet_dlo.bullet.contact.LOAD_DEPTH`` of the radius);
the cable's share of the box's weight over 5/8; the support balance (ground on cable + ground on box) over both
weights; the time after which the box last moved faster than 1e-4 m/s; the cable's status; and the thread CPU time of
the run. Compare with older code by running it with ``PYTHONPATH=<tree>``.

``--cable soft`` takes a soft cable instead (0.3 m, 5 mm, 30 g, E 1 MPa) and ``--table hull`` lays the cable on a
static convex-hull slab (Bullet's mesh, 1 mm collision margin) instead of the ground: a soft cable under a 3-10 kg box
on the hull at 60 Hz is the marginal case, before and after, of docs/concepts/contact.md ("Bodies resting on the
cable").

Usage: python demos/heavy_on_thin.py [--masses 0.03 0.3 3 10] [--ns 13 40] [--hz 60 240] [--seconds 2]
       [--cable thin|soft] [--table ground|hull]
"""
from __future__ import annotations

import argparse
import itertools
import time

import numpy as np
import pybullet as pb

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

G = 9.81
HALF = (0.02, 0.05, 0.005)  # [m] the leaning box: 4 cm along the cable, 10 cm across, 1 cm thick
OFFSET = 0.03  # [m] the box's far end rests on the table OFFSET + 5 cm from the cable


CABLES = {"thin": dict(length=0.25, diameter=0.0025, mass=0.008, youngs_modulus=2e9),
          "soft": dict(length=0.3, diameter=0.005, mass=0.03, youngs_modulus=1e6)}
HULL_HALF = (0.3, 0.2, 0.025)  # [m] the hull slab's half extents, its top at 0.1 m (plus Bullet's 1 mm margin)


def table(world: BulletWorld, kind: str) -> tuple[int, float]:
    """The body the cable lies on and the height of its surface [m]: the ground, or a static convex-hull slab."""
    if kind == "ground":
        return world.ground_id, 0.0
    signs = [(sx, sy, sz) for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    v = [[sx * HULL_HALF[0], sy * HULL_HALF[1], sz * HULL_HALF[2]] for sx, sy, sz in signs]
    col = pb.createCollisionShape(pb.GEOM_MESH, vertices=v, physicsClientId=world.client)
    return pb.createMultiBody(0.0, col, -1, [0.0, 0.0, 0.1 - HULL_HALF[2]], physicsClientId=world.client), 0.101


def leaning_box(world: BulletWorld, spec: CableSpec, mass: float, top: float):
    """The cable settled 0.2 s on the table (its surface at ``top`` [m]), then the box across it, bottom face
    through the cable's top and the table. Returns (cable, box)."""
    r = spec.diameter / 2
    cable = world.add_cable(spec, start=(-spec.length / 2, 0.0, top + r + 2e-4), direction=(1, 0, 0))
    world.run(0.2)
    top = float(cable.x[:, 2].mean()) - r
    p0, p1 = np.array([0.0, 0.0, top + 2 * r + 1e-4]), np.array([0.0, OFFSET + HALF[1], top + 1e-4])
    u = (p1 - p0) / np.linalg.norm(p1 - p0)
    phi = np.arctan2(u[2], u[1])
    centre = p1 - HALF[1] * u + HALF[2] * np.array([0.0, -u[2], u[1]])
    box = world.add_box(HALF, centre.tolist(), (np.sin(phi / 2), 0.0, 0.0, np.cos(phi / 2)), mass=mass)
    return cable, box


def run(mass: float, n: int, hz: float, seconds: float, cable_kind: str = "thin", table_kind: str = "ground") -> dict:
    spec = CableSpec(**CABLES[cable_kind], n_masses=n, damping=0.02)
    r = spec.diameter / 2
    t0 = time.thread_time()
    with BulletWorld(dt=1.0 / hz) as world:
        cid = world.client
        under, top = table(world, table_kind)
        cable, box = leaning_box(world, spec, mass, top)
        moved = 0.0
        for k in range(world.steps_in(seconds)):
            world.step()
            if np.linalg.norm(pb.getBaseVelocity(box, physicsClientId=cid)[0]) > 1e-4:
                moved = (k + 1) * world.dt
        pos, orn = pb.getBasePositionAndOrientation(box, physicsClientId=cid)
        local = (cable.x - np.asarray(pos)) @ np.array(pb.getMatrixFromQuaternion(orn)).reshape(3, 3)
        over = (np.abs(local[:, 0]) < HALF[0]) & (np.abs(local[:, 1]) < HALF[1])
        face = float(np.max(r + HALF[2] - np.abs(local[over, 2]))) if over.any() else float("nan")
        into_table = float(top + r - cable.x[:, 2].min())
        pc = cable.contact_forces()
        on_cable = float(pc["force"][pc["body"] == under][:, 2].sum())
        on_box = sum(cp[9] for cp in pb.getContactPoints(box, under, physicsClientId=cid))
        share = float(cable.body_forces().get(box, np.zeros(3))[2]) / (5 / 8 * mass * G)
        balance = (on_cable + on_box) / ((spec.mass + mass) * G)
        return dict(face=face / r, table=into_table / r, share=share, balance=balance,
                    rest=moved, status="stable" if cable.stable else cable.reason, cpu=time.thread_time() - t0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--masses", type=float, nargs="+", default=[0.03, 0.3, 3.0, 10.0], help="box masses [kg]")
    ap.add_argument("--ns", type=int, nargs="+", default=[13, 40], help="numbers of masses of the cable")
    ap.add_argument("--hz", type=float, nargs="+", default=[60.0, 240.0], help="Bullet step rates [1/s]")
    ap.add_argument("--seconds", type=float, default=2.0, help="simulated time after the box is laid on [s]")
    ap.add_argument("--cable", choices=sorted(CABLES), default="thin", help="the cable (module doc)")
    ap.add_argument("--table", choices=["ground", "hull"], default="ground", help="what the cable lies on")
    a = ap.parse_args()
    print("| box [kg] | n | rate [Hz] | face into cable [r] | node into table [r] | cable's share / (5/8) | "
          "support balance | at rest from [s] | status | CPU [s] |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for mass, n, hz in itertools.product(a.masses, a.ns, a.hz):
        o = run(mass, n, hz, a.seconds, a.cable, a.table)
        print(f"| {mass:g} | {n} | {hz:g} | {o['face']:.3f} | {o['table']:.3f} | {o['share']:.3f} | "
              f"{o['balance']:.4f} | {o['rest']:.2f} | {o['status']} | {o['cpu']:.1f} |", flush=True)


if __name__ == "__main__":
    main()
