"""Issue 23 item 2: a dynamic box dropped / placed on a cable lying on the ground.

For each box mass and step: peak reaction on the box [N] (and in units of its weight), peak box speed [m/s], the box's
largest mechanical energy over the energy it was dropped with (E/E0: kinetic, and potential above its rest flat on the
ground; the cable lies at rest, so above 1 the contact made energy), time to rest (box speed below 1e-4 m/s for good)
[s], support balance at the end (ground on cable + ground on box) / ((m_cable + m_box) g), penetration of the box into
the cable, D/scl (the largest rise of the box's own energy balance over its scale, bullet/body_energy.py: the cable
stops at 1), cable status. Usage: python demos/resting_bodies.py [--drop 0.01] [--seconds 2] [--hz 240 1000] [--n 20]
[--offset 0] [--yaw 0] [--shape box] [--trace] [--no-spare]: --offset [m] moves the box's centre off the cable (along
y) and --yaw [rad] turns it about z, so that it tips off the cable onto the ground; --shape hull drops the same box as
a convex hull of its 8 corners (Bullet's mesh, its surface a collision margin of 1 mm further out, met by the contact
model's hull rows instead of its box rows); --no-spare switches off the cap on an unconverged solve's reaction
(held_bodies.spare_thrown), to see what it prevents; --trace prints every step from the first one in which the model
has a contact row on the box: its Newton iterations, whether the solve converged, the residual ratio of a kept
unconverged solve (contact.stall_ratio), whether it was taken again as sub-steps, and the box's speed.
"""
from __future__ import annotations

import argparse
import itertools
import time

import numpy as np
import pybullet as pb

from bullet_dlo.bullet import held_bodies
from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

G = 9.81
HALF = (0.02, 0.02, 0.01)  # [m] box half extents: 4 cm square across the cable, 2 cm tall
HULL_MARGIN = 1e-3  # [m] Bullet's collision margin of a mesh shape


def run(mass: float, hz: float, drop: float, seconds: float, n: int = 20, offset: float = 0.0,
        yaw: float = 0.0, trace: bool = False, shape: str = "box") -> dict:
    spec = CableSpec.lv2017(n_masses=n, damping=0.02)
    r = spec.diameter / 2
    with BulletWorld(dt=1.0 / hz) as world:
        cable = world.add_cable(spec, start=(-0.15, 0.0, r), direction=(1, 0, 0))
        world.run(0.2)  # the cable lies still on the ground
        turn = pb.getQuaternionFromEuler((0.0, 0.0, yaw))
        cid = world.client
        if shape == "box":
            box = world.add_box(HALF, (0.0, offset, 2 * r + HALF[2] + drop), turn, mass=mass, friction=0.5)
            low = HALF[2]  # [m] the centre's height resting flat on the ground
        else:
            corners = [[sx * HALF[0], sy * HALF[1], sz * HALF[2]] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
            col = pb.createCollisionShape(pb.GEOM_MESH, vertices=corners, physicsClientId=cid)
            low = HALF[2] + HULL_MARGIN
            box = pb.createMultiBody(mass, col, -1, (0.0, offset, 2 * r + low + drop), turn, physicsClientId=cid)
            pb.changeDynamics(box, -1, lateralFriction=0.5, physicsClientId=cid)
        peak_f, peak_v, last_moving, worst_gap, rise = 0.0, 0.0, 0.0, 0.0, 0.0
        dropped = most = _energy(box, mass, cid, low)
        t_contact = tic = 0.0
        steps = int(round(seconds * hz))
        tic = time.perf_counter()
        prev = _counters(cable.solver)
        for k in range(steps):
            world.step()
            f = cable.body_forces().get(box, np.zeros(3))
            peak_f = max(peak_f, float(np.linalg.norm(f)))
            v = np.linalg.norm(pb.getBaseVelocity(box, physicsClientId=cid)[0])
            peak_v = max(peak_v, float(v))
            most = max(most, _energy(box, mass, cid, low))
            if v > 1e-4:
                last_moving = (k + 1) / hz
            pc = cable.contact_forces()
            on_box = pc["body"] == box
            if on_box.any():
                worst_gap = min(worst_gap, float(pc["gap"][on_box].min()))
                t_contact = t_contact or (k + 1) / hz
            cs = cable.contact.set
            if cs is not None and cs.free_bodies:
                be = cs.energy_check
                rise = max(rise, float(((be.gain - be.lowest) / (be.scale + be.exchanged)).max()))
            if trace and t_contact:
                _trace_step(k + 1, hz, cable.solver, prev, v)
            prev = _counters(cable.solver)
            if not cable.stable:
                break
        wall = time.perf_counter() - tic
        pc = cable.contact_forces()
        ground_on_cable = float(pc["force"][pc["body"] == world.ground_id][:, 2].sum())
        ground_on_box = sum(cp[9] for cp in pb.getContactPoints(box, world.ground_id, physicsClientId=cid))
        balance = (ground_on_cable + ground_on_box) / ((spec.mass + mass) * G)
        return dict(mass=mass, hz=hz, peak_f=peak_f, peak_w=peak_f / (mass * G), peak_v=peak_v, energy=most / dropped,
                    rest=last_moving, balance=balance, status=cable.reason or "stable", gap=worst_gap, rise=rise,
                    ms_per_step=1e3 * wall / max(k + 1, 1), z=pb.getBasePositionAndOrientation(box, physicsClientId=cid)[0][2])


def _energy(box: int, mass: float, cid: int, low: float) -> float:
    """The box's mechanical energy [J]: kinetic (Bullet's principal inertia, centred and aligned with the box), and
    potential above its rest flat on the ground (centre at ``low`` [m])."""
    pos, orn = pb.getBasePositionAndOrientation(box, physicsClientId=cid)
    lin, ang = pb.getBaseVelocity(box, physicsClientId=cid)
    local = np.array(pb.getMatrixFromQuaternion(orn)).reshape(3, 3).T @ np.asarray(ang)
    inertia = np.asarray(pb.getDynamicsInfo(box, -1, physicsClientId=cid)[2])
    return mass * G * (pos[2] - low) + 0.5 * mass * float(np.dot(lin, lin)) + 0.5 * float(inertia @ local ** 2)


def _counters(solver) -> tuple:
    """The solver's running counts: (Newton iterations, unconverged steps, sub-step retries)."""
    return solver.newton_iterations, solver.newton_failures, solver.stall_retries


def _trace_step(k: int, hz: float, solver, prev: tuple, box_speed: float) -> None:
    """One line about step k's solve (the counters' change since ``prev``)."""
    its, fails, retries = (a - b for a, b in zip(_counters(solver), prev))
    ratio = solver.last_ratio
    print(f"    step {k:5d} t {k / hz:7.4f} s  iterations {its:3d}  {'converged' if not fails else 'NOT converged'}"
          f"{f'  residual ratio {ratio:.3g}' if fails else ''}{'  retried as sub-steps' if retries else ''}"
          f"  box speed {box_speed:.4g} m/s", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--drop", type=float, nargs="+", default=[1e-4, 0.01])
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--hz", type=float, nargs="+", default=[240, 1000])
    ap.add_argument("--mass", type=float, nargs="+", default=[0.001, 0.005, 0.03, 0.3, 3.0])
    ap.add_argument("--n", type=int, nargs="+", default=[20], help="the cable's masses")
    ap.add_argument("--offset", type=float, nargs="+", default=[0.0], help="[m] box centre off the cable, along y")
    ap.add_argument("--yaw", type=float, nargs="+", default=[0.0], help="[rad] box turned about z")
    ap.add_argument("--shape", nargs="+", choices=("box", "hull"), default=["box"],
                    help="Bullet's box, or the same box as a convex hull of its corners (default box)")
    ap.add_argument("--no-spare", action="store_true",
                    help="switch off held_bodies.spare_thrown (the cap on an unconverged solve's reaction to a body)")
    ap.add_argument("--trace", action="store_true",
                    help="print every step's Newton solve from the first step with a contact row on the box")
    a = ap.parse_args()
    if a.no_spare:
        held_bodies.spare_thrown = lambda cs, dt: None  # (cable.py calls it through the module)
    print(f"{'shape':>5} {'n':>3} {'offset':>6} {'yaw':>4} {'drop':>7} {'hz':>5} {'mass':>6} {'peak F':>9} {'xW':>8} "
          f"{'peak v':>8} {'E/E0':>6} {'rest':>6} {'balance':>8} {'gap mm':>7} {'box z':>7} {'ms/st':>6} {'D/scl':>6} "
          "status")
    for shape, n, offset, yaw, drop, hz, m in itertools.product(a.shape, a.n, a.offset, a.yaw, a.drop, a.hz, a.mass):
        o = run(m, hz, drop, a.seconds, n, offset, yaw, a.trace, shape)
        print(f"{shape:>5} {n:3d} {offset:6.3f} {yaw:4.1f} {drop:7.4f} {hz:5.0f} {m:6.3f} {o['peak_f']:9.3f} "
              f"{o['peak_w']:8.1f} "
              f"{o['peak_v']:8.4f} {o['energy']:6.3f} {o['rest']:6.3f} {o['balance']:8.4f} {1e3 * o['gap']:7.3f} "
              f"{o['z']:7.4f} "
              f"{o['ms_per_step']:6.3f} {o['rise']:6.3f} {o['status']}", flush=True)


if __name__ == "__main__":
    main()
