"""The energy check of the free bodies the cable moves in its step (issue 23 item 2; docs/concepts/contact.md,
"A body that gains energy from contact").

The cable's own energy check (:mod:`bullet_dlo.core.kernels.monitor`) has the cable's scale, M g L plus the holders'
work: a 1 g box thrown off a cable at rest takes 1e-4 J, a thousandth of that, and went unreported. So each free body
(one dynamic link, no joints, moved inside the cable's step: :class:`~bullet_dlo.core.kernels.contact.Bodies`) keeps
its own balance while it is in the step.

The cable's step plans the body's motion with the reaction it hands over: over a Bullet step of dt the reaction's
impulse J (force and angular, :attr:`Bodies.impulse`) does the work W = J . (U + U') / 2 in the plan (U the body's
velocity Bullet had at the step's start, U' the velocity the step solved for; the same for the turn). Bullet then
moves the body under that impulse, gravity and its own contacts, which are passive (a resting contact takes energy
out, or none). So the body's mechanical energy E (kinetic, turning and -M g . x) cannot rise above the plan's work:

    D(t) = sum over the steps in contact of [E(t_k+1) - E(t_k) - W_k] <= 0 (up to Bullet's own rounding).

What makes D grow is the part of Bullet's motion the plan did not have: a held load that lagged, an apparent mass
(bullet/held_bodies.py) where Bullet moved the true one; and a plan that was not solved. A kept unconverged solve
(the stall guard's, bullet/solver.py) hands the body a reaction that balances the body's own equations but not the
cable's: the body then gains what the plan says it was given while the cable never paid for it (with the cap of
``held_bodies.spare_thrown`` off, 1 g boxes so took 2.8 and 4.4 times their drop energy with D flat). Such a step
books the work J does in Bullet's update less the kinetic energy it hands the body beyond the larger of what the body
had and what it would have without J: the bound ``spare_thrown`` enforces, so that with the cap on such a step books
what Bullet does, and with it off (or any other way round it) the excess counts as made. The check stops the cable
(status BODY_ENERGY) when D rises above its lowest value so far by more than ``energy_factor`` times the body's own
scale, so that energy Bullet's contacts took out earlier (an impact on the ground) does not hide a gain that follows.
The scale is M |g| l / 2 (l its largest extent: more than tipping it over an edge lifts it, since its centre of mass
rises by less than half its size) plus the kinetic energy it came into
the plan with and the sum of |W| since, as the cable's scale holds the holders' sum |dW|: without gravity a box
thrown at a cable has no other (the scale was 0 there, and the first rounding stopped the run).

A body several cables move in their steps (bullet/held_bodies.py, "Bodies on several cables") is booked by one of
them (the first by name) with the work of all their reactions together (:func:`plan_shared`). Steps where something
else can do work on the body are not booked: a body a user constraint holds, a body a sub-stepped cable shares with
another and something else holds (condensed, not in the cables' steps), and a step in which Bullet held the body by a
link or body that is not fixed (a robot's finger, another dynamic body), whose work the plan cannot see.
These functions hold no compiled code, so changing them does not empty the Numba cache.
"""
from __future__ import annotations

import numpy as np
import pybullet as pb

from bullet_dlo.bullet.held_bodies import holder_velocity, unloaded_velocity

MOVING = 1e-6  # [m/s] a holder moving faster than this at a contact point can do work on the body it holds


class BodyEnergy:
    """The balance of the free bodies of one contact set, by slot (ns slots): their energy at the last booked
    state, the plan's work in the coming step, the booked gain D and its lowest value so far [J], the scale's parts
    M |g| l / 2 and the energy exchanged [J]; ``report``: why the check stopped the cable (None while every body is
    within its bound)."""

    def __init__(self, client: int, free_bodies: list[int], mass: np.ndarray, gravity: np.ndarray):
        ns = len(free_bodies)
        self.energy = np.zeros(ns)  # [J] at the start of the step in the plan
        self.current = np.zeros(ns, np.bool_)  # energy was read at the last step's end (the body was in its plan)
        self.entered = np.zeros(ns, np.bool_)  # the body has been in a plan (its kinetic energy then is in the scale)
        self.work = np.zeros(ns)  # [J] the plan's work on the body in the coming Bullet step
        self.planned = np.zeros(ns, np.bool_)  # the coming step moves the body in the cable's plan
        self.gain = np.zeros(ns)  # [J] D
        self.lowest = np.zeros(ns)  # [J] min D so far
        g = float(np.linalg.norm(gravity))
        size = np.array([_largest_extent(client, b) for b in free_bodies])
        self.size = size
        self.scale = 0.5 * np.asarray(mass, float) * g * size  # [J] M |g| l / 2
        self.exchanged = np.zeros(ns)  # [J] the kinetic energy it came with plus sum |W| (module doc)
        self.report: str | None = None
        self.fixed: dict[tuple[int, int], bool] = {}  # (body, link): a fixed base (no work)


def _largest_extent(client: int, body: int) -> float:
    """The largest side [m] of the body's axis-aligned box now (its size, whatever its pose)."""
    lo, hi = pb.getAABB(body, -1, physicsClientId=client)
    return float(max(np.subtract(hi, lo)))


def mechanical_energy(m: float, inertia: np.ndarray, gravity: np.ndarray, com, lin, ang) -> float:
    """Kinetic, turning and gravity's potential energy [J] of a body of mass m [kg], world inertia [kg m^2] (3, 3),
    centre of mass com [m], velocity lin [m/s] and ang [rad/s] (on Python floats: a few NumPy calls on 3-vectors
    would cost more than the rest of the check)."""
    return kinetic_energy(m, inertia, lin, ang) - m * sum(a * b for a, b in zip(gravity.tolist(), com))


def kinetic_energy(m: float, inertia: np.ndarray, lin, ang) -> float:
    """Kinetic and turning energy [J] of a body of mass m [kg], world inertia [kg m^2] (3, 3), velocity lin [m/s]
    and ang [rad/s] (each a sequence of 3 floats)."""
    w0, w1, w2 = ang
    (i00, i01, i02), (i10, i11, i12), (i20, i21, i22) = inertia.tolist()
    turning = w0 * (i00 * w0 + i01 * w1 + i02 * w2) + w1 * (i10 * w0 + i11 * w1 + i12 * w2) + w2 * (
        i20 * w0 + i21 * w1 + i22 * w2)
    return 0.5 * m * (lin[0] * lin[0] + lin[1] * lin[1] + lin[2] * lin[2]) + 0.5 * turning


def _energy_now(cs, o: int, body: int) -> float:
    """The mechanical energy [J] of the free body of slot ``o`` (id ``body``) at the contact set's last read."""
    sh = cs.shapes
    s = int(cs._slot_row[o])
    if s >= cs.n_exact:  # a probed base link: its pose now (the probe reads it only when it probes)
        com = pb.getBasePositionAndOrientation(body, physicsClientId=cs.client)[0]
    else:
        com = sh.com[s].tolist()
    v = cs.velocity_now[o].tolist()
    return mechanical_energy(1.0 / sh.inv_mass[s], sh.inertia[s], cs.bodies.gravity, com, v[:3], v[3:])


def book(cs, support: dict, factor: float, t: float) -> str | None:
    """After Bullet's step (time t [s]): each free body of the contact set ``cs`` that the last step planned (and
    that nothing else could do work on, module doc) adds E_now - E_before - W to its gain D, its energy and
    velocity as the contact set read them (``cs.velocity_now``); ``support``: Bullet's contact points on each body
    in that step ({body: points}, :attr:`BulletWorld.support_points
    <bullet_dlo.bullet.world.BulletWorld.support_points>`). Returns the report of the first body whose D rose more
    than ``factor`` times its scale above its lowest value (and keeps it in ``cs.energy_check.report``), else
    None."""
    be = cs.energy_check
    for o, body in enumerate(cs.free_bodies):
        if not be.planned[o]:
            be.current[o] = False
            continue
        be.planned[o] = False
        e = _energy_now(cs, o, body)
        be.current[o] = True
        if _worked_on(cs, support.get(body, ())):
            be.energy[o] = e
            continue
        be.gain[o] += e - be.energy[o] - be.work[o]
        be.energy[o] = e
        be.exchanged[o] += abs(be.work[o])
        be.lowest[o] = min(be.lowest[o], be.gain[o])
        rise = be.gain[o] - be.lowest[o]
        scale = be.scale[o] + be.exchanged[o]
        if be.report is None and rise > factor * scale:
            m = 1.0 / cs.shapes.inv_mass[cs._slot_row[o]]
            be.report = (
                f"t = {t:.6g} s: body {body} ({1e3 * m:.4g} g) gained {rise:.3g} J from contact with the cable "
                f"beyond the work the cable's step did on it, more than {factor:g} x its energy scale "
                f"{scale:.3g} J (M g l / 2 = {be.scale[o]:.3g} J with l = {be.size[o]:.3g} m its size, plus the "
                f"{be.exchanged[o]:.3g} J it brought and exchanged): Bullet moved it where the cable's "
                "reaction was not planned to (an unconverged or lagging contact solve); the cable is stopped as "
                "unstable; try a smaller dt")
    return be.report


def plan(cs, dt: float, converged: bool) -> None:
    """After the cable's step of dt [s] was planned (its reaction to each free body final, :attr:`Bodies.impulse`):
    the work W = J . (U + U') / 2 it does on each body the step moved (U their velocities at the step's start,
    ``cs.velocity_now``; U' the step's solved velocity, :attr:`Bodies.vel`), booked by :func:`book` after Bullet's
    step. After a kept unconverged solve (``converged`` False) U' is the velocity J gives the body in Bullet's update,
    and W leaves out the kinetic energy that brings beyond what the body had or would have without J (module doc).
    A body entering the plan has its energy read now, and brings its kinetic energy into its scale."""
    be, bd = cs.energy_check, cs.bodies
    for o, body in enumerate(cs.free_bodies):
        be.planned[o] = bool(bd.active[o]) and body not in cs._held and body not in cs._shared
        if not be.planned[o]:
            continue
        _enter(cs, o, body)
        if converged:
            v, u, j = cs.velocity_now[o].tolist(), bd.vel[o].tolist(), bd.impulse[o].tolist()
            be.work[o] = 0.5 * sum(a * (b + c) for a, b, c in zip(j, v, u))
        else:
            be.work[o] = _unplanned_work(cs, o, dt)


def _enter(cs, o: int, body: int) -> None:
    """The free body of slot ``o`` (id ``body``) is in the coming step's plan: its energy now, if it was not read
    after the last step, and its kinetic energy into its scale the first time."""
    be = cs.energy_check
    if not be.current[o]:  # (not booked after the last step: it was not in that plan)
        be.energy[o] = _energy_now(cs, o, body)
        be.current[o] = True
        if not be.entered[o]:
            v = cs.velocity_now[o].tolist()
            be.exchanged[o] += kinetic_energy(1.0 / cs.shapes.inv_mass[cs._slot_row[o]],
                                              cs.shapes.inertia[cs._slot_row[o]], v[:3], v[3:])
            be.entered[o] = True


def plan_shared(cs, o: int, work: float) -> None:
    """The free body of slot ``o`` of the contact set ``cs``, which several cables move, is booked by this cable's
    check with ``work`` [J], the work all the cables' reactions do on it in the coming Bullet step
    (:func:`bullet_dlo.bullet.held_bodies.settle`). What else holds it is booked as for a body on one cable: a fixed
    holder does no work, a step in which a moving one held it is not booked (:func:`book`), nor a body a user
    constraint holds."""
    be = cs.energy_check
    if cs.free_bodies[o] in cs._held:
        return
    _enter(cs, o, cs.free_bodies[o])
    be.planned[o] = True
    be.work[o] = work


def _unplanned_work(cs, o: int, dt: float) -> float:
    """The work [J] a kept unconverged solve's reaction (impulse J) does on the body of slot ``o`` in Bullet's update
    of dt [s], less the kinetic energy it hands the body beyond the larger of what the body had and what it would
    have without J (the bound ``held_bodies.spare_thrown`` enforces)."""
    sh, impulse = cs.shapes, cs.bodies.impulse[o]
    s = int(cs._slot_row[o])
    m, inertia = 1.0 / sh.inv_mass[s], sh.inertia[s]
    turn = np.linalg.pinv(inertia)
    u_free, w_free = unloaded_velocity(cs, o, dt, turn)
    u_j, w_j = u_free + impulse[:3] / m, w_free + turn @ impulse[3:]
    u, w = cs.velocity_now[o, :3], cs.velocity_now[o, 3:]

    def kinetic(lin, ang):
        return kinetic_energy(m, inertia, lin.tolist(), ang.tolist())

    excess = max(0.0, kinetic(u_j, w_j) - max(kinetic(u, w), kinetic(u_free, w_free)))
    return 0.5 * float(impulse[:3] @ (u + u_j)) + 0.5 * float(impulse[3:] @ (w + w_j)) - excess


def _worked_on(cs, points) -> bool:
    """Whether Bullet held a body in its last step by a body or link that moves at any of its contact ``points``
    (:attr:`BulletWorld.support_points <bullet_dlo.bullet.world.BulletWorld.support_points>` of the body), one that
    can do work on it (module doc). A fixed base (mass 0) is known once; anything else is asked for its velocity."""
    fixed = cs.energy_check.fixed
    for point, _normal, _load, holder, link in points:
        key = (holder, link)
        if key not in fixed:
            fixed[key] = link < 0 and pb.getDynamicsInfo(holder, link, physicsClientId=cs.client)[0] == 0.0
        if not fixed[key] and float(np.linalg.norm(holder_velocity(holder, link, point, cs.client))) > MOVING:
            return True
    return False
