"""Issue 23 item 2: bodies on the cable that something else holds too (docs/concepts/contact.md, "Bodies resting on
the cable").

The cases, each measured without the contact model's own numbers (its gaps and forces):

- ``leaning``: a box (4 x 10 x 1 cm) lying across a cable on the table, one end on the table, the other part on
  the cable (Bullet supports the box too). Statics: the cable carries the share of the weight the lever gives
  (5/8 here), the table the rest; the box at rest.
- ``plank``: a plank (2 x 10 x 1.2 cm) dropped 1 cm across the cable lying on the table, its centre 1 cm to one side:
  it tips onto the table and rests on one end and the cable (``share``: of its weight on the cable).
- ``held``: a 30 g board fixed in the air by a user constraint (JOINT_FIXED), the cable lying on it.
- ``dragged``: a box of 40 x 10 x 4 cm on a frictionless table (Bullet holds it up), the cable lying along it and
  pulled at its first node by 0.05 N after 1 s: static friction must drag the box (mu 0.8 / 0.6 on a 0.8 box);
  ``balance`` is then the box's acceleration over 0.6 s over pull / (m_box + m_cable), the status says how many of
  the cable's rows slide at the end.
- ``rod``: Bullet alone, the leaning box on a fixed rod of the cable's radius where the cable lies (the reference for
  ``rest`` and ``creep``; sink, balance and share are not measured).

Per case, mass and step: ``sink`` [mm], how far the body's face is inside the cable's surface (the centre line's
distance to the face minus the cable radius, over the nodes under the face; positive: inside), at the end and its
worst over the last second; ``balance``: (ground on cable + ground on box) / (m_cable + m_box) g (leaning) or the
cable's push on the board / the cable's weight (held); ``rest``: when the box last moved faster than 1e-4 m/s [s];
``creep``: the body's largest speed over the last second [mm/s]; ``fails``: the cable's Newton solves that did not
converge (``cable.solver.newton_failures``).
Usage: python demos/supported_bodies.py [--hz 60 120] [--mass 0.001 0.03 0.3 3] [--case leaning plank held dragged rod]
"""
from __future__ import annotations

import argparse
import math
import sys

import numpy as np
import pybullet as pb

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

G = 9.81
HALF = (0.02, 0.05, 0.005)  # [m] the leaning box: 4 cm along the cable, 10 cm across, 1 cm thick
OFFSET = 0.03  # [m] the box's centre from the cable, across it: the end 0.08 m from the cable lies on the table
PLANK_HALF = (0.01, 0.05, 0.006)  # [m] the plank: 2 cm along the cable, 10 cm across, 1.2 cm thick


def _face_sink(cable, body: int, half, r: float, cid: int) -> float:
    """How far [m] the body's bottom (leaning) or top (held) face is inside the cable's surface, over the nodes
    under / over the face (positive: inside); -inf when no node is there."""
    pos, orn = pb.getBasePositionAndOrientation(body, physicsClientId=cid)
    rot = np.array(pb.getMatrixFromQuaternion(orn)).reshape(3, 3)
    local = (cable.x - np.asarray(pos)) @ rot
    over = (np.abs(local[:, 0]) < half[0]) & (np.abs(local[:, 1]) < half[1])
    if not over.any():
        return -math.inf
    return float(np.max(r + half[2] - np.abs(local[over, 2])))


def _lean_box(world, r: float, mass: float) -> int:
    """The leaning box: its bottom edge 0.1 mm above the table, its face 0.1 mm above a cable of radius r [m]."""
    p0, p1 = np.array([0.0, 0.0, 2 * r + 1e-4]), np.array([0.0, OFFSET + HALF[1], 1e-4])
    u = (p1 - p0) / np.linalg.norm(p1 - p0)  # the box's local y
    w = np.array([0.0, -u[2], u[1]])  # its local z
    phi = math.atan2(u[2], u[1])
    centre = p1 - HALF[1] * u + HALF[2] * w
    return world.add_box(HALF, centre.tolist(), (math.sin(phi / 2), 0.0, 0.0, math.cos(phi / 2)), mass=mass)


def leaning(mass: float, hz: float, seconds: float) -> dict:
    spec = CableSpec.lv2017(n_masses=20, damping=0.02)
    r = spec.diameter / 2
    with BulletWorld(dt=1.0 / hz) as world:
        cable = world.add_cable(spec, start=(-0.15, 0.0, r), direction=(1, 0, 0))
        world.run(0.2)
        box = _lean_box(world, r, mass)
        return _run(world, cable, box, mass, spec, r, seconds, HALF, "leaning")


def plank(mass: float, hz: float, seconds: float) -> dict:
    spec = CableSpec.lv2017(n_masses=20, damping=0.02)
    r = spec.diameter / 2
    with BulletWorld(dt=1.0 / hz) as world:
        cable = world.add_cable(spec, start=(-0.15, 0.0, r), direction=(1, 0, 0))
        world.run(0.1)
        box = world.add_box(PLANK_HALF, (0.0, 0.01, 2 * r + PLANK_HALF[2] + 0.01), mass=mass)
        return _run(world, cable, box, mass, spec, r, seconds, PLANK_HALF, "plank")


def dragged(mass: float, hz: float, seconds: float) -> dict:
    spec = CableSpec.lv2017(n_masses=20, static_friction=0.8, dynamic_friction=0.6)
    r, pull, half = spec.diameter / 2, 0.05, (0.2, 0.05, 0.02)
    with BulletWorld(dt=1.0 / hz, ground_friction=0.0) as world:
        cid = world.client
        box = world.add_box(half, (0.0, 0.0, half[2]), mass=mass, friction=0.8)
        cable = world.add_cable(spec, start=(-0.15, 0.0, 2 * half[2] + r), direction=(1, 0, 0))
        world.run(1.0)
        cable.set_external_force(0, (-pull, 0.0, 0.0))  # along -x
        t, v = [], []
        for k in range(world.steps_in(0.6)):
            world.step()
            t.append(k * world.dt)
            v.append(pb.getBaseVelocity(box, physicsClientId=cid)[0][0])
        t, v = np.array(t), np.array(v)
        accel = np.polyfit(t[t > 0.1], v[t > 0.1], 1)[0]
        sliding = int(cable.contact_forces()["sliding"].sum())
        nan = math.nan
        ratio = accel / (-pull / (mass + spec.mass))
        status = f"{cable.reason or 'stable'}, {sliding} rows sliding"
        return dict(case="dragged", mass=mass, hz=hz, sink=nan, worst=nan, balance=ratio, share=nan, rest=nan,
                    creep=nan, fails=cable.solver.newton_failures, status=status)


def rod(mass: float, hz: float, seconds: float) -> dict:
    spec = CableSpec.lv2017(n_masses=20, damping=0.02)
    r = spec.diameter / 2
    with BulletWorld(dt=1.0 / hz) as world:
        cid = world.client
        world.add_cylinder(r, spec.length, (0.0, 0.0, r), (0.0, math.sqrt(0.5), 0.0, math.sqrt(0.5)), name="rod")
        box = _lean_box(world, r, mass)
        last_moving, creep = 0.0, 0.0
        for k in range(world.steps_in(seconds)):
            world.step()
            v = float(np.linalg.norm(pb.getBaseVelocity(box, physicsClientId=cid)[0]))
            if v > 1e-4:
                last_moving = (k + 1) * world.dt
            if (k + 1) * world.dt > seconds - 1.0:
                creep = max(creep, v)
    nan = math.nan
    return dict(case="rod", mass=mass, hz=hz, sink=nan, worst=nan, balance=nan, share=nan, rest=last_moving,
                creep=1e3 * creep, fails=0, status="stable")


def held(mass: float, hz: float, seconds: float) -> dict:
    spec = CableSpec.lv2017(n_masses=20, damping=0.05)
    r, half = spec.diameter / 2, (0.6 * spec.length, 0.05, 0.01)
    with BulletWorld(dt=1.0 / hz) as world:
        cid = world.client
        box = world.add_box(half, (0.0, 0.0, 0.3), mass=mass)
        pb.createConstraint(box, -1, -1, -1, pb.JOINT_FIXED, (0, 0, 0), (0, 0, 0), (0.0, 0.0, 0.3),
                            physicsClientId=cid)
        cable = world.add_cable(spec, start=(-0.5 * spec.length, 0.0, 0.31 + r + 1e-4), direction=(1, 0, 0))
        return _run(world, cable, box, mass, spec, r, seconds, half, "held")


def _run(world, cable, box, mass, spec, r, seconds, half, case) -> dict:
    cid = world.client
    steps = world.steps_in(seconds)
    last_moving, worst, creep = 0.0, -math.inf, 0.0
    for k in range(steps):
        world.step()
        if not cable.stable:
            break
        v = float(np.linalg.norm(pb.getBaseVelocity(box, physicsClientId=cid)[0]))
        if v > 1e-4:
            last_moving = (k + 1) * world.dt
        if (k + 1) * world.dt > seconds - 1.0:
            worst = max(worst, _face_sink(cable, box, half, r, cid))
            creep = max(creep, v)
    sink = _face_sink(cable, box, half, r, cid)
    on_box = float(cable.body_forces().get(box, np.zeros(3))[2])
    if case in ("leaning", "plank"):
        pc = cable.contact_forces()
        ground_on_cable = float(pc["force"][pc["body"] == world.ground_id][:, 2].sum())
        ground_on_box = sum(cp[9] for cp in pb.getContactPoints(box, world.ground_id, physicsClientId=cid))
        balance = (ground_on_cable + ground_on_box) / ((spec.mass + mass) * G)
        share = on_box / (mass * G)  # of the box's weight on the cable (lever: 5/8)
    else:
        balance = -on_box / (spec.mass * G)
        share = math.nan
    return dict(case=case, mass=mass, hz=1.0 / world.dt, sink=1e3 * sink, worst=1e3 * worst, balance=balance,
                share=share, rest=last_moving, creep=1e3 * creep, fails=cable.solver.newton_failures,
                status=cable.reason or "stable")


CASES = {"leaning": leaning, "plank": plank, "held": held, "dragged": dragged, "rod": rod}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hz", type=float, nargs="+", default=[60.0, 120.0])
    ap.add_argument("--mass", type=float, nargs="+", default=[0.001, 0.03, 0.3, 3.0, 10.0])
    ap.add_argument("--case", nargs="+", choices=tuple(CASES), default=["leaning", "held"])
    ap.add_argument("--seconds", type=float, default=2.0)
    args = ap.parse_args(argv)
    for name, val, lo in (("--hz", min(args.hz), 10.0), ("--mass", min(args.mass), 1e-4), ("--seconds", args.seconds, 1.0)):
        if not val >= lo:
            print(f"{name} must be at least {lo:g}, got {val:g}", file=sys.stderr)
            sys.exit(2)
    print(f"{'case':8s} {'mass kg':>8s} {'Hz':>6s} {'sink mm':>8s} {'worst 1s':>8s} {'balance':>8s} {'on cable':>8s}"
          f" {'rest s':>7s} {'creep':>7s} {'fails':>6s}  status")
    for case in args.case:
        for hz in args.hz:
            for m in args.mass:
                res = CASES[case](m, hz, args.seconds)
                print(f"{case:8s} {m:8.3g} {hz:6.0f} {res['sink']:8.3f} {res['worst']:8.3f} {res['balance']:8.4f}"
                      f" {res['share']:8.4f} {res['rest']:7.3f} {res['creep']:7.3f} {res['fails']:6d}  {res['status']}",
                      flush=True)


if __name__ == "__main__":
    main()
