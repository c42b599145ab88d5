"""Free bodies that something besides the cable holds, in the cable's implicit step (docs/concepts/contact.md,
"Bodies resting on the cable").

A free body (one dynamic link, no joints) that the cable touches moves inside the cable's step (its velocity is
six unknowns of the step's Newton solve, :class:`~bullet_dlo.core.kernels.contact.Bodies`). When Bullet also holds
it (a contact with the ground or another body in the last step) or a user constraint does, the cable's step does
not know that support. It takes it as measured over Bullet's last step, from the body's own motion:

    F_held = M (U - U_before) / dt - M g - F_applied,   tau_held = I (Omega - Omega_before) / dt - tau_applied,

F_applied, tau_applied the reaction this cable applied in that step (so F_held is Bullet's contacts, constraints,
damping, other cables' and a user's forces, however Bullet found them), and the body's backward Euler in the step
becomes M (U' - U) = h (M g + F_held + F). The support then arrives in the same step as the cable's reaction: at
rest the prediction of the body's motion is Bullet's, and the body does not sink g h^2 into the cable (the
condensed contact's softness, which these bodies had before).

The measured load lags one step. Where the cable pushes the body against what holds it (a board a constraint holds
under the cable, a box on the table with the cable across it) a light body would yield in the cable's step while
Bullet holds it rigidly, and the lag makes the cable bounce (a 30 g board under the 30 g cable gained energy at 60
and 120 Hz). There the body takes an apparent mass M_a = M + CARRY_FACTOR m_c (m_c the cable's mass at those rows, whose
normals lie within 45 degrees of the held load; the holder, rigid in Bullet, takes the push) in the step:
M_a (U' - U) = h (M g + F_held + F).

The lag also makes the step move the body where Bullet's holder does not (a 1 g box leaning on the cable and the table
at 60 Hz: a roll of 7 mrad/s planned every step, 0.06 mrad/s in Bullet), by about (change of the load / M) dt^2 a
step. The friction springs on the body (k_t = k_n, k_n = alpha m_c / h^2: stiff for the cable's mass, not the body's)
stick only within mu times the penetration, 6 nm under that box: far below that miss, so every row slid at its cap in
the direction of the miss and light boxes crept for seconds (0.05-0.3 mm/s, where Bullet alone rests them). On a held
body they are put in series with its mass, k_t / (1 + dt^2 sum k_t / M) (:func:`soften_friction`; the condensed
contact's rule, on translation), so that they stick within about mu (f_n / M) dt^2 times the rows, the scale of that
miss.

A holder whose load is below CARRY_MIN of the body's weight gives no apparent mass: it holds nothing rigidly, and the
direction of so small a load is noise (a 1 g box touching the ground at 0.5 mN was planned 24 times as heavy and
thrown).
After a kept unconverged solve the reaction handed to a free body is capped by the kinetic energy it brought
(:func:`spare_thrown`).

Across Bullet steps the measured load is a fixed-point iteration between two solvers: the cable's step given the
holder's load, Bullet's step given the cable's reaction. Taking each step's measurement whole, that iteration did
not converge for a body resting on one ground point and on the cable (pybullet_data's duck, a V-HACD compound: a
period-4 rocking of +-0.45 mm at 60 Hz under 2 g, 0.3 m/s after 2 s; the ground's load swinging between 0.88 and
1.10 of the weights at 240 Hz under 100 g, where Bullet rests the duck alone). The load is under-relaxed, each step
moving it by RELAX of the way to the new measurement (a mode the full update flips, a factor -1 a step, it damps
to 0): at rest it is the measured load, in a change it lags about a step more.

Bullet's contact points on the body (the ground, another body) carry a part of that load that the body's own motion
in the step decides: a body that leaves its holder takes no more load from it. Taken whole from the last step, that
part made the step plan a body on support it had lost: the duck of tests/bullet/test_contact_compound.py, tumbling
back onto the cable and the ground at 60 Hz, lost its one ground point's 0.73 N in Bullet's next step while the plan
still counted it; the plan lifted the duck at 0.054 m/s where Bullet dropped it at 0.06 m/s, 1.4 mm into the cable
in one step. So each of those points (:attr:`BulletWorld.support_points
<bullet_dlo.bullet.world.BulletWorld.support_points>`: the HOLD_POINTS that carried most) is a holder in the step
(``Bodies.hold_*``): its normal load is taken as measured (not relaxed; the rest of the load is) and lets go by
HOLD_RATE (M / dt) v_n while the body's point leaves it at v_n, down to nothing (the step's Newton solve has it in
its residual, potential and Schur block). Pressing into it adds nothing: there the apparent mass above holds the
body. What was tried and measured (2026-12-02, ``python demos/resting_bodies.py`` off-centre drop grids, docs/concepts/
contact.md): a holder as stiff both ways (HOLD_RATE 3-100, with or without the apparent mass, with the point's load
growing at most to its holder's whole load) kept 1 g boxes leaning on the cable and the table at 60 and 120 Hz from
coming to rest; the points of one holder taken as one (at their centre of load) kept a 2 g duck rocking between its
two ground points at 240 Hz (Bullet's contact distance is not taken as room to close: a loaded point 0.01 mm off the
ground at 240 Hz would count as leaving at 2.4 mm/s, which lets go of 5.8 N under the 100 g duck). As it is, a 3 kg
box rolling its load from one ground point of an edge to the other loses the part the rising point lets go (the other
takes no more): one of the 72 drops at 60 Hz is stopped as energy growth. HOLD_RATE 30 kept the three 3 kg drops that
fail at 100 but failed five others (one stopped), and let the duck at 1.5 m/s end 0.12 mm inside the cable; 50 was
no better.
Bodies on several cables. A free body that two or more cables touch moves in each cable's step with its whole mass and
the other cables' reactions, each linear in the body's velocity delta = (U', Omega'): impulse_i - E_i (delta - ref_i),
E_i = -d impulse_i / d delta (6 x 6, its load mass: cable i's block of the Schur complement of its Newton matrix, its
rows' J^T G J less C^T A^-1 C as its nodes yield; ``Bodies.load_mass``), kept from cable i's last plan (:class:`Share`)
and put in the body's mass matrix (``Bodies.other_mass``, :func:`couple`). ref_i is the velocity of cable i's plan when
that plan is of this step (the cables before this one); when it is of the last step, the velocity that keeps its
contacts as they are (the mean velocity of its nodes at the rows, no turn), since a contact's spring load follows the
body's position: its load stays until the body moves into or out of it. After every cable has planned, the body's
velocity under all the reactions together, (M_b + sum E_i) delta* = M_b U + dt M g + sum (impulse_i + E_i vel_i), is
where Bullet's step takes it when each cable hands it impulse_i - E_i (delta* - vel_i) (:func:`settle`); a cable whose
plan moved the body more than MISMATCH from delta* (at its radius of gyration for the turn) is planned again first with
the others' reactions of this step, up to SHARED_PASSES rounds (block Gauss-Seidel on the body's velocity:
:func:`unsettled`; in the first step of contact every cable planned without the others and carried the whole body, and
the cable with the far support then tipped the box over the other one in its plan). This is a joint Newton step of the
cables and the body, linearised about each cable's plan, without a joint solve. Mass splitting (:func:`share`, each
cable's step with 1/k of the mass, Tonge et al. 2012, one pass) remains for cables that take several sub-steps per
Bullet step (the load masses relate one sub-step's impulse to its velocity there): each share turns under its own
cable's support alone, about h^2 g |r|^2 M / I a step, which put boxes through two cables at 60 Hz
(docs/concepts/contact.md, "A body on two cables"). A shared body that something else holds too (the table under a box
tipped across two cables) is held as above and coupled on top: its measured load leaves out every cable's reaction
(:meth:`BulletWorld.applied_by_others <bullet_dlo.bullet.world.BulletWorld.applied_by_others>`), the other cables' load
masses join its apparent mass, and the combined velocity counts that load. (Before, such a body kept the condensed
contact, and boxes went through the cables to the table at 60 Hz; with sub-steps it still does.)

These functions hold no compiled code, so changing them does not empty the Numba cache.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pybullet as pb

CARRY_FACTOR = 10.0  # apparent mass per kg of cable pushing a held body against its holder
CARRY_COS = math.cos(math.radians(45.0))  # a row pushes the body against its holder within 45 degrees of the load
CARRY_MIN = 0.25  # a holder whose load is below this share of the body's weight carries no apparent mass
RELAX = 0.5  # share of the newly measured load taken each step (1: the last step's load as measured)
HOLD_RATE = 100.0  # a holder lets go of HOLD_RATE M v_n / dt of its load as the body leaves it at v_n [m/s]


def measure(cs, dt: float, stepped: bool, supported, support: dict, others_applied: dict, near=None) -> list[int]:
    """The slots of the free bodies of the contact set ``cs`` (:class:`~bullet_dlo.bullet.contact.ContactSet`) that
    something besides this cable holds (``supported``: bodies with a Bullet contact in the last step; the bodies a
    user constraint holds; not the bodies another cable shares that keep the condensed contact), with, in
    ``cs.held_load``, the force and torque [N, N m] (about the centre of mass, world frame) the world put on each in
    Bullet's last step of dt [s] besides gravity and the cables' reactions (this one's, and ``others_applied`` {body:
    force and torque} of the others; module doc); before a step was measured (a new contact set), the body's weight.
    After a re-plan (``stepped`` False) the last step's. ``support`` {body: Bullet's contact points on it in the last
    step} (:attr:`BulletWorld.support_points <bullet_dlo.bullet.world.BulletWorld.support_points>`): their normal
    forces, ``cs.support_load``, are taken whole, and only the rest of the load (friction, constraints, ...) is
    relaxed; the step changes them with the body's motion (:func:`hold_points`). ``near`` (S,) bool: the bodies that
    may come within the cable's reach in the coming step (:meth:`ContactSet._near_free_bodies
    <bullet_dlo.bullet.contact.ContactSet._near_free_bodies>`); only their loads are measured (None: every body's).
    Every body's velocity is kept, so a body coming near takes its whole load as measured over the last step."""
    sh, rows = cs.shapes, cs._slot_row
    if cs._spared and stepped:  # Bullet moved a spared body (spare_thrown) where the plan did not: as an impact, the
        for body in cs._spared:  # penetration that made is let out without the penalty's energy (Store.sink)
            sh.impact[cs.body_ids == body] = True
        cs._spared.clear()
    now = np.concatenate((sh.lin_vel[rows], sh.ang_vel[rows]), axis=1)
    for o in np.flatnonzero(rows >= cs.n_exact).tolist():  # a probed base link: read now
        lin, ang = pb.getBaseVelocity(cs.free_bodies[o], physicsClientId=cs.client)
        now[o] = (*lin, *ang)
    cs.velocity_now = now
    if not stepped and cs._seen.any():
        return cs._measured
    want = cs._held.union(supported).difference(cs._condensed) if supported or cs._held else ()
    before = cs._measured  # held in the last step too: its load there is the one to relax from
    measured = []
    for o, body in enumerate(cs.free_bodies):
        if body not in want or (near is not None and not near[o]):
            continue
        s = int(rows[o])
        m = 1.0 / sh.inv_mass[s]
        pressed = support_load(cs, o, s, support.get(body, ()))
        if cs._seen[o] and stepped:
            dv = (now[o] - cs._vel_before[o]) / dt
            load = np.empty(6)
            load[:3] = m * (dv[:3] - cs.bodies.gravity) - cs._applied[o, :3]
            load[3:] = sh.inertia[s] @ dv[3:] - cs._applied[o, 3:]
            if body in others_applied:
                load -= others_applied[body]
            relax = RELAX if o in before else 1.0
            rest = cs.held_load[o] - cs.support_load[o]
            rest += relax * (load - pressed - rest)  # (module doc: the lag's limit cycle)
            cs.held_load[o] = rest + pressed
        else:  # no step measured yet (a new contact set): the holder carries the body's weight
            cs.held_load[o, :3] = -m * cs.bodies.gravity
            cs.held_load[o, 3:] = 0.0
        cs.support_load[o] = pressed
        measured.append(o)
    cs._measured = measured
    if not stepped:
        return measured
    cs._vel_before[:] = now
    cs._seen[:] = True
    return measured


def hold(cs, measured: list[int], dt: float, mass: np.ndarray) -> None:
    """Put the measured loads of the slots ``measured`` (:func:`measure`) into the coming step's free bodies
    (``cs.bodies``, just loaded by the detector), with the apparent mass where the cable pushes a body against its
    holder (module doc; ``mass`` (n,) [kg] the cable's node masses): M_a (U' - U_0) = h (M_a g + F) with U_0 = U +
    h ((M g + F_held) / M_a - g) is M_a (U' - U) = h (M g + F_held + F), the load an impulse over the Bullet step."""
    bd, sh, c = cs.bodies, cs.shapes, cs.contacts
    g = bd.gravity
    count = int(c.count[0])
    for o in measured:
        if not bd.active[o]:
            continue  # no row of this cable touches it this step: it is not in the step (nor its inertia loaded)
        s = int(cs._slot_row[o])
        m = 1.0 / sh.inv_mass[s]
        held = cs.held_load[o, :3]
        # the cable's mass at the rows that push the body against what holds it (the row's normal, body to cable,
        # within 45 degrees of the held load). Any row with a part along it (> 0) also took in the side rows of a 1 g
        # box tipping off the cable whose corner had just hit the ground (a load of one impact, mostly upwards): its
        # apparent mass, 40x its own, pushed back the penetration of Bullet's impact and the box left at 3-20 m/s
        # A holder that carries next to nothing (its load under CARRY_MIN of the body's weight) holds nothing rigidly,
        # and the direction of such a load is noise: a 1 g box touching the ground at 0.5 mN took 24x its mass from
        # rows along the table, and Bullet's update of its true mass under that reaction threw it at 3.6 m/s
        load = float(np.linalg.norm(held))
        k = np.flatnonzero((bd.slot[:count] == o) & (c.normal[:count] @ held > CARRY_COS * load))
        if load < CARRY_MIN * m * float(np.linalg.norm(g)):
            k = k[:0]
        carried = float(c.weight[k, 0] @ mass[c.node[k, 0]] + c.weight[k, 1] @ mass[c.node[k, 1]]) if k.size else 0.0
        scale = 1.0 + CARRY_FACTOR * carried / m  # the apparent mass over the true one
        bd.mass[o] = scale * m
        bd.inertia[o] *= scale
        # (kept apart in held_dv too: sub-steps of the Bullet step each take their share, bullet.kernels.spread_held)
        bd.held_dv[o, :3] = dt * ((m * g + held) / (scale * m) - g)
        try:
            bd.held_dv[o, 3:] = dt * np.linalg.solve(bd.inertia[o], cs.held_load[o, 3:])
        except np.linalg.LinAlgError:  # a point or flat body's inertia: no turn where it has none
            bd.held_dv[o, 3:] = dt * (np.linalg.pinv(bd.inertia[o]) @ cs.held_load[o, 3:])
        bd.vel[o] += bd.held_dv[o]
        soften_friction(c, bd, o, count, m, dt)
        hold_points(cs, o, dt)


def support_load(cs, o: int, s: int, points) -> np.ndarray:
    """The force and torque [N, N m] (about the centre of mass, world frame) of the normal forces of Bullet's contact
    points ``points`` on the body of slot ``o`` (shape row ``s``), the HOLD_POINTS that carried most, which it keeps
    for :func:`hold_points` (arm [m], normal into the body, normal force [N], holder body and link, point [m])."""
    kept, out = [], np.zeros(6)
    com = cs.shapes.com[s]
    for point, normal, load, holder, link in sorted(points, key=lambda p: -p[2])[:cs.bodies.hold_load.shape[1]]:
        arm, normal, load = np.subtract(point, com), np.asarray(normal), max(load, 0.0)
        out[:3] += load * normal
        out[3:] += load * np.cross(arm, normal)
        kept.append((arm, normal, load, holder, link, point))
    cs._support[o] = kept
    return out


def hold_points(cs, o: int, dt: float) -> None:
    """Bullet's contact points on the body of slot ``o`` in the last step of dt [s] (:func:`support_load`) into the
    coming step's holders (:class:`~bullet_dlo.core.kernels.contact.Bodies`, hold_*), each with the holder's normal
    velocity there and the rate HOLD_RATE M / dt [N s/m] at which it lets go. (Bullet's contact distance is not
    taken as room to close: a loaded point 0.01 mm off the ground at 240 Hz would then let go of a resting body's
    whole weight.)"""
    bd, cid = cs.bodies, cs.client
    kept = cs._support[o]
    for p, (arm, normal, load, holder, link, point) in enumerate(kept):
        bd.hold_arm[o, p] = arm
        bd.hold_normal[o, p] = normal
        bd.hold_load[o, p] = load
        bd.hold_vel[o, p] = float(holder_velocity(holder, link, point, cid) @ normal)
    bd.hold_count[o] = len(kept)
    bd.hold_c[o] = HOLD_RATE * bd.mass[o] / dt


def spare_thrown(cs, dt: float) -> None:
    """After a planned step whose contact solve did not converge: the reaction handed to each free body is scaled
    down, where needed, so that Bullet's update under it leaves the body with no more kinetic energy than it had at
    the step's start or would have after the step without it: its velocity + dt (g + F_held / M) + impulse / M, and
    the turn I^-1 dt tau_held plus I^-1 times the angular impulse (F_held, tau_held the load the step counted from
    what else holds it, :func:`measure`; none for a body nothing else holds). A passive contact does not throw a
    body, and an unconverged solve's reaction is not the contact's: kept, such solves spun a 1 g box landing with its
    edge on the cable from 8 to 65 rad/s in one step at 240 Hz (6.4 times the energy it fell with). The cable felt
    the whole reaction: the momentum handed to the body is short by what is scaled away, in a step already off its
    balance; the body's move then counts as unplanned (an impact, :func:`measure`). dt [s]: the Bullet step."""
    bd, sh = cs.bodies, cs.shapes
    for o in range(len(cs.free_bodies)):
        if not bd.active[o]:
            continue
        s = int(cs._slot_row[o])
        m, inertia = 1.0 / sh.inv_mass[s], sh.inertia[s]
        lin, w = cs.velocity_now[o, :3], cs.velocity_now[o, 3:]
        turn = np.linalg.pinv(inertia)  # (a point or flat body has no turn about some axes)
        u0, w0 = unloaded_velocity(cs, o, dt, turn)
        du, dw = bd.impulse[o, :3] / m, turn @ bd.impulse[o, 3:]
        a = 0.5 * m * du @ du + 0.5 * dw @ inertia @ dw  # the energy after, a a^2 + b a + c, of the share a of it
        b = m * u0 @ du + dw @ inertia @ w0
        c = 0.5 * m * u0 @ u0 + 0.5 * w0 @ inertia @ w0
        had = max(0.5 * m * lin @ lin + 0.5 * w @ inertia @ w, c)
        if a + b + c <= had or a <= 0.0:
            continue
        share = (-b + math.sqrt(max(b * b - 4.0 * a * (c - had), 0.0))) / (2.0 * a)  # the larger root (c <= had)
        bd.impulse[o] *= min(max(share, 0.0), 1.0)
        cs._spared.add(cs.free_bodies[o])


def unloaded_velocity(cs, o: int, dt: float, turn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The velocity [m/s] and turn rate [rad/s] Bullet's step of dt [s] would leave the free body of slot ``o`` with
    without this cable's reaction: its velocity at the step's start (``cs.velocity_now``) plus dt (g + F_held / M)
    and dt I^-1 tau_held (``turn``: the pseudo-inverse of its world inertia), the held load as the step counted it
    (:func:`measure`; none for a body nothing else holds)."""
    s = int(cs._slot_row[o])
    m = 1.0 / cs.shapes.inv_mass[s]
    load = cs.held_load[o] if o in cs._measured else np.zeros(6)
    return (cs.velocity_now[o, :3] + dt * (cs.bodies.gravity + load[:3] / m),
            cs.velocity_now[o, 3:] + dt * (turn @ load[3:]))


def holder_velocity(body: int, link: int, point, cid: int) -> np.ndarray:
    """The velocity [m/s] of the holder's (body, link) material point at ``point`` [m] now (zero when it is fixed)."""
    if link < 0 and pb.getDynamicsInfo(body, link, physicsClientId=cid)[0] == 0.0:
        return np.zeros(3)
    if link < 0:
        lin, ang = pb.getBaseVelocity(body, physicsClientId=cid)
        com = pb.getBasePositionAndOrientation(body, physicsClientId=cid)[0]
    else:
        st = pb.getLinkState(body, link, computeLinkVelocity=1, physicsClientId=cid)
        com, lin, ang = st[0], st[6], st[7]
    return np.asarray(lin) + np.cross(ang, np.subtract(point, com))


def soften_friction(c, bd, o: int, count: int, m: float, dt: float) -> None:
    """Put the friction springs of the rows on the held body of slot ``o`` (mass m [kg]) in series with its mass over
    the Bullet step dt [s]: k_t <- k_t / (1 + dt^2 lambda), lambda = sum k_t / m [1/s^2] over its rows (module doc).
    The body's translation in series only: with the rotation too (lambda bounded with the smallest principal inertia,
    as ``_condense_bodies`` does) k_t fell a million-fold under a 1 g box and every box from 1 g to 30 g crept alike at
    0.08 mm/s for 2 s. dt^2 lambda is alpha m_c / m a row at any dt (alpha = 1e4, m_c the cable's mass at the row; more
    where a row stiffens to a heavy body's load, contact._follow_loads):
    under the leaning box (six rows on 1.5 g nodes) k_t drops 1e5-fold under 1 g and 33-fold under 3 kg; the rows then
    stick within mu f_n / k_t, about mu (f_n / m) dt^2 times the rows: 0.8-1.4 mm at 60 Hz and 2-7 um at 1 kHz under a 1
    g or a 3 kg leaning box (the price: that much elastic slip before a row slides)."""
    k = np.flatnonzero(bd.slot[:count] == o)
    if k.size:
        c.k_t[k] /= 1.0 + dt * dt * float(c.k_t[k].sum()) / m


COUPLE_SHARED = True
"""Move a body that several cables share (and nothing else holds) in each cable's step with its whole mass and the
other cables' reactions (:func:`couple`, :func:`settle`); False: with its share of the mass (:func:`share`), as before
the afternoon of 2026-12-05 (for comparisons)."""

MISMATCH = 1e-5  # [m] a cable's plan of a shared body this far from all the cables' together is planned again
SHARED_PASSES = 4  # at most this many plans again of the cables sharing bodies, per Bullet step

SPLIT_SHARED = True
"""Move a body that several cables share (and nothing else holds) in each cable's step with its share of the mass
(:func:`share`); False: the condensed contact for every shared body, as before 2026-12-05 (for comparisons)."""


def sharing(cs, shared, supported, support, coupling: bool = False) -> frozenset:
    """Of the free bodies another cable's contacts also touched in the last step (``shared``: {body: cables sharing
    it}, :meth:`BulletWorld.shared_bodies <bullet_dlo.bullet.world.BulletWorld.shared_bodies>`), the ones this
    cable's step takes with their share of the mass (``cs._split``, applied by :func:`share`), and the ones it
    leaves to the condensed contact (returned): those something else holds too (a user constraint, or Bullet: a
    point of ``support`` {body: points} in ``supported`` that carried load), whose measured load would hold the
    other cables' reactions. (Bullet lists a pair's points up to 2 cm apart: a box resting on two cables 4 mm above
    the table has points on it that carry nothing.) ``coupling``: the cable's step takes every shared body with the
    other cables' reactions (:func:`couple`), a held one too (its measured load then leaves out every cable's
    reaction): none is left to the condensed contact. Sets ``cs._shared`` (all of them: no body-energy booking by
    this cable's plan)."""
    if not shared:  # (the common case, every step of a scene with free bodies: nothing to build)
        cs._split, cs._shared = {}, frozenset()
        return cs._shared
    shares = {b: k for b, k in shared.items() if b in cs._slot_of}
    if coupling:
        cs._split = shares
    else:
        held = cs._held.union(b for b in supported if any(p[2] > 0.0 for p in support.get(b, ())))
        cs._split = {b: k for b, k in shares.items() if b not in held} if SPLIT_SHARED else {}
    cs._shared = frozenset(shares)
    return cs._shared.difference(cs._split)


def share(cs) -> None:
    """Each body shared by k cables (``cs._split``) in this cable's coming step with 1/k of its mass and inertia (as
    the detector loaded them), so with 1/k of its weight: the k cables' reactions, applied together in Bullet's step,
    move the whole body as each share moved in its cable's step where the cables carry equal shares (mass splitting,
    Tonge et al. 2012, one pass: otherwise the average of the shares' motions, and each share turns under its own
    cable's support alone, which the plan of its contacts sees and Bullet does not: about h^2 g |r|^2 M / I at a
    contact at r from the centre of mass, 0.1 mm at 240 Hz and 1.6 mm at 60 Hz for a 40 x 40 x 20 mm box on cables 20
    mm apart; docs/concepts/contact.md, "A body on two cables")."""
    bd = cs.bodies
    for b, k in cs._split.items():
        o = cs._slot_of[b]
        if bd.active[o]:
            bd.mass[o] /= k
            bd.inertia[o] /= k


@dataclasses.dataclass(frozen=True)
class Share:
    """One cable's part in a free body that several cables touch, as its last plan left it (:func:`shares_of`): the
    reaction of its rows on the body, linear in the body's velocity delta = (U', Omega') about the planned one,
    impulse - load_mass (delta - vel) (module doc, "Bodies on several cables")."""

    cs: object  # the cable's ContactSet
    slot: int  # the body's slot in it
    impulse: np.ndarray  # (6,) [N s, N m s] the rows' reaction on the body over the Bullet step (torque about the com)
    load_mass: np.ndarray  # (6, 6) [kg, kg m, kg m^2] -d impulse / d delta, symmetrised
    vel: np.ndarray  # (6,) [m/s, rad/s] the body's velocity at the step's end in that plan
    rest: np.ndarray  # (6,) the velocity that keeps its contacts as they are: its nodes' mean velocity there, no turn
    step: int  # the world's step count when it was planned
    coupled: bool  # the plan had other cables' reactions on the body (other_mass)


def mass_matrix(mass: float, inertia: np.ndarray) -> np.ndarray:
    """The 6 x 6 mass matrix diag(M I, I_world) [kg, kg m^2] of a body of mass [kg] and world inertia (3, 3)."""
    out = np.zeros((6, 6))
    out[:3, :3] = mass * np.eye(3)
    out[3:, 3:] = inertia
    return out


def body_mass(cs, o: int) -> np.ndarray:
    """The mass matrix (:func:`mass_matrix`) of the free body of slot ``o`` at the step's start, as Bullet has it."""
    s = int(cs._slot_row[o])
    return mass_matrix(1.0 / cs.shapes.inv_mass[s], cs.shapes.inertia[s])


def shares_of(cs, step: int, v: np.ndarray) -> dict[int, Share]:
    """The Share of each free body in the plan just made by the cable of contact set ``cs`` (its world at step count
    ``step``) for the bodies it moved in its step; v (n, 3) [m/s]: the cable's planned node velocities."""
    bd, c = cs.bodies, cs.contacts
    count = int(c.count[0])
    out = {}
    for o in np.flatnonzero(bd.active).tolist():
        e = bd.load_mass[o]
        k = np.flatnonzero(bd.slot[:count] == o)
        rest = np.zeros(6)
        if k.size:
            w = c.weight[k]
            rest[:3] = (w[:, :1] * v[c.node[k, 0]] + w[:, 1:] * v[c.node[k, 1]]).mean(axis=0)
        out[cs.free_bodies[o]] = Share(cs, o, bd.impulse[o].copy(), 0.5 * (e + e.T), bd.vel[o].copy(), rest, step,
                                       bool(bd.other_mass[o].any()))
    return out


def carries(impulse: np.ndarray, load_mass: np.ndarray) -> bool:
    """Whether a cable's plan of a body loads it: a reaction (impulse (6,)) or a load mass (6, 6). A cable within reach
    whose rows carry nothing neither moves the body nor joins its combination (:func:`couple`, :func:`unsettled`)."""
    return bool(impulse.any() or load_mass.any())


def couple(cs, others: dict[int, list[tuple]], dt: float) -> None:
    """Each body of ``cs._split`` (touched by other cables, nothing else holding it) into the coming step of dt [s]
    with its whole mass and the other cables' reactions, ``others`` {body: [(impulse, load_mass, ref)]}, each linear
    in the body's velocity delta, impulse - load_mass (delta - ref) (:meth:`BulletWorld.other_shares
    <bullet_dlo.bullet.world.BulletWorld.other_shares>`): bodies.other_mass = sum load_mass, and the body's start
    velocity V (bodies.vel, U before) solves (M_b + other_mass) V = M_b U + sum (impulse + load_mass ref). The
    friction springs on it are put in series with its mass (:func:`soften_friction`): at their full stiffness (that
    of the cable's mass) a row's stick or slip changed between the plans of a step, and a 10 kg box across cables 30
    mm apart at 60 Hz kept rocking by 0.03 mm at 2-3 mm/s (period three steps) with mu 0.5 and 1."""
    bd = cs.bodies
    count = int(cs.contacts.count[0])
    for b in cs._split:
        o = cs._slot_of[b]
        parts = [p for p in others.get(b, ()) if carries(p[0], p[1])]
        if not bd.active[o] or not parts:
            continue
        mb = mass_matrix(float(bd.mass[o]), bd.inertia[o])  # the step's: a held body's apparent one (hold)
        e = sum(p[1] for p in parts)
        rhs = mb @ bd.vel[o] + sum(p[0] + p[1] @ p[2] for p in parts)
        bd.vel[o] = np.linalg.solve(mb + e, rhs)
        bd.held_dv[o] = np.linalg.solve(mb + e, mb @ bd.held_dv[o])  # (the held load's part of it, as above)
        bd.other_mass[o] = e
        if o not in cs._measured:  # (hold softened a held body's already)
            soften_friction(cs.contacts, bd, o, count, float(bd.mass[o]), dt)
        cs._coupled = True


def _together(parts: list[Share], dt: float) -> np.ndarray:
    """The velocity delta* [m/s, rad/s] of a body under the reactions of the cables' plans ``parts`` together, each
    linear about its own plan (:func:`settle`); dt [s] the Bullet step. A body something else holds moves by the
    plans' own equation (:func:`_held_together`)."""
    for p in parts:  # what else holds it, as measured over Bullet's last step (measure)
        if p.slot in p.cs._measured and p.cs.bodies.active[p.slot]:
            return _held_together(parts, p.cs, p.slot, dt)
    cs, o = parts[0].cs, parts[0].slot
    mb = body_mass(cs, o)
    e = sum(p.load_mass for p in parts)
    rhs = mb @ cs.velocity_now[o] + sum(p.impulse + p.load_mass @ p.vel for p in parts)
    rhs[:3] += dt * mb[0, 0] * cs.bodies.gravity
    for p in parts:  # measured but in no plan's step (no hold points loaded): its load alone
        if p.slot in p.cs._measured:
            rhs += dt * p.cs.held_load[p.slot]
            break
    return np.linalg.solve(mb + e, rhs)


HELD_ITERATIONS = 20  # at most this many Newton steps over the holders' states for a held shared body's velocity


def _held_together(parts: list[Share], cs, o: int, dt: float) -> np.ndarray:
    """:func:`_together` for a body that something else holds, slot ``o`` of contact set ``cs`` measured it (its
    held load, apparent mass and Bullet's hold points of this step, :func:`hold`): the equation each cable's plan
    solved for the body, M_a (delta - U) = dt (M g + F_held) + H(delta) + sum (impulse_i - load_mass_i (delta -
    vel_i)), M_a its apparent mass and inertia in the step, H the holders' change of load (each lets go of hold_c v_n
    while the body's point leaves it at v_n, down to its whole load; pressing adds nothing), solved by Newton over the
    holders' states from the first plan's velocity. With one plan that takes the others' reactions as they are, its
    own velocity solves it (leaving the hold points and the apparent mass out, as this did until 2026-12-05, put a
    leaning box 0.047 rad/s off the plan of the one cable that carried it)."""
    bd = cs.bodies
    ma = mass_matrix(float(bd.mass[o]), bd.inertia[o])
    m = 1.0 / cs.shapes.inv_mass[cs._slot_row[o]]
    e = sum(p.load_mass for p in parts)
    base = ma @ cs.velocity_now[o] + dt * cs.held_load[o] + sum(p.impulse + p.load_mass @ p.vel for p in parts)
    base[:3] += dt * m * bd.gravity
    delta = parts[0].vel.copy()
    jn = np.empty(6)
    states = None
    for _ in range(HELD_ITERATIONS):
        k, rhs, now = ma + e, base.copy(), []
        for q in range(int(bd.hold_count[o])):
            a, n = bd.hold_arm[o, q], bd.hold_normal[o, q]
            jn[:3], jn[3:] = n, np.cross(a, n)
            c, load = float(bd.hold_c[o]), float(bd.hold_load[o, q])
            change = -c * (float(jn @ delta) - float(bd.hold_vel[o, q]))
            now.append(0 if change >= 0.0 else 1 if change <= -load else 2)
            if change >= 0.0:  # pressing into it: the apparent mass holds the body there
                continue
            if change <= -load:  # gone: it lets go of its whole load
                rhs -= dt * load * jn
                continue
            k = k + dt * c * np.outer(jn, jn)  # letting go in proportion to the speed it leaves at
            rhs += dt * c * float(bd.hold_vel[o, q]) * jn
        delta = np.linalg.solve(k, rhs)
        if now == states:  # the holders' states held: the solution of that linear piece
            break
        states = now
    return delta


def _settled(parts: dict[str, Share], step: int) -> list[Share] | None:
    """The Shares of step count ``step`` of a body that :func:`settle` combines, or None (one cable alone moved
    it)."""
    now = [p for p in parts.values() if p.step == step]
    if not now or (len(now) == 1 and not now[0].coupled):
        return None
    return now


def unsettled(shares: dict[int, dict[str, Share]], step: int, dt: float) -> tuple[set[str], dict]:
    """The cables whose plan of step count ``step`` moved a body they share (:func:`settle`) more than MISMATCH [m]
    away from where all the cables' reactions together take it in the Bullet step of dt [s] (at its radius of
    gyration for the turn), and those velocities, {body: delta*}: their plans assumed the others' reactions of the
    step before, or none (the first step in contact). Planned again with the others' reactions of this step (block
    Gauss-Seidel), they agree. A plan whose rows carry nothing (no reaction, no load mass) does not count: where it
    leaves one plan that took no other cable's reaction, that plan's velocity is the body's."""
    out, targets = set(), {}
    for body, parts in shares.items():
        now = _settled(parts, step)
        if now is None:
            continue
        loaded = [p for p in now if carries(p.impulse, p.load_mass)]
        if len(loaded) <= 1 and not any(p.coupled for p in loaded):
            # the others' rows carry nothing (within reach, not touching): the loaded plan stands as made (to the bit;
            # _together would give it to round-off), and with none loaded nothing is handed
            targets[body] = (loaded or now)[0].vel.copy()
            continue
        target = targets[body] = _together(now, dt)
        cs, o = now[0].cs, now[0].slot
        s = int(cs._slot_row[o])
        gyration = math.sqrt(1.5 * float(np.trace(cs.shapes.inertia[s])) * cs.shapes.inv_mass[s])
        for name, p in parts.items():
            d = target - p.vel
            if p.step == step and dt * (np.linalg.norm(d[:3]) + gyration * np.linalg.norm(d[3:])) > MISMATCH:
                out.add(name)
    return out, targets


def settle(shares: dict[int, dict[str, Share]], step: int, targets: dict) -> list[tuple]:
    """Before Bullet's step: each free body that two or more cables moved in their plans of this step (``shares``
    {body: {cable: Share}}, those of world step count ``step``), or that one moved with the others' reactions of the
    step before, gets the velocity delta* of all of them together (``targets`` {body: delta*}, :func:`unsettled`:
    (M_b + sum load_mass) delta* = M_b U + dt M g + sum (impulse + load_mass vel), each cable's reaction linear about
    its own plan), and each cable hands it impulse - load_mass (delta* - vel): Bullet's update under their sum lands
    the body on delta* (module doc, "Bodies on several cables"). The Shares are updated to what was handed. Returns,
    per body, who books its energy:
    (contact set, slot, work [J]), the first of those cables by name with the work of all the reactions, (sum handed)
    . (U + delta*) / 2 (:func:`~bullet_dlo.bullet.body_energy.plan_shared`); the others do not book it (each would
    count the others' work as made)."""
    bookings = []
    for body, target in targets.items():
        parts = shares[body]
        total = np.zeros(6)
        for name, p in parts.items():
            if p.step != step:
                continue
            handed = p.impulse - p.load_mass @ (target - p.vel)
            p.cs.bodies.impulse[p.slot] = handed
            p.cs.energy_check.planned[p.slot] = False
            total += handed
            parts[name] = dataclasses.replace(p, impulse=handed, vel=target)
        booking = parts[min(name for name, p in parts.items() if p.step == step)]
        cs, o = booking.cs, booking.slot
        bookings.append((cs, o, 0.5 * float(total @ (cs.velocity_now[o] + target))))
    return bookings
