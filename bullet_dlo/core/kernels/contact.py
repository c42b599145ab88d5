"""Contact and Coulomb friction inside the implicit step (Numba): penalty normal force, anchored friction.

A contact k joins a point of the cable to a body surface for one step. The cable point is
p = w_a x_a + w_b x_b (a node: w_b = 0; a segment interior at parameter s: w_a = 1 - s, w_b = s,
b = a + 1), the surface a plane through the point c with unit normal n (both at the start of the
step, moved at the body's velocity u_b over it). With the cable radius r:

- gap g = n . (p - c) - r; normal force f_n = k_n max(0, -g) - c_n (n . (p' - u_b)) while g < 0;
- friction: an anchor a tied to a MATERIAL point of the cable (parameter s_a on the segment,
  ``anchor[k, 3]``) holds it with a tangential spring, u = P_t((1 - s_a) x_a + s_a x_b - a),
  P_t = I - n n^T; f_t = -k_t u while k_t |u| <= cap (stick), else -cap u/|u| (slide), with
  cap = mu_s f_n if the contact stuck last step, mu_d f_n if it slid. After a slide the anchor
  moves so that the spring carries exactly mu_d f_n (and s_a to the current closest point).

f_t is minus the gradient of a convex Huber potential (cap frozen), so a step with contacts keeps
an incremental potential (merit) and its Newton matrix stays symmetric and block-banded (a
segment contact couples a and a + 1). The caps follow the normal force as a fixed point after
each Newton solve. Contacts are evaluated at the END of the step (backward Euler contact) for
every implicit method; the implicit midpoint rule is unstable with stiff one-sided contact even
so, and takes implicit Euler steps while contacts are active (BDF2 too, on the step after an
impact, which its two-step history would turn into a bounce).

Grip with friction (:class:`Grip`, field ``grip`` of :class:`Contacts`): a gripper pinching an end
node with F_n per finger (two fingers). The end node is free (not held); it is tied to an anchor A
= c + xi d on the gripper's axis (c the grasp centre, d the cable's direction in the gripper,
both at the end of the step, xi the anchor's offset along the axis) by a stiff lateral spring
k (I - d d^T) (the fingers enclose the cable) and an axial friction spring with the Huber
potential above, capacity 2 mu_s F_n while stuck, 2 mu_d F_n while slipping. After a slipping
step xi moves so that the spring carries 2 mu_d F_n: the end slides along the gripper and
leaves it (the grip is lost) once |xi| exceeds the finger's reach.

Stiffness: k_n = alpha m_k / h^2 per contact, m_k the cable mass at the contact point (one
stiffness for all contacts would load the half-mass end nodes wrongly), alpha = 1e4 by default
(penetration about g h^2 / alpha at rest: microns at 60 Hz), raised by the detector to the row's last
load over LOAD_DEPTH of the radius under a free body (bullet.contact, ``_follow_loads``); k_t = k_n.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from bullet_dlo.core.kernels.banded import HALF
from bullet_dlo.core.kernels.gauss_legendre import gl_band_factor, gl_band_substitute
from bullet_dlo.core.kernels.forces import _angle_terms, _bend_hessian
from bullet_dlo.core.kernels.jit import njit
from bullet_dlo.core.kernels.twist import edge_frame, has_twist, set_clamp, twist_ready, twist_step
from bullet_dlo.core.kernels.steppers import (
    BDF2,
    IMPLICIT_EULER,
    IMPLICIT_MIDPOINT,
    _set_held,
    _start_implicit,
    newton,
)

STICK, SLIDE = 0, 1
# Contacts.lock during Newton (:func:`lock_rows`): the low two bits LOCK_STICK, LOCK_SLIDE or LOCK_FREE (the regime
# follows the slip, k_t |u| <= cap: the Huber potential), the rest the row's switches so far in the solve
LOCK_STICK, LOCK_SLIDE, LOCK_FREE = 1, 2, 3
LOCK_SWITCHES = 4  # a row switched this often in one solve follows its slip again
PENALTY, WRAP = 0, 1  # Contacts.kind: penalty contact, or a segment wrapped round a sharp edge
SIGMA_MIN = 0.01  # a wrap's material fraction either side of the edge, at least (sub-spring stiffness ks / sigma)
ARC_BLEND = 0.1  # [rad] a node between two wrapped paths loses its kink's bend as both arcs grow past this
DEFAULT_ALPHA = 1.0e4  # k_n h^2 / m: contact frequency times step, squared
MIN_CONTACT_ITER = 30  # Newton iterations allowed in contact at least (stick/slide kinks need more than 8)
WILD_RATIO = 10.0  # [-] a solve ending this far from convergence (stall_ratio) is wildly far (Bodies.felt_ratio)
BODY_TOL = 0.1  # [-] a free body's residual tolerance, as a share of the solve's: its velocity is off by at most that
# times tol g h (Bullet integrates the reaction impulse the rows carry, not the solved velocity): at tol 1e-3 and 60 Hz
# 1.6e-4 m/s, above a resting body's 1e-4; a 1 g box on the cable was kicked to 1.1-1.6e-4 m/s every 25 steps
RETRY_RATIO = 100.0  # [-] a cable-only solve ending this far is solved again from bounded_caps (steppers.newton)
SUPPORT_COLS = 26  # Contacts.support's columns
SUPPORT_ROUNDING = 1e-3  # [-] a flat section's support is rounded over a tilt of at least this (set_support)


class Grip(NamedTuple):
    """Friction grips of the two cable ends (index 0 first, 1 last), see the module docstring.

    active (2,) bool; k_ax, k_lat (2,) [N/m] axial friction spring and lateral spring; cap_s,
    cap_d (2,) [N] axial capacity stuck / slipping (derived force caps 2 mu F_n, from the grip's
    static_friction / dynamic_friction coefficients and its normal force); reach (2,) [m] how far the anchor
    may slide along the gripper before the end leaves it; offset (2,) [m] anchor offset xi along
    the axis; state (2,) int STICK / SLIDE; center (2, 3) [m], axis (2, 3) unit, vel (2, 3)
    [m/s]: the gripper at the end of the step; force (2, 3) [N]: the grip's force on the cable.
    """

    active: np.ndarray
    k_ax: np.ndarray
    k_lat: np.ndarray
    cap_s: np.ndarray
    cap_d: np.ndarray
    reach: np.ndarray
    offset: np.ndarray
    state: np.ndarray
    center: np.ndarray
    axis: np.ndarray
    vel: np.ndarray
    force: np.ndarray


def make_grip() -> Grip:
    """Two inactive grips."""
    f = np.zeros
    return Grip(active=np.zeros(2, np.bool_), k_ax=f(2), k_lat=f(2), cap_s=f(2), cap_d=f(2), reach=f(2),
                offset=f(2), state=np.zeros(2, np.int64), center=f((2, 3)), axis=f((2, 3)), vel=f((2, 3)),
                force=f((2, 3)))


class Bodies(NamedTuple):
    """Free rigid bodies (S slots) whose motion the contact step solves together with the cable's.

    A dynamic body that Bullet moves only under the cable's force would meet the stiff contact
    spring explicitly (k h^2 / M of hundreds): thrown off, or, softened, sinking g h^2 per step into
    the cable. So each free body (a single rigid link, no joints) in contact is a 6-DOF unknown of
    the cable's implicit step, delta = (U', Omega') its velocity at the end of the step: the
    contact's body point moves by h (U' + Omega' x arm), and the body obeys backward Euler,
    M (U' - U) = h (M g + F), I (Omega' - Omega) = h tau, with F, tau the contacts' reactions; Bullet's
    semi-implicit update under those reactions lands the body on the same velocity (when nothing else
    touches it). See docs/concepts/contact.md, "Bodies resting on the cable".

    active (S,) bool: touched by a row this step; mass (S,) [kg]; inertia (S, 3, 3) [kg m^2] world
    frame at the start of the step; gravity (3,) [m/s^2] of the bodies' world; vel (S, 6) [m/s, rad/s]
    at the start of the step; vel_new, vel_try (S, 6): Newton's iterate and the line search's trial;
    step (S, 6): Newton's direction; residual (S, 6) [N s, N m s] of the velocities the contact
    rows hold now (:func:`load_bodies`); coupling (3n, 6S), schur (6S, 6S), work (3n,): scratch of
    :func:`coupled_solve`. Per contact row (M rows, as :class:`Contacts`): slot (M,) int, the row's body slot
    (-1: a static body, a link of an articulated body, the cable itself or another cable: its surface moves at
    body_vel); arm (M, 3) [m]: the row's surface point from the body's centre of mass at the start of the step;
    point0, anchor0 (M, 3) [m]: the row's surface point and anchor at the start of the step. impulse (S, 6) [N s,
    N m s]: the rows' reactions on each body summed over the (sub-)steps of the planned Bullet step (torque about
    the centre of mass at the rows' arms): Bullet gets their mean, so that its update lands the body where the
    sub-steps took it (:func:`_add_reactions`). felt_ratio (1,) [-]: a solve that ends unconverged beyond this
    :func:`stall_ratio` hands the bodies the reaction the cable felt, not the rows' forces at its last iterate
    (:func:`felt_forces`; default :data:`WILD_RATIO`).

    What else holds a body (bullet/held_bodies.py): Bullet's contact points of the last step on slot s, the first
    hold_count[s] (S,) of HOLD_POINTS: hold_arm (S, H, 3) [m] the point from the centre of mass, hold_normal (S, H, 3)
    the unit normal from the holder into the body, hold_load (S, H) [N] the normal force Bullet found there,
    hold_vel (S, H) [m/s] the holder's own velocity there along the normal;
    hold_c (S,) [N s/m]: the rate at which a holder lets go. The step takes each holder's load as measured and lets
    it go by hold_c v_n while the body's point leaves the holder at v_n (relative to the holder's), down to nothing
    (:func:`_holder_change`): a body the step lifts off its holder loses that support in the same step, as in
    Bullet. Pressing into it adds nothing (the measured load and the apparent mass of bullet/held_bodies.py hold it).
    held_dv (S, 6) [m/s, rad/s]: the part of ``vel`` that the held load gives over the Bullet step
    (bullet/held_bodies.py folds it in, as one step's impulse): cable sub-steps and a retry's sub-steps
    (bullet/kernels.py, :func:`~bullet_dlo.bullet.kernels.spread_held`) give each of their steps its share.
    travel (S, 6) [m, rad]: the body's planned displacement over the Bullet step, h times its solved velocity summed over
    the (sub-)steps (its centre of mass, and a rotation vector): Bullet's update of the mean reaction lands the
    velocity of the last sub-step, not this place (bullet/cable.py, :meth:`BulletCable.land_free_bodies`).

    A body other cables touch too (bullet/held_bodies.py, "Bodies on several cables"): other_mass (S, 6, 6) [kg, kg m,
    kg m^2], the other cables' load_mass summed, is in the body's mass matrix, (M_b + other_mass) (delta - delta_0):
    their reactions, linear in the body's velocity, in this cable's step. load_mass (S, 6, 6), out: this cable's
    -d(reaction impulse)/d(delta) at the solve's last Newton matrix (its contact rows' J^T G J less C^T A^-1 C, the
    cable's nodes yielding), zero for a body not in the step.

    The Bodies are not a field of :class:`Contacts`: every compiled call that passes a NamedTuple takes and
    drops a reference to each of its arrays, and the contact kernels that run several times per Newton
    iteration need none of these (while they were a field, the detection of a cable on the ground, no body in
    the world, took 35 against 31 us a step at n = 20 and 120 against 106 us at n = 80; docs/concepts/contact.md).
    """

    active: np.ndarray
    mass: np.ndarray
    inertia: np.ndarray
    gravity: np.ndarray
    vel: np.ndarray
    vel_new: np.ndarray
    vel_try: np.ndarray
    step: np.ndarray
    residual: np.ndarray
    coupling: np.ndarray
    schur: np.ndarray
    work: np.ndarray
    slot: np.ndarray
    arm: np.ndarray
    point0: np.ndarray
    anchor0: np.ndarray
    impulse: np.ndarray
    felt_ratio: np.ndarray
    hold_count: np.ndarray
    hold_arm: np.ndarray
    hold_normal: np.ndarray
    hold_load: np.ndarray
    hold_vel: np.ndarray
    hold_c: np.ndarray
    other_mass: np.ndarray
    load_mass: np.ndarray
    held_dv: np.ndarray
    travel: np.ndarray


HOLD_POINTS = 8  # Bullet's contact points kept per held body (a manifold holds up to 4 per pair of links)


def make_bodies(n: int, capacity: int, slots: int) -> Bodies:
    """Room for ``slots`` free bodies touching an n-node cable (none active), for a contact set of ``capacity``
    rows (as :func:`make_contacts`)."""
    s = int(slots)
    m = max(1, int(capacity))
    f = np.zeros
    return Bodies(active=np.zeros(s, np.bool_), mass=f(s), inertia=f((s, 3, 3)), gravity=f(3), vel=f((s, 6)),
                  vel_new=f((s, 6)), vel_try=f((s, 6)), step=f((s, 6)), residual=f((s, 6)),
                  coupling=f((3 * n, 6 * s)), schur=f((6 * s, 6 * s)), work=f(3 * n), slot=np.full(m, -1, np.int64),
                  arm=f((m, 3)), point0=f((m, 3)), anchor0=f((m, 3)), impulse=f((s, 6)),
                  felt_ratio=np.full(1, WILD_RATIO), hold_count=np.zeros(s, np.int64),
                  hold_arm=f((s, HOLD_POINTS, 3)), hold_normal=f((s, HOLD_POINTS, 3)), hold_load=f((s, HOLD_POINTS)),
                  hold_vel=f((s, HOLD_POINTS)), hold_c=f(s), other_mass=f((s, 6, 6)), load_mass=f((s, 6, 6)),
                  held_dv=f((s, 6)), travel=f((s, 6)))


class Contacts(NamedTuple):
    """The contacts of one cable for the coming step (capacity M rows; the first ``count[0]`` used).

    Geometry (filled by the detector): node (M, 2) int, weight (M, 2): the contact point
    p = w0 x[node0] + w1 x[node1]; normal (M, 3) unit, from the body to the cable; point (M, 3)
    [m]: surface point at the start of the step; body_vel (M, 3) [m/s]: the body's velocity at it.
    Parameters: k_n, k_t [N/m], c_n [N s/m], static_friction, dynamic_friction [-] (the friction
    coefficients mu_s, mu_d), each (M,).
    Friction state (persisted by the detector between steps): anchor (M, 4): anchor position
    [m] and material parameter s_a on the segment; state (M,) int: STICK or SLIDE.
    Results of the step: f_n (M,) [N] normal force (>= 0), f_t (M, 3) [N] friction force, both on
    the cable; cap (M,) [N] friction limit used. Scalars (1,): count, radius [m] (cable radius),
    body_work (2,) [J]: [0] work the touched bodies did on the cable so far, plus [1] the penalty energy that a
    body Bullet moved further into the cable than the step planned left in this step's rows (not counted as
    energy: see ``bullet.contact.detect``); impact (1 when a contact took
    load at an approach speed above g h: the next BDF2 step restarts with implicit Euler).
    internal (M,) bool: the "body" is another part of the same cable (self-contact: its work is not
    external). node_force (n, 3) [N]: scratch for the contact forces on the nodes. grip: the
    friction grips of the ends (:class:`Grip`), evaluated with the contacts.
    Edge wraps (docs/concepts/contact.md, "Edges"): kind (M,) int, PENALTY or WRAP; for a WRAP row
    (segment node[k] across a sharp edge of a static body) point (M, 3) [m] is a point of the edge
    line, axis (M, 3) its unit direction, side (M, 3) the unit bisector of the edge's outward normal
    cone (the side the cable wraps round), seg (M, 6) the segment's stretch stiffness [N/m], rest
    length [m], the bending constants [N m/rad^2] at its two nodes, the edge's radius [m] (0 for a box's
    sharp edge, the collision margin of a convex hull's edge; the axis wraps at the cable radius plus it) and
    1.0 when the segment before has a WRAP row round the same edge (:func:`mark_wrap_neighbours`; that row
    then bends the shared node while both paths wrap), else 0.0, anchor[k, 3] the material fraction sigma of the segment on node[k, 0]'s side of the
    edge (the friction anchor); normal, f_n: the direction and size of the edge's push on the cable
    (results), cap [N]: the capstan's friction limit.
    Free bodies solved with the cable: a :class:`Bodies` beside the Contacts (its rows' body slots and arms).
    lock (M,) int: a penalty row's friction regime as Newton's active set holds it (0 outside Newton; see
    :func:`lock_rows`).
    A flat section (docs/concepts/contact.md, "Flat sections"): section (3,) the rectangle's half width along d1
    and half thickness along d2 [m] and the rounding of its support function [-] (all 0 for a round section);
    reach (1,) [m] how far from the centre line the section reaches (the detector's envelope: the radius, or the
    rectangle's half diagonal); support (M, SUPPORT_COLS) per penalty row (:func:`set_support`): [0] the section's
    support distance s along -normal [m] (0: the row takes the radius), [1] its rate ds/dt [m/s] from the twist
    rates, [2:4] ds/dtheta [m/rad] and [4:6] d2s/dtheta^2 [m/rad^2] on the row's two edges (:func:`row_edges`; 0 on
    an edge it does not have), [6:9] the tangential move [m] of the section's touching point since the step's start
    from the section's turn about its axis (the friction's slip counts it: :func:`set_support`), [9:11] the two
    edges' twist angles at the step's start [rad] (:func:`start_support`), [12:15], [15:18] the move's derivative
    in the two edges' twist angles [m/rad], [18:21], [21:24] the support distance's gradient [-] in the far node
    of each of the two edges (e + 1; minus it in node e): the material frame turns with the edge's tangent,
    [24:26] each edge's part of the support distance [m] (with its weight in the row).
    """

    count: np.ndarray
    radius: np.ndarray
    node: np.ndarray
    weight: np.ndarray
    normal: np.ndarray
    point: np.ndarray
    body_vel: np.ndarray
    k_n: np.ndarray
    k_t: np.ndarray
    c_n: np.ndarray
    static_friction: np.ndarray
    dynamic_friction: np.ndarray
    anchor: np.ndarray
    state: np.ndarray
    f_n: np.ndarray
    f_t: np.ndarray
    cap: np.ndarray
    body_work: np.ndarray
    impact: np.ndarray
    internal: np.ndarray
    node_force: np.ndarray
    grip: Grip
    kind: np.ndarray
    axis: np.ndarray
    side: np.ndarray
    seg: np.ndarray
    lock: np.ndarray
    section: np.ndarray
    reach: np.ndarray
    support: np.ndarray


def make_contacts(n: int, capacity: int, radius: float, grip: Grip | None = None,
                  section: tuple[float, float] = (0.0, 0.0)) -> Contacts:
    """Empty contact arrays for an n-node cable of radius [m], room for ``capacity`` contacts
    (``grip``: the cable's grips, shared between successive contact sets; None: inactive ones). ``section``: a
    rectangle's (width, thickness) [m], whose support distance the penalty rows of a cable with a material frame
    take instead of the radius; (0, 0): round. The free bodies solved with the cable come beside it
    (:func:`make_bodies`)."""
    m = max(1, int(capacity))
    f = np.zeros
    width, thickness = float(section[0]), float(section[1])
    flat = np.zeros(3)
    if width > 0.0 and thickness > 0.0:
        # the corners rounded over a tilt of a quarter of h/b (a sharper kink costs Newton iterations on the ground)
        flat[:] = 0.5 * width, 0.5 * thickness, min(1.0, max(SUPPORT_ROUNDING, 0.25 * thickness / width))
    reach = max(float(radius), math.hypot(flat[0], flat[1]))
    return Contacts(count=np.zeros(1, np.int64), radius=np.full(1, float(radius)), node=np.zeros((m, 2), np.int64),
                    weight=f((m, 2)), normal=f((m, 3)), point=f((m, 3)), body_vel=f((m, 3)), k_n=f(m), k_t=f(m),
                    c_n=f(m), static_friction=f(m), dynamic_friction=f(m), anchor=f((m, 4)), state=np.zeros(m, np.int64), f_n=f(m),
                    f_t=f((m, 3)), cap=f(m), body_work=f(2), impact=np.zeros(1, np.int64),
                    internal=np.zeros(m, np.bool_), node_force=f((n, 3)),
                    grip=grip if grip is not None else make_grip(), kind=np.zeros(m, np.int64),
                    axis=f((m, 3)), side=f((m, 3)), seg=f((m, 6)), lock=np.zeros(m, np.int64), section=flat,
                    reach=np.full(1, reach), support=f((m, SUPPORT_COLS)))


# ----- the grips -----------------------------------------------------------------------------
@njit(cache=True, error_model="numpy", inline="always")
def _grip_offset(g, e, x, w):
    """w <- lateral offset [m] (3,) of end e's node from the gripper axis; returns the axial offset
    u [m] of the node from the anchor."""
    i = 0 if e == 0 else x.shape[0] - 1
    ua = 0.0
    for j in range(3):
        w[j] = x[i, j] - g.center[e, j] - g.offset[e] * g.axis[e, j]
        ua += w[j] * g.axis[e, j]
    for j in range(3):
        w[j] -= ua * g.axis[e, j]
    return ua


@njit(cache=True, error_model="numpy", inline="always")
def _grip_cap(g, e):
    return g.cap_s[e] if g.state[e] == STICK else g.cap_d[e]


@njit(cache=True, error_model="numpy")
def grip_forces(g, x, f):
    """f += the grips' forces on the end nodes [N] at x (caps frozen); also fills g.force."""
    w = np.empty(3)
    n = x.shape[0]
    for e in range(2):
        if not g.active[e]:
            continue
        ua = _grip_offset(g, e, x, w)
        cap, k = _grip_cap(g, e), g.k_ax[e]
        fa = -k * ua if k * abs(ua) <= cap else -cap * math.copysign(1.0, ua)
        i = 0 if e == 0 else n - 1
        for j in range(3):
            fj = -g.k_lat[e] * w[j] + fa * g.axis[e, j]
            g.force[e, j] = fj
            f[i, j] += fj


@njit(cache=True, error_model="numpy")
def grip_potential(g, x):
    """Potential [J] of the grips' forces at x (caps frozen): lateral spring plus axial Huber term."""
    w = np.empty(3)
    phi = 0.0
    for e in range(2):
        if not g.active[e]:
            continue
        ua = _grip_offset(g, e, x, w)
        cap, k = _grip_cap(g, e), g.k_ax[e]
        phi += 0.5 * g.k_lat[e] * (w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
        if k * abs(ua) <= cap:
            phi += 0.5 * k * ua * ua
        else:
            phi += cap * abs(ua) - 0.5 * cap * cap / k
    return phi


@njit(cache=True, error_model="numpy")
def grip_energy(g, x):
    """Energy [J] stored in the grips' springs at x."""
    w = np.empty(3)
    e_sum = 0.0
    for e in range(2):
        if not g.active[e]:
            continue
        ua = _grip_offset(g, e, x, w)
        fa = min(g.k_ax[e] * abs(ua), _grip_cap(g, e))
        e_sum += 0.5 * g.k_lat[e] * (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) + 0.5 * fa * fa / g.k_ax[e]
    return e_sum


@njit(cache=True, error_model="numpy")
def add_grip_jacobian(g, x, kx, band):
    """band += kx (-dF/dx) of the grips: k_lat (I - d d^T), plus k_ax d d^T while within the cap."""
    w = np.empty(3)
    n = x.shape[0]
    for e in range(2):
        if not g.active[e]:
            continue
        ua = _grip_offset(g, e, x, w)
        k_axial = g.k_ax[e] if g.k_ax[e] * abs(ua) <= _grip_cap(g, e) else 0.0
        i = 0 if e == 0 else n - 1
        for r in range(3):
            for q in range(3):
                dd = g.axis[e, r] * g.axis[e, q]
                val = g.k_lat[e] * ((1.0 if r == q else 0.0) - dd) + k_axial * dd
                row = 3 * i + r
                band[row, 3 * i + q - row + HALF] += kx * val


@njit(cache=True, error_model="numpy")
def grip_active(g):
    return g.active[0] or g.active[1]


@njit(cache=True, error_model="numpy")
def _update_grips(g, x_end):
    """After the step: stick or slip; a slipping grip's anchor follows (the spring carries cap_d);
    a grip whose anchor slid past its reach has let the end go (active False)."""
    w = np.empty(3)
    for e in range(2):
        if not g.active[e]:
            continue
        ua = _grip_offset(g, e, x_end, w)
        k = g.k_ax[e]
        if k * abs(ua) <= _grip_cap(g, e) * (1.0 + 1e-6):
            g.state[e] = STICK
        else:
            g.state[e] = SLIDE
            g.offset[e] += ua - math.copysign(g.cap_d[e] / k, ua)
            if abs(g.offset[e]) > g.reach[e]:
                g.active[e] = False


# ----- one contact ---------------------------------------------------------------------------
@njit(cache=True, error_model="numpy", inline="always")
def _gap(c, k, x):
    """Gap g [m] of contact k at positions x (negative: penetration)."""
    a, b = c.node[k, 0], c.node[k, 1]
    wa, wb = c.weight[k, 0], c.weight[k, 1]
    g = 0.0
    for j in range(3):
        g += c.normal[k, j] * (wa * x[a, j] + wb * x[b, j] - c.point[k, j])
    # both read before the choice: an array read inside a branch costs Numba a reference count per call (10x here)
    s, r = c.support[k, 0], c.radius[0]  # a flat section's support distance (else 0), the radius
    return g - (s if s > 0.0 else r)


@njit(cache=True, error_model="numpy", inline="always")
def _slip(c, k, x, u):
    """Tangential offset u [m] (3,) of the anchored material point from the anchor; returns |u|."""
    a, b = c.node[k, 0], c.node[k, 1]
    sa = c.anchor[k, 3]
    dn = 0.0
    for j in range(3):  # (a flat section: plus its touching point's move with the section's turn; else 0)
        u[j] = (1.0 - sa) * x[a, j] + sa * x[b, j] + c.support[k, 6 + j] - c.anchor[k, j]
        dn += u[j] * c.normal[k, j]
    ul = 0.0
    for j in range(3):
        u[j] -= dn * c.normal[k, j]
        ul += u[j] * u[j]
    return math.sqrt(ul)


@njit(cache=True, error_model="numpy", inline="always")
def _approach(c, k, v):
    """Normal velocity [m/s] of the cable point relative to the body (negative: approaching)."""
    a, b = c.node[k, 0], c.node[k, 1]
    wa, wb = c.weight[k, 0], c.weight[k, 1]
    q = 0.0
    for j in range(3):
        q += c.normal[k, j] * (wa * v[a, j] + wb * v[b, j] - c.body_vel[k, j])
    if c.support[k, 0] > 0.0:  # a flat section turning towards the body reaches for it (twist and tangent)
        e0, e1 = row_edges(a, b, v.shape[0] - 1)
        for slot in range(2):
            e = e0 if slot == 0 else e1
            if e >= 0:
                for j in range(3):
                    q -= c.support[k, 18 + 3 * slot + j] * (v[e + 1, j] - v[e, j])
    return q - c.support[k, 1]


# ----- a flat section's support (docs/concepts/contact.md, "Flat sections") -----------------------------------
@njit(cache=True, error_model="numpy", inline="always")
def row_edges(a, b, ns):
    """The edges whose section a penalty row on nodes (a, b) touches with: a node row (a == b) the two edges at
    node a (a - 1, a; the mean of their sections), a segment row (b = a + 1) edge a alone (-1, a); -1 for an edge
    the cable has not (ns edges)."""
    e0 = a - 1 if a == b and a >= 1 else -1
    e1 = a if a < ns else -1
    return e0, e1


@njit(cache=True, error_model="numpy", inline="always")
def _rounded(a, eps):
    """A rounded |a| (0 at 0, 1 at +-1; rounded over |a| ~ eps) and its first and second derivatives."""
    q = math.sqrt(a * a + eps * eps)
    scale = 1.0 / (math.sqrt(1.0 + eps * eps) - eps)
    return (q - eps) * scale, a / q * scale, eps * eps / (q * q * q) * scale


@njit(cache=True, error_model="numpy")
def set_support(c, E, W, ref, tan):
    """c.support <- each penalty row's support distance and its derivatives (see :class:`Contacts`) for a flat
    section (c.section[0] > 0; else nothing), from the edges' frames ``E`` (the coupled step's
    :class:`~bullet_dlo.core.kernels.twist_coupled.Scratch` edges: column k + 1 edge k, rows 0 its length, 1-3
    its unit tangent t, 4-6 its reference director r, 7 its twist angle theta), twist rates ``W`` [rad/s] (n -
    1,) and the step's reference frames (``ref``, ``tan``: the directors r was transported from and their
    tangents, (n - 1, 3); :func:`~bullet_dlo.core.kernels.twist.edge_frame`).

    The material axes d1 = cos(theta) r + sin(theta) t x r (the width's), d2 = t x d1 (the thickness'); a rectangle
    of half width b, half thickness h reaches s = b |d1 . n| + h |d2 . n| from its centre line towards a body of
    normal n, with |.| rounded over eps = c.section[2] (|a| -> sqrt(a^2 + eps^2) - eps, scaled to 1 at |a| = 1).
    With dd1/dtheta = d2, dd2/dtheta = -d1, s turns with theta: the penalty's potential 1/2 k_n (n . p - n . c - s)^2
    then has the moment that lays a tilted strip flat. The friction holds the section's touching point, a depth s
    below the centre line: turned by dtheta about its axis t, the section moves it tangentially by s dtheta (n x t)
    (its offset across the section only moves it along n), so the slip counts s (theta - theta0) (n x t) over the
    step (theta0: the step's start, kept in the row) and the friction's moment about the axis is f_t . s (n x t): a
    strip rolling on its edge does not slip there, one lying flat rolls at its half thickness.

    The section also turns with its edge's tangent (r is the reference director transported onto it): s depends on
    the edge's nodes, and the normal force, acting at the touching point off the centre line, has a bending moment
    as well as the twisting one: -f_n ds/dx on the nodes (:func:`_support_gradient`)."""
    hw, ht, eps = c.section[0], c.section[1], c.section[2]
    if hw <= 0.0:
        return
    ns = W.shape[0]
    for k in range(c.count[0]):
        for q in range(SUPPORT_COLS):
            if q < 9 or q >= 11:
                c.support[k, q] = 0.0
        if c.kind[k] == WRAP or c.internal[k]:  # (the other part of the same cable keeps the round envelope)
            continue
        e0, e1 = row_edges(c.node[k, 0], c.node[k, 1], ns)
        beta = 0.5 if e0 >= 0 and e1 >= 0 else 1.0
        n0, n1, n2 = c.normal[k, 0], c.normal[k, 1], c.normal[k, 2]
        for slot in range(2):
            e = e0 if slot == 0 else e1
            if e < 0:
                continue
            col = e + 1
            t0, t1, t2, r0, r1, r2, th = E[1, col], E[2, col], E[3, col], E[4, col], E[5, col], E[6, col], E[7, col]
            b0, b1, b2 = t1 * r2 - t2 * r1, t2 * r0 - t0 * r2, t0 * r1 - t1 * r0
            ct, st = math.cos(th), math.sin(th)
            u0, u1, u2 = ct * r0 + st * b0, ct * r1 + st * b1, ct * r2 + st * b2  # d1
            w0, w1, w2 = ct * b0 - st * r0, ct * b1 - st * r1, ct * b2 - st * r2  # d2 = t x d1
            a1 = u0 * n0 + u1 * n1 + u2 * n2
            a2 = w0 * n0 + w1 * n1 + w2 * n2
            f1, g1, h1 = _rounded(a1, eps)
            f2, g2, h2 = _rounded(a2, eps)
            ds = hw * g1 * a2 - ht * g2 * a1
            dds = hw * (h1 * a2 * a2 - g1 * a1) + ht * (h2 * a1 * a1 - g2 * a2)
            se = hw * f1 + ht * f2
            c.support[k, 0] += beta * se
            c.support[k, 1] += beta * ds * W[e]
            c.support[k, 2 + slot] = beta * ds
            c.support[k, 4 + slot] = beta * dds
            c.support[k, 24 + slot] = beta * se
            turn = th - c.support[k, 9 + slot]  # since the step's start
            x0, x1, x2 = n1 * t2 - n2 * t1, n2 * t0 - n0 * t2, n0 * t1 - n1 * t0  # n x t
            c.support[k, 6] += beta * se * turn * x0
            c.support[k, 7] += beta * se * turn * x1
            c.support[k, 8] += beta * se * turn * x2
            lever = beta * (se + turn * ds)
            c.support[k, 12 + 3 * slot] = lever * x0
            c.support[k, 13 + 3 * slot] = lever * x1
            c.support[k, 14 + 3 * slot] = lever * x2
            _support_gradient(c, k, 18 + 3 * slot, beta, E, col, ref[e], tan[e], hw * g1, ht * g2)


@njit(cache=True, error_model="numpy", inline="always")
def _support_gradient(c, k, col0, beta, E, col, u, a, w1, w2):
    """c.support[k, col0:col0 + 3] <- beta times the gradient of s_e = b rho(d1 . n) + h rho(d2 . n) [-] in the
    far node of edge e (E's column ``col``; minus it in the near one), with w1 = b rho'(d1 . n), w2 = h rho'(d2 .
    n): d1, d2 turn with the tangent t through the transport of the reference director u from tangent a, r = u -
    (u . t)(a + t)/(1 + a . t), whose derivative A has A^T q = -u q.(a + t)/(1 + c) - (u . t) q/(1 + c) + (u . t)
    (a + t) . q a/(1 + c)^2, c = a . t; d(d1 . n)/dt = cos(theta) P1 + sin(theta) P2, d(d2 . n)/dt = cos(theta) P2 -
    sin(theta) P1 with P1 = A^T n, P2 = A^T (n x t) + r x n; dt/dx = (I - t t^T)/length."""
    length, t0, t1, t2 = E[0, col], E[1, col], E[2, col], E[3, col]
    r0, r1, r2, th = E[4, col], E[5, col], E[6, col], E[7, col]
    n0, n1, n2 = c.normal[k, 0], c.normal[k, 1], c.normal[k, 2]
    cc = a[0] * t0 + a[1] * t1 + a[2] * t2
    for j in range(3):
        c.support[k, col0 + j] = 0.0
    if not 1.0 + cc > 1e-12:  # (a reversed edge: the transport is not defined; no gradient)
        return
    ut = u[0] * t0 + u[1] * t1 + u[2] * t2
    s0, s1, s2 = a[0] + t0, a[1] + t1, a[2] + t2  # a + t
    q0, q1, q2 = n1 * t2 - n2 * t1, n2 * t0 - n0 * t2, n0 * t1 - n1 * t0  # n x t
    inv = 1.0 / (1.0 + cc)
    sn = (s0 * n0 + s1 * n1 + s2 * n2) * inv
    sq = (s0 * q0 + s1 * q1 + s2 * q2) * inv
    ct, st = math.cos(th), math.sin(th)
    g = np.empty(3)
    for j in range(3):
        nj = n0 if j == 0 else (n1 if j == 1 else n2)
        qj = q0 if j == 0 else (q1 if j == 1 else q2)
        p1 = -u[j] * sn - ut * nj * inv + ut * sn * inv * a[j]
        rn = (r1 * n2 - r2 * n1) if j == 0 else ((r2 * n0 - r0 * n2) if j == 1 else (r0 * n1 - r1 * n0))  # r x n
        p2 = -u[j] * sq - ut * qj * inv + ut * sq * inv * a[j] + rn
        g[j] = w1 * (ct * p1 + st * p2) + w2 * (ct * p2 - st * p1)
    gt = g[0] * t0 + g[1] * t1 + g[2] * t2
    c.support[k, col0] = beta * (g[0] - gt * t0) / length
    c.support[k, col0 + 1] = beta * (g[1] - gt * t1) / length
    c.support[k, col0 + 2] = beta * (g[2] - gt * t2) / length


@njit(cache=True, error_model="numpy")
def start_support(c, m, x, dirs):
    """The rows' twist angles at the step's start (``m``'s twist state) and :func:`set_support` from its material
    frame at positions x [m] (the coupled solve turns it with the twist; a solve that does not take the twist, the
    staggered step with a free body, holds it)."""
    if c.section[0] <= 0.0:
        return
    n = x.shape[0]
    E = np.zeros((8, n + 1))
    for k in range(n - 1):
        fr = edge_frame(x, dirs, m.tw_theta, m.tw_ref, m.tw_tan, m.tw_clamp, k)
        for q in range(8):
            E[q, k + 1] = fr[q]
    for k in range(c.count[0]):
        e0, e1 = row_edges(c.node[k, 0], c.node[k, 1], n - 1)
        c.support[k, 9] = m.tw_theta[e0] if e0 >= 0 else 0.0
        c.support[k, 10] = m.tw_theta[e1] if e1 >= 0 else 0.0
    set_support(c, E, m.tw_omega, m.tw_ref, m.tw_tan)
    c.support[:c.count[0], 18:24] = 0.0  # (s held at the step's start: no gradient in the positions)


@njit(cache=True, error_model="numpy", inline="always")
def _sticks(c, k, ul):
    """Whether penalty row k's friction is its anchor spring (stick) at the slip |u| = ul: the regime Newton locked
    it in (``c.lock``), else the Huber potential's region, k_t |u| <= cap; no cap, no friction (slide at cap 0)."""
    cap = c.cap[k]
    if cap <= 0.0:
        return False
    lk = c.lock[k] & 3
    if lk == LOCK_STICK:
        return True
    if lk == LOCK_SLIDE:
        return False
    return c.k_t[k] * ul <= cap


@njit(cache=True, error_model="numpy")
def lock_rows(c, x):
    """Newton's active set for the friction of the penalty rows (docs/concepts/contact.md, "Friction in Newton"):
    a row not yet locked is locked to stick (every row first holds by its anchor spring: the elastic predictor); a
    row locked to slide whose slip is now inside the stick region (k_t |u| < cap) goes to stick, since there the
    slide potential cap |u| has its cone tip (u = 0) which Newton cannot approach. Returns how many rows' forces at x
    changed."""
    u = np.empty(3)
    changed = 0
    for k in range(c.count[0]):
        if c.kind[k] == WRAP or c.cap[k] <= 0.0:
            continue
        lk = c.lock[k] & 3
        if lk == LOCK_FREE:
            continue
        ul = _slip(c, k, x, u)
        inside = c.k_t[k] * ul <= c.cap[k]
        if c.lock[k] == 0:
            c.lock[k] = LOCK_STICK
            changed += 0 if inside else 1
        elif lk == LOCK_SLIDE and inside:
            changed += 1
            _switch(c, k, LOCK_STICK)
    return changed


@njit(cache=True, error_model="numpy", inline="always")
def _switch(c, k, regime):
    """Lock row k to ``regime``, counting the switch; after LOCK_SWITCHES its regime follows its slip."""
    n = (c.lock[k] >> 2) + 1
    c.lock[k] = (LOCK_FREE if n >= LOCK_SWITCHES else regime) + 4 * n


@njit(cache=True, error_model="numpy")
def unlock_inconsistent(c, x):
    """At a converged solve with locked rows: a row locked to stick whose spring exceeds its cap (k_t |u| > cap
    (1 + 1e-9)) goes to slide, one locked to slide whose slip lies inside the stick region goes to stick. Returns how
    many switched (0: every locked row is where Coulomb's law puts it at x, the locked forces are the Huber
    potential's, and the solve is the unlocked one's)."""
    u = np.empty(3)
    changed = 0
    for k in range(c.count[0]):
        lk = c.lock[k] & 3
        if lk == 0 or lk == LOCK_FREE or c.kind[k] == WRAP:
            continue
        f = c.k_t[k] * _slip(c, k, x, u)
        if lk == LOCK_STICK and f > c.cap[k] * (1.0 + 1e-9):
            _switch(c, k, LOCK_SLIDE)
            changed += 1
        elif lk == LOCK_SLIDE and f < c.cap[k]:
            _switch(c, k, LOCK_STICK)
            changed += 1
    return changed


# ----- a segment wrapped round a sharp edge (docs/concepts/contact.md, "Edges") -------------------
@njit(cache=True, error_model="numpy")
def _bend_term(p, q, k, sign, gp, gq, hb):
    """sign * 1/2 k theta(p, q)^2 (theta the angle between vectors p and q): returns it [J]; gp, gq (3,) <- its
    gradients; hb (6, 6) <- its Hessian in (p, q) (the core's bending Hessian, times sign)."""
    theta, s_, c_, la, lb, ux, uy, uz, wx, wy, wz, ratio, _ = _angle_terms(p[0], p[1], p[2], q[0], q[1], q[2])
    ga = -sign * k * ratio / la
    gb = -sign * k * ratio / lb
    gp[0], gp[1], gp[2] = ga * (wx - c_ * ux), ga * (wy - c_ * uy), ga * (wz - c_ * uz)
    gq[0], gq[1], gq[2] = gb * (ux - c_ * wx), gb * (uy - c_ * wy), gb * (uz - c_ * wz)
    g = np.empty(12)
    _bend_hessian(p[0], p[1], p[2], q[0], q[1], q[2], k, g, hb)
    if sign < 0.0:
        for i in range(6):
            for j in range(6):
                hb[i, j] = -hb[i, j]
    return sign * 0.5 * k * theta * theta


@njit(cache=True, error_model="numpy")
def _add_bend(p, q, k, sign, Jp, Jq, grad, hess, want_hess):
    """Add sign * 1/2 k theta(p, q)^2 with dp/dX = Jp, dq/dX = Jq (3, 12) to grad (12,), hess (12, 12) (the
    Hessian through the first derivatives of p, q only); returns the term [J]."""
    gp = np.empty(3)
    gq = np.empty(3)
    hb = np.empty((6, 6))
    e = _bend_term(p, q, k, sign, gp, gq, hb)
    for i in range(12):
        acc = 0.0
        for j in range(3):
            acc += Jp[j, i] * gp[j] + Jq[j, i] * gq[j]
        grad[i] += acc
    if want_hess:
        J = np.empty((6, 12))
        J[0:3] = Jp
        J[3:6] = Jq
        JH = np.zeros((12, 6))
        for i in range(12):
            for a in range(6):
                if J[a, i] == 0.0:
                    continue
                for b in range(6):
                    JH[i, b] += J[a, i] * hb[a, b]
        for i in range(12):
            for j in range(12):
                acc = 0.0
                for b in range(6):
                    acc += JH[i, b] * J[b, j]
                hess[i, j] += acc
    return e


@njit(cache=True, error_model="numpy")
def _path_terms(E, A, B, r, xa, xb, want_h, geo, ev, gP, gZ, gL, HP, HL):
    """The path of the axis from xa to xb round the edge line (point E, direction A, wrapping on the side B)
    as in :func:`_wrap_eval`, with its parts. geo (10,) <- (alpha [rad], P [m] the path across the edge, L
    [m] unrolled, d_a, d_b [m] the nodes' distances from the edge, t_a, t_b [m] the tangents, the sign of
    phi_a - phi_b, the angles [rad] from B of the tangent points on a's and on b's side); ev (4, 3) <- the unit
    directions e_a, e_b from the edge to the nodes and their turns pe_a, pe_b in the plane across it; gP, gZ, gL
    (6,) <- dP, d(z_b - z_a), dL over (xa, xb); with want_h HP (6, 6) <- d2P (per node, zero across) and HL (6, 6) <-
    d2L (exact). Returns alpha (<= 0: not wrapped, only d_a, d_b, t_a, t_b and the tangent points' angles set; 0 also
    when a node lies on the edge line)."""
    Q = np.empty(3)
    Q[0] = A[1] * B[2] - A[2] * B[1]
    Q[1] = A[2] * B[0] - A[0] * B[2]
    Q[2] = A[0] * B[1] - A[1] * B[0]
    pa = qa = za = pb = qb = zb = 0.0
    for j in range(3):
        wa, wb = xa[j] - E[j], xb[j] - E[j]
        pa += wa * B[j]
        qa += wa * Q[j]
        za += wa * A[j]
        pb += wb * B[j]
        qb += wb * Q[j]
        zb += wb * A[j]
    da = math.sqrt(pa * pa + qa * qa)
    db = math.sqrt(pb * pb + qb * qb)
    geo[3], geo[4] = da, db
    if da == 0.0 or db == 0.0:
        return 0.0
    phia = math.atan2(qa, pa)
    phib = math.atan2(qb, pb)
    sg = 1.0 if phia >= phib else -1.0
    ta = math.sqrt(max(da * da - r * r, 0.0))
    tb = math.sqrt(max(db * db - r * r, 0.0))
    beta_a, beta_b = math.acos(min(r / da, 1.0)), math.acos(min(r / db, 1.0))
    alpha = abs(phia - phib) - beta_a - beta_b
    geo[5], geo[6], geo[8], geo[9] = ta, tb, phia - sg * beta_a, phib + sg * beta_b
    if alpha <= 0.0:
        return alpha
    P = ta + tb + r * alpha
    dz = zb - za
    L = math.sqrt(P * P + dz * dz)
    geo[0], geo[1], geo[2], geo[5], geo[6], geo[7] = alpha, P, L, ta, tb, sg
    for j in range(3):
        ev[0, j] = (pa * B[j] + qa * Q[j]) / da
        ev[1, j] = (pb * B[j] + qb * Q[j]) / db
        ev[2, j] = (-qa * B[j] + pa * Q[j]) / da
        ev[3, j] = (-qb * B[j] + pb * Q[j]) / db
    for j in range(3):
        gP[j] = (ta / da) * ev[0, j] + (r * sg / da) * ev[2, j]
        gP[3 + j] = (tb / db) * ev[1, j] - (r * sg / db) * ev[3, j]
        gZ[j] = -A[j]
        gZ[3 + j] = A[j]
        gL[j] = (P * gP[j] + dz * gZ[j]) / L
        gL[3 + j] = (P * gP[3 + j] + dz * gZ[3 + j]) / L
    if want_h:
        HP[:, :] = 0.0
        for side in range(2):
            d, t, sgn = (da, ta, sg) if side == 0 else (db, tb, -sg)
            o = 3 * side
            for i in range(3):
                for j in range(3):
                    e_i, e_j, pe_i, pe_j = ev[side, i], ev[side, j], ev[2 + side, i], ev[2 + side, j]
                    if d > r:  # (1/t) n n^T, n normal to the tangent in the plane
                        ni = (r * e_i - sgn * t * pe_i) / d
                        nj = (r * e_j - sgn * t * pe_j) / d
                        HP[o + i, o + j] = ni * nj / max(t, 1e-6 * r)
                    else:  # on the arc: r sgn phi
                        HP[o + i, o + j] = -(r * sgn / (d * d)) * (pe_i * e_j + e_i * pe_j)
        for i in range(6):
            for j in range(6):
                HL[i, j] = (gP[i] * gP[j] + P * HP[i, j] + gZ[i] * gZ[j] - gL[i] * gL[j]) / L
    return alpha


@njit(cache=True, error_model="numpy", inline="always")
def _arc_gradient(geo, ev, r, out):
    """out (6,) <- d alpha / d(xa, xb) [1/m] of the path :func:`_path_terms` left in geo, ev (wrapped): alpha = sg
    (phi_a - phi_b) - beta_a - beta_b, d phi = pe / d, d beta = r / (d t) e (0 on the cylinder, d <= r)."""
    sg, da, db, ta, tb = geo[7], geo[3], geo[4], geo[5], geo[6]
    ka = r / (da * ta) if da > r and ta > 0.0 else 0.0
    kb = r / (db * tb) if db > r and tb > 0.0 else 0.0
    for j in range(3):
        out[j] = sg * ev[2, j] / da - ka * ev[0, j]
        out[3 + j] = -sg * ev[3, j] / db - kb * ev[1, j]


@njit(cache=True, error_model="numpy", inline="always")
def _blend(alpha):
    """The smoothstep of alpha / ARC_BLEND [-] (0 at alpha = 0, 1 from ARC_BLEND on, C1) and its derivative [1/rad]."""
    u = min(max(alpha / ARC_BLEND, 0.0), 1.0)
    return u * u * (3.0 - 2.0 * u), 6.0 * u * (1.0 - u) / ARC_BLEND


@njit(cache=True, error_model="numpy")
def _path(E, A, B, r, xa, xb, gL, HL):
    """The path of the axis from xa to xb round the edge line (point E, direction A, wrapping on the side B)
    as in :func:`_wrap_eval`: returns its arc alpha [rad] (<= 0: not wrapped, gL and HL untouched); gL (6,)
    <- dL/d(xa, xb), HL (6, 6) <- d2L/d(xa, xb)^2 (exact)."""
    geo = np.empty(10)
    ev = np.empty((4, 3))
    gP = np.empty(6)
    gZ = np.empty(6)
    gl = np.empty(6)
    HP = np.empty((6, 6))
    hl = np.empty((6, 6))
    alpha = _path_terms(E, A, B, r, xa, xb, True, geo, ev, gP, gZ, gl, HP, hl)
    if alpha > 0.0:
        gL[:] = gl
        HL[:, :] = hl
    return alpha


@njit(cache=True, error_model="numpy")
def _wrap_eval(c, k, x, grad, hess, want_hess):
    """Wrap row k: segment a-b (a = node[k, 0], b = node[k, 1] = a + 1) whose axis must stay outside the
    cylinder of the cable radius r round the edge line (point[k], axis[k] = A), wrapping round it on the
    side[k] (B).

    Geometry in the plane across the edge (coordinates p along B, q along A x B): node distances d_a, d_b
    from the edge and angles phi_a, phi_b from B; the axis' path over the edge is tangent - arc -
    tangent, P = t_a + t_b + r alpha (t = sqrt(d^2 - r^2), alpha = |phi_a - phi_b| - acos(r/d_a) -
    acos(r/d_b) the arc, also the angle the cable turns through), unrolled with the offset along the
    edge: L = sqrt(P^2 + Delta^2). The wrap is active while alpha > 0 (the chord passes closer to the
    edge than r); at alpha = 0 the path is the chord.

    Stretch: the segment's material is split at a point S of the arc (its angle psi from B, anchor[k, 0], fixed over a
    step: :func:`_update_friction` moves it to the arc's middle between steps, the material fraction with it): part 1
    (node a's side, rest length sigma l0, stiffness ks / sigma) spans the path from a to S, L1 = L P1 / P with P1 = t_a
    + r theta_a (theta_a the arc from a's tangent point to S), part 2 the rest, L2 = L - L1. So node a feels T1 along
    the path and b T2, whatever their distances from the edge (a split that moved with the nodes, (L + d_a - d_b) / 2,
    pushed a node near the edge along its radius by (T2 - T1) / 2: it lifted the last node on a table off its friction).
    The edge holds the split (sigma anchored, anchor[k, 3]) while the tensions differ by at most the capstan's friction
    cap = (exp(mu alpha) - 1) T_small (frozen, cap[k]); beyond it the material slides over the edge (the slip s
    minimises the two springs' energy plus cap |s|, the Huber potential's limit). Bending: the bends at a and b are
    measured against the path's directions there (seg[k, 2], seg[k, 3]: the bending constants at a and b, 0 to leave a
    bend alone), the turn over the edge is the edge's (a node b between two wrapped paths keeps the share
    1 - s(alpha_ab) s(alpha_bc) of its bend, s the smoothstep of alpha / ARC_BLEND). The row's potential replaces the
    segment's own spring and those two bends:

        W = V(L1, L2) - 1/2 ks (|x_b - x_a| - l0)^2 + sum_{a, b} 1/2 k_b (theta_path^2 - theta_chord^2)

    Returns (active, W [J], T1, T2 [N] the two parts' tensions, alpha [rad], slip s [m], L1 / L (the
    frictionless split; not wrapped: t_a / (t_a + t_b), where a wrap starts from), the elastic part of W [J]).
    grad (12,) <- dW/dX [N], X the positions of nodes a - 1, a, b, b + 1 (entries of a missing node stay 0); with
    want_hess, hess (12, 12) <- an approximation of its Hessian [N/m]: the wrapped spring's positive semi-definite part
    (the two parts' springs along the path, the path's geometric stiffness with the mean tension, the tension
    difference's term left out) and the bends' Hessians through the first derivatives of the path's
    directions, minus the chord's spring and bends as the core adds them (so the Newton matrix keeps
    the core's kind of spring).
    """
    a, b = c.node[k, 0], c.node[k, 1]
    n = x.shape[0]
    r = c.radius[0] + c.seg[k, 4]  # the edge's own rounding (a mesh's collision margin) adds to the cable's radius
    ks, l0 = c.seg[k, 0], c.seg[k, 1]
    kba = c.seg[k, 2] if a > 0 else 0.0
    kbb = c.seg[k, 3] if b < n - 1 else 0.0
    E, A, B = c.point[k], c.axis[k], c.side[k]
    ch = np.empty(3)
    cl2 = 0.0
    for j in range(3):
        ch[j] = x[b, j] - x[a, j]
        cl2 += ch[j] * ch[j]
    chord = math.sqrt(cl2)
    grad[:] = 0.0
    if want_hess:
        hess[:, :] = 0.0
    if chord == 0.0:
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.5, 0.0
    # the path's geometry, its gradient, and its exact Hessian H_L where the bends or the Newton matrix need it
    need_hl = kba > 0.0 or kbb > 0.0
    pg = np.empty(10)
    ev = np.empty((4, 3))
    gP = np.empty(6)
    gZ = np.empty(6)
    gL = np.empty(6)
    HP = np.empty((6, 6))
    HL = np.zeros((6, 6))
    alpha = _path_terms(E, A, B, r, x[a], x[b], need_hl or want_hess, pg, ev, gP, gZ, gL, HP, HL)
    da, db = pg[3], pg[4]
    if da == 0.0 or db == 0.0:
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.5, 0.0
    if alpha <= 0.0:
        tt = pg[5] + pg[6]
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, pg[5] / tt if tt > 0.0 else 0.5, 0.0
    P, L, ta, tb, sg = pg[1], pg[2], pg[5], pg[6], pg[7]
    # the path from a to the split point S (kept inside the path: S leaves the arc only within a step)
    P1 = ta + r * sg * (pg[8] - c.anchor[k, 0])
    held = P1 < SIGMA_MIN * P or P1 > (1.0 - SIGMA_MIN) * P  # then a fixed fraction of P
    P1 = min(max(P1, SIGMA_MIN * P), (1.0 - SIGMA_MIN) * P)
    L1 = L * P1 / P
    L2 = L - L1
    sig = min(max(c.anchor[k, 3], SIGMA_MIN), 1.0 - SIGMA_MIN)
    k1, k2 = ks / sig, ks / (1.0 - sig)
    e1, e2 = L1 - sig * l0, L2 - (1.0 - sig) * l0
    tau = k1 * e1 - k2 * e2
    cap = c.cap[k]
    slip = 0.0
    stick = abs(tau) <= cap
    if not stick:
        slip = (tau - math.copysign(cap, tau)) / (k1 + k2)
    T1, T2 = k1 * (e1 - slip), k2 * (e2 + slip)
    stored = 0.5 * k1 * (e1 - slip) ** 2 + 0.5 * k2 * (e2 + slip) ** 2 - 0.5 * ks * (chord - l0) ** 2
    # gradients (6,) over (x_a, x_b) of the two parts' lengths and the chord (P, Z, L from the path)
    J1 = np.empty(6)
    J2 = np.empty(6)
    gC = np.empty(6)
    for j in range(6):
        if held:
            gP1 = (P1 / P) * gP[j]
        else:  # P1 = t_a + r theta_a: node a's part of dP only
            gP1 = gP[j] if j < 3 else 0.0
        J1[j] = (P1 / P) * gL[j] + (L / P) * (gP1 - (P1 / P) * gP[j])
        J2[j] = gL[j] - J1[j]
    for j in range(3):
        gC[j] = -ch[j] / chord
        gC[3 + j] = ch[j] / chord
    tc = ks * (chord - l0)
    for j in range(6):  # nodes a, b are entries 3..8 of the 12
        grad[3 + j] = T1 * J1[j] + T2 * J2[j] - tc * gC[j]
    if want_hess:
        kk = k1 * k2 / (k1 + k2)
        tm = max(0.5 * (T1 + T2), 0.0)
        geo = max(1.0 - l0 / chord, 0.0)
        for i in range(6):
            for j in range(6):
                if stick:
                    h = k1 * J1[i] * J1[j] + k2 * J2[i] * J2[j]
                else:
                    h = kk * gL[i] * gL[j]
                # the path's geometric stiffness, its curvature bounded where a tangent is short; a node's
                # own curvature carries its own part's tension (S fixed: P1 holds a's, P2 b's)
                h += tm * (gP[i] * gP[j] + gZ[i] * gZ[j] - gL[i] * gL[j]) / L
                if (i < 3) == (j < 3):
                    d, t = (da, ta) if i < 3 else (db, tb)
                    ts = tm if held else max(T1 if i < 3 else T2, 0.0)
                    h += ts * P * HP[i, j] * max(t, 1e-6 * r) / max(t, 0.1 * r) / L if d > r else 0.0
                # the chord's own spring (as the core's, compressive part filtered), taken out
                ii, jj = i % 3, j % 3
                cc = ch[ii] * ch[jj] / cl2
                hc = ks * (cc + geo * ((1.0 if ii == jj else 0.0) - cc))
                h -= hc if (i < 3) == (j < 3) else -hc
                hess[3 + i, 3 + j] = h
    if need_hl:
        # bends at a (incoming segment u_a, outgoing: the path's direction -dL/dx_a, else the chord) and at b
        Jp = np.zeros((3, 12))
        Jq = np.zeros((3, 12))
        p = np.empty(3)
        q = np.empty(3)
        gN = np.empty(6)
        HN = np.empty((6, 6))
        if kba > 0.0 and c.seg[k, 5] > 0.0 and _path(E, A, B, r, x[a - 1], x[a], gN, HN) > 0.0:
            # the segment before has its own wrap row round this edge and its path wraps: that row bends a
            # (between the two paths). Without such a row nothing else would, and dropping the bend here
            # made W jump (by 1e-3 J on the soft cable) where the segment before's chord crosses the
            # cylinder round the edge: Newton's line search stalled on the jump (issue 23 item 3)
            kba = 0.0
        if kba > 0.0:
            for j in range(3):
                p[j] = x[a, j] - x[a - 1, j]
                q[j] = -gL[j]
            Jp[:, :] = 0.0
            Jq[:, :] = 0.0
            for j in range(3):
                Jp[j, j] = -1.0
                Jp[j, 3 + j] = 1.0
                for i in range(6):
                    Jq[j, 3 + i] = -HL[j, i]
            stored += _add_bend(p, q, kba, 1.0, Jp, Jq, grad, hess, want_hess)
            Jq[:, :] = 0.0
            for j in range(3):
                q[j] = ch[j]
                Jq[j, 3 + j] = -1.0
                Jq[j, 6 + j] = 1.0
            stored += _add_bend(p, q, kba, -1.0, Jp, Jq, grad, hess, want_hess)
        if kbb > 0.0:
            Jp[:, :] = 0.0
            Jq[:, :] = 0.0
            geo_n = np.zeros(10)
            ev_n = np.empty((4, 3))
            gP_n = np.empty(6)
            gZ_n = np.empty(6)
            HP_n = np.empty((6, 6))
            alpha_n = _path_terms(E, A, B, r, x[b], x[b + 1], True, geo_n, ev_n, gP_n, gZ_n, gN, HP_n, HN)
            next_wraps = alpha_n > 0.0
            for j in range(3):
                p[j] = gL[3 + j]
                for i in range(6):
                    Jp[j, 3 + i] = HL[3 + j, i]
                if next_wraps:  # the segment after wraps the same edge: b bends between the two paths
                    q[j] = -gN[j]
                    for i in range(6):
                        Jq[j, 6 + i] = -HN[j, i]
                else:
                    q[j] = x[b + 1, j] - x[b, j]
                    Jq[j, 6 + j] = -1.0
                    Jq[j, 9 + j] = 1.0
            keep = 1.0
            if next_wraps:
                # b between two wrapped paths: the kink 2 acos(r / d_b) between their tangents at b is no bend of the
                # cable's (the turn over the edge is the edge's), and its 1/2 k_b theta^2, linear in b's lift off the
                # cylinder, made b's potential V-shaped there: Newton did not converge in 142 of 144 steps of each
                # crossing (issue 23 item 3). Kept in full where either arc starts (continuous with a chord's bend),
                # gone once both arcs exceed ARC_BLEND: keep = 1 - s(alpha_ab) s(alpha_bc), its gradient exact, the
                # Hessian the kept share of the bend's
                s_ab, ds_ab = _blend(alpha)
                s_bc, ds_bc = _blend(alpha_n)
                keep = 1.0 - s_ab * s_bc
                if keep < 1.0:
                    theta = _angle_terms(p[0], p[1], p[2], q[0], q[1], q[2])[0]
                    e_b = 0.5 * kbb * theta * theta
                    ga = np.empty(6)
                    _arc_gradient(pg, ev, r, ga)
                    gb = np.empty(6)
                    _arc_gradient(geo_n, ev_n, r, gb)
                    for j in range(6):
                        grad[3 + j] -= e_b * ds_ab * s_bc * ga[j]
                        grad[6 + j] -= e_b * s_ab * ds_bc * gb[j]
            stored += _add_bend(p, q, kbb * keep, 1.0, Jp, Jq, grad, hess, want_hess)
            Jq[:, :] = 0.0
            for j in range(3):
                q[j] = x[b + 1, j] - x[b, j]
                Jq[j, 6 + j] = -1.0
                Jq[j, 9 + j] = 1.0
            Jp[:, :] = 0.0
            for j in range(3):
                p[j] = ch[j]
                Jp[j, 3 + j] = -1.0
                Jp[j, 6 + j] = 1.0
            stored += _add_bend(p, q, kbb, -1.0, Jp, Jq, grad, hess, want_hess)
    if want_hess:
        for i in range(12):
            for j in range(i):
                sym = 0.5 * (hess[i, j] + hess[j, i])
                hess[i, j] = sym
                hess[j, i] = sym
    W = stored + cap * abs(slip)
    return True, W, T1, T2, alpha, slip, L1 / L, stored


@njit(cache=True, error_model="numpy")
def mark_wrap_neighbours(c, first):
    """seg[k, 5] <- 1.0 for each WRAP row k (from row ``first`` on) whose segment's predecessor has a WRAP row round
    the same edge line (same direction and side, its point on the line within 1e-9 m), else 0.0. Only then does
    :func:`_wrap_eval` leave the bend at the shared node to that row: the choice depends on the rows, not on
    where the predecessor's chord happens to lie, so each row's potential is continuous in the positions."""
    for k in range(first, c.count[0]):
        if c.kind[k] != WRAP:
            continue
        c.seg[k, 5] = 0.0
        for j in range(first, c.count[0]):
            if c.kind[j] != WRAP or c.node[j, 0] != c.node[k, 0] - 1:
                continue
            dot_a = 0.0
            dot_b = 0.0
            along = 0.0
            for q in range(3):
                dot_a += c.axis[j, q] * c.axis[k, q]
                dot_b += c.side[j, q] * c.side[k, q]
                along += (c.point[j, q] - c.point[k, q]) * c.axis[k, q]
            off = 0.0
            for q in range(3):
                off += (c.point[j, q] - c.point[k, q] - along * c.axis[k, q]) ** 2
            if abs(dot_a) > 1.0 - 1e-12 and dot_b > 1.0 - 1e-12 and off < 1e-18:
                c.seg[k, 5] = 1.0


@njit(cache=True, error_model="numpy")
def _arc_middle(c, k, x):
    """The angle [rad] from the side B of the middle of wrap row k's arc at x (where its two tangent points'
    angles meet when the path does not wrap), the arc alpha [rad], the unrolled path's length L [m] (0 when
    not wrapped) and the share [-] of the path across the edge from node a to the arc's middle, (t_a + r alpha / 2) /
    P (-1 when not wrapped)."""
    geo = np.zeros(10)
    ev = np.empty((4, 3))
    g6 = np.empty(6)
    h6 = np.empty((6, 6))
    a, b = c.node[k, 0], c.node[k, 1]
    alpha = _path_terms(c.point[k], c.axis[k], c.side[k], c.radius[0] + c.seg[k, 4], x[a], x[b], False, geo, ev,
                        g6, g6, g6, h6, h6)
    r = c.radius[0] + c.seg[k, 4]
    wrapped = alpha > 0.0
    return (0.5 * (geo[8] + geo[9]), alpha, geo[2] if wrapped else 0.0,
            (geo[5] + 0.5 * r * alpha) / geo[1] if wrapped else -1.0)


@njit(cache=True, error_model="numpy")
def wrap_start(c, k, x):
    """A new wrap's friction anchor: the split point S at its arc's middle, the material fraction [-] on
    node[k, 0]'s side that leaves both parts at the same tension (L1 / L, see :func:`_wrap_eval`)."""
    g = np.empty(12)
    h = np.empty((12, 12))
    c.anchor[k, 0] = _arc_middle(c, k, x)[0]
    c.anchor[k, 3] = _wrap_eval(c, k, x, g, h, False)[6]


@njit(cache=True, error_model="numpy")
def _recentre_wrap(c, k, x):
    """Where wrap row k's split point S has left its arc at x (a node rounding the edge has passed it), move S
    to the arc's middle (after a step: within one S stays put, so the nodes feel their own parts' tensions),
    with the material between the old and the new S: the material fraction sigma changes by that stretch of path
    over the stretch (1 + T / (k_s l0)) of the part that gives it, which keeps its tension; the other part's moves
    towards it. Only where S has left the arc: moved at every step, S follows the arc's jitter back and forth,
    and each return trip passes tension from the tighter part to the slacker one, eroding the capstan's
    friction. The change of the stored energy counts as work on the cable, as a new wrap's energy does."""
    g = np.empty(12)
    h = np.empty((12, 12))
    psi, alpha, L, _ = _arc_middle(c, k, x)
    if L == 0.0 or abs(c.anchor[k, 0] - psi) <= 0.5 * alpha:
        return
    _, _, T1, T2, _, _, f_old, e_old = _wrap_eval(c, k, x, g, h, False)
    c.anchor[k, 0] = psi
    f_new = _wrap_eval(c, k, x, g, h, False)[6]
    ks, l0 = c.seg[k, 0], c.seg[k, 1]
    moved = (f_new - f_old) * L  # path that changes from part 2 to part 1 [m]
    t_left = T2 if moved > 0.0 else T1
    sig = c.anchor[k, 3] + moved / (l0 + max(t_left, 0.0) / ks)
    c.anchor[k, 3] = min(max(sig, SIGMA_MIN), 1.0 - SIGMA_MIN)
    c.body_work[0] += _wrap_eval(c, k, x, g, h, False)[7] - e_old


@njit(cache=True, error_model="numpy")
def wrap_energy(c, k, x):
    """The elastic energy [J] wrap row k adds to the chain's at x (its part of :func:`contact_energy`)."""
    g = np.empty(12)
    h = np.empty((12, 12))
    return _wrap_eval(c, k, x, g, h, False)[7]


@njit(cache=True, error_model="numpy")
def wrap_active(c, k, x):
    """Whether wrap row k's path wraps round its edge at x (alpha > 0, see :func:`_wrap_eval`)."""
    g = np.empty(12)
    h = np.empty((12, 12))
    return _wrap_eval(c, k, x, g, h, False)[0]


@njit(cache=True, error_model="numpy")
def wrap_arc_share(c, k, x):
    """Where wrap row k's arc lies on its path at x: the share [-] of the path across the edge from node a to the
    arc's middle, (t_a + r alpha / 2) / P (:func:`_wrap_eval`). Along the edge the unrolled path is straight, so the
    arc's middle lies that share of the way from a's coordinate along the edge to b's. -1 when the path does not
    wrap."""
    return _arc_middle(c, k, x)[3]


@njit(cache=True, error_model="numpy")
def _wrap_cap(c, k, x):
    """The capstan's friction limit [N] of wrap row k at x: (exp(mu alpha) - 1) T_small (mu_s while stuck,
    mu_d while sliding; the tensions with the caps in c.cap)."""
    g = np.empty(12)
    h = np.empty((12, 12))
    active, _, T1, T2, alpha, _, _, _ = _wrap_eval(c, k, x, g, h, False)
    if not active:
        return 0.0
    mu = c.static_friction[k] if c.state[k] == STICK else c.dynamic_friction[k]
    return (math.exp(mu * alpha) - 1.0) * max(min(T1, T2), 0.0)


# ----- forces, potential, Jacobian -----------------------------------------------------------
@njit(cache=True, error_model="numpy")
def contact_forces(c, x, v, f):
    """f <- contact forces on the nodes [N] at (x, v), (n, 3); also fills c.f_n, c.f_t (caps frozen)."""
    f[:, :] = 0.0
    u = np.empty(3)
    gw = np.empty(12)
    hw = np.empty((12, 12))
    for k in range(c.count[0]):
        a, b = c.node[k, 0], c.node[k, 1]
        if c.kind[k] == WRAP:
            fn2 = 0.0
            _wrap_eval(c, k, x, gw, hw, False)
            for q in range(4):
                i = a - 1 + q
                if 0 <= i < x.shape[0]:
                    for j in range(3):
                        f[i, j] -= gw[3 * q + j]
            for j in range(3):
                push = -(gw[j] + gw[3 + j] + gw[6 + j] + gw[9 + j])  # the edge's push on the cable
                fn2 += push * push
                c.f_t[k, j] = 0.0
            c.f_n[k] = math.sqrt(fn2)
            if c.f_n[k] > 0.0:
                for j in range(3):
                    c.normal[k, j] = -(gw[j] + gw[3 + j] + gw[6 + j] + gw[9 + j]) / c.f_n[k]
            continue
        wa, wb = c.weight[k, 0], c.weight[k, 1]
        g = _gap(c, k, x)
        fn = 0.0
        if g < 0.0:
            fn = -c.k_n[k] * g - c.c_n[k] * _approach(c, k, v)
        ul = _slip(c, k, x, u)
        kt, cap = c.k_t[k], c.cap[k]
        if _sticks(c, k, ul):
            sc = -kt
        elif ul > 0.0:
            sc = -cap / ul
        else:
            sc = 0.0
        sa = c.anchor[k, 3]
        for j in range(3):
            ft = sc * u[j]
            c.f_t[k, j] = ft
            f[a, j] += wa * fn * c.normal[k, j] + (1.0 - sa) * ft
            f[b, j] += wb * fn * c.normal[k, j] + sa * ft
        c.f_n[k] = fn
    grip_forces(c.grip, x, f)


@njit(cache=True, error_model="numpy")
def contact_potential(c, x, v, damping_weight):
    """Potential [J] of the contact forces at (x, v): penalty 1/2 k_n g^2, friction Huber potential
    (caps frozen) and ``damping_weight`` [s] times the normal dampers' Rayleigh term (merit only)."""
    phi = 0.0
    u = np.empty(3)
    gw = np.empty(12)
    hw = np.empty((12, 12))
    for k in range(c.count[0]):
        if c.kind[k] == WRAP:
            phi += _wrap_eval(c, k, x, gw, hw, False)[1]
            continue
        g = _gap(c, k, x)
        if g < 0.0:
            qn = _approach(c, k, v)
            phi += 0.5 * c.k_n[k] * g * g + 0.5 * damping_weight * c.c_n[k] * qn * qn
        ul = _slip(c, k, x, u)
        kt, cap = c.k_t[k], c.cap[k]
        if cap <= 0.0:  # no friction
            pass
        elif _sticks(c, k, ul):
            phi += 0.5 * kt * ul * ul
        else:
            phi += cap * ul - 0.5 * cap * cap / kt
    return phi + grip_potential(c.grip, x)


@njit(cache=True, error_model="numpy")
def contact_energy(c, x):
    """Energy [J] stored in the contacts at x: penalty springs and friction anchor springs."""
    e = 0.0
    u = np.empty(3)
    gw = np.empty(12)
    hw = np.empty((12, 12))
    for k in range(c.count[0]):
        if c.kind[k] == WRAP:  # the two parts' springs instead of the chord's (elastic only: no slip at rest)
            e += _wrap_eval(c, k, x, gw, hw, False)[7]
            continue
        g = _gap(c, k, x)
        if g < 0.0:
            e += 0.5 * c.k_n[k] * g * g
        ul = _slip(c, k, x, u)
        ft = min(c.k_t[k] * ul, c.cap[k])
        e += 0.5 * ft * ft / c.k_t[k] if c.k_t[k] > 0.0 else 0.0
    return e + grip_energy(c.grip, x)


@njit(cache=True, error_model="numpy", inline="always")
def _row_blocks(c, k, x, kx, kv, u, blk):
    """blk (2, 3, 3) <- penalty row k's stiffness at x: blk[0] = (kx k_n + kv c_n) n n^T while g < 0 (normal, at the
    closest point), blk[1] = kx times the friction spring's (stick: k_t P_t; slide: (cap/|u|)(P_t - u u^T/|u|^2),
    at the anchored point); u: scratch (3,)."""
    g = _gap(c, k, x)
    ul = _slip(c, k, x, u)
    kt, cap = c.k_t[k], c.cap[k]
    stick = _sticks(c, k, ul)
    # scalars chosen first, arrays read in straight code (tests/core/test_kernel_refcounts.py)
    kn = kx * c.k_n[k] + kv * c.c_n[k]
    kp, ku, uu = 0.0, 0.0, 1.0  # blk[1] = kp (P_t - ku u u^T / uu)
    if stick:
        kp = kx * kt
    elif ul > 0.0:
        kp, ku, uu = kx * (cap / ul), 1.0, ul * ul
    for r in range(3):
        for q in range(3):
            nn = c.normal[k, r] * c.normal[k, q]  # (elements, not a view of the row: a view is reference-counted)
            blk[0, r, q] = kn * nn if g < 0.0 else 0.0
            blk[1, r, q] = kp * (((1.0 if r == q else 0.0) - nn) - ku * u[r] * u[q] / uu)


@njit(cache=True, error_model="numpy")
def add_contact_jacobian(c, held, x, kx, kv, band):
    """band += kx (-dF/dx) + kv (-dF/dv) of the contact forces at x (3x3 blocks, symmetric).

    Normal: k_n n n^T (+ c_n n n^T on dF/dv) while g < 0; stick: k_t P_t; slide:
    (cap/|u|)(P_t - u u^T/|u|^2). Rows and columns of held nodes are left alone (identity).
    """
    blk = np.empty((2, 3, 3))
    wts = np.empty((2, 2))
    u = np.empty(3)
    gw = np.empty(12)
    hw = np.empty((12, 12))
    for k in range(c.count[0]):
        if c.kind[k] == WRAP:
            if _wrap_eval(c, k, x, gw, hw, True)[0]:
                nn = x.shape[0]
                for aa in range(4):
                    na = c.node[k, 0] - 1 + aa
                    if na < 0 or na >= nn or held[na]:
                        continue
                    for bb in range(4):
                        nb = c.node[k, 0] - 1 + bb
                        if nb < 0 or nb >= nn or held[nb] or abs(aa - bb) > 2:
                            continue
                        for r in range(3):
                            for q in range(3):
                                row = 3 * na + r
                                band[row, 3 * nb + q - row + HALF] += kx * hw[3 * aa + r, 3 * bb + q]
            continue
        _row_blocks(c, k, x, kx, kv, u, blk)
        wts[0, 0], wts[0, 1] = c.weight[k, 0], c.weight[k, 1]  # normal force at the closest point
        wts[1, 0], wts[1, 1] = 1.0 - c.anchor[k, 3], c.anchor[k, 3]  # friction at the anchored point
        for p in range(2):
            for aa in range(2):
                na = c.node[k, aa]
                if wts[p, aa] == 0.0 or held[na]:
                    continue
                for bb in range(2):
                    nb = c.node[k, bb]
                    if wts[p, bb] == 0.0 or held[nb]:
                        continue
                    w = wts[p, aa] * wts[p, bb]
                    for r in range(3):
                        for q in range(3):
                            row = 3 * na + r
                            band[row, 3 * nb + q - row + HALF] += w * blk[p, r, q]
    add_grip_jacobian(c.grip, x, kx, band)


@njit(cache=True, error_model="numpy")
def elastic_caps(c, x, out):
    """out <- friction limits mu f_n [N] from the penalty force at x (mu_s if stuck, mu_d if sliding)."""
    for k in range(c.count[0]):
        if c.kind[k] == WRAP:
            out[k] = _wrap_cap(c, k, x)
            continue
        g = _gap(c, k, x)
        mu = c.static_friction[k] if c.state[k] == STICK else c.dynamic_friction[k]
        out[k] = mu * c.k_n[k] * (-g) if g < 0.0 else 0.0


@njit(cache=True, error_model="numpy")
def bounded_caps(c, x, X, mass, held, cx, hf, out):
    """out <- :func:`elastic_caps` at the predictor's positions X (the step's map at the start velocities), except that
    the depth a penalty row's own motion adds over the step (its predicted depth beyond its depth at the step's start
    positions x) is taken with the stiffness the step's inertia gives it, min(k_n, m_row / (cx hf)) (m_row the row
    point's effective mass, its held nodes left out; all held: k_n): the force that stops the row within the step, not
    the penalty's at a depth the solve will not reach. The limits a contact solve starts from again when the one from
    :func:`elastic_caps` ended wildly far from convergence (:func:`~bullet_dlo.core.kernels.steppers.newton`)."""
    for k in range(c.count[0]):
        if c.kind[k] == WRAP:
            out[k] = _wrap_cap(c, k, X)
            continue
        mu = c.static_friction[k] if c.state[k] == STICK else c.dynamic_friction[k]
        depth = max(-_gap(c, k, X), 0.0)
        start = max(-_gap(c, k, x), 0.0)
        kn = c.k_n[k]
        inv = 0.0  # 1 / m_row: the row's point p = w0 x_a + w1 x_b moves as a mass m_row under a force at it
        for q in range(2):
            i, w = c.node[k, q], c.weight[k, q]
            if w != 0.0 and not held[i]:
                inv += w * w / mass[i]
        k_step = kn if inv == 0.0 else min(kn, 1.0 / (inv * cx * hf))
        out[k] = mu * (kn * depth if depth <= start else kn * start + k_step * (depth - start))


@njit(cache=True, error_model="numpy")
def caps_settled(c, x, caps_new, cap_tol) -> bool:
    """caps_new <- the friction limits at x (:func:`elastic_caps`); whether they differ from those the solve used
    (c.cap) by at most cap_tol of the largest (the contact Newton solves' outer fixed point on the caps)."""
    elastic_caps(c, x, caps_new)
    cmax = 0.0
    dcap = 0.0
    for k in range(c.count[0]):
        cmax = max(cmax, caps_new[k])
        dcap = max(dcap, abs(caps_new[k] - c.cap[k]))
    return dcap <= cap_tol * cmax


@njit(cache=True, error_model="numpy")
def relax_caps(c, caps_new, history, passes):
    """c.cap <- the friction limits [N] for the next pass of the outer fixed point cap = mu f_n(x(cap)), caps_new
    the limits at the solution with c.cap (:func:`caps_settled`). From the second pass on, each row steps towards
    caps_new by 1 / (1 - s), s its secant slope of the map over its last two passes, kept within [1/4, 1]: a row
    whose limit overshoots (s < 0: a large limit lifts the row out of the ground and a small one lets it back in,
    so its limit jumps between zero and a value, or alternates and decays slowly) moves part way, to where the
    secant crosses; a row that converges monotonically takes the whole step. history (count, 2): each row's limit
    used and the limit it gave in the last pass (written here)."""
    for k in range(c.count[0]):
        step = caps_new[k] - c.cap[k]
        if passes > 1:
            used = c.cap[k] - history[k, 0]
            if used != 0.0:
                slope = (caps_new[k] - history[k, 1]) / used
                if slope < 0.0:
                    step *= max(0.25, 1.0 / (1.0 - slope))
        history[k, 0] = c.cap[k]
        history[k, 1] = caps_new[k]
        c.cap[k] += step


# ----- free bodies solved with the cable (see Bodies) ---------------------------------------------
@njit(cache=True, error_model="numpy")
def start_bodies(c, bd, h):
    """Start of a contact step of h [s] with the free bodies ``bd`` (:class:`Bodies`): mark the body slots some
    row touches, keep every row's surface point and anchor at the start (point0, anchor0) and start Newton's
    body iterate at the bodies' velocity; rows on other moving surfaces (slot -1) move at their body_vel over
    the step. Returns the active slots."""
    for s in range(bd.active.shape[0]):
        bd.active[s] = False
        for j in range(6):
            bd.vel_new[s, j] = bd.vel[s, j]
    for k in range(c.count[0]):
        s = bd.slot[k]
        for j in range(3):
            bd.point0[k, j] = c.point[k, j]
            bd.anchor0[k, j] = c.anchor[k, j]
        if s >= 0:
            bd.active[s] = True
        else:
            for j in range(3):
                c.point[k, j] += h * c.body_vel[k, j]
                c.anchor[k, j] += h * c.body_vel[k, j]
    active = 0
    for s in range(bd.active.shape[0]):
        if bd.active[s]:
            active += 1
    return active


@njit(cache=True, error_model="numpy", inline="always")
def _point_velocity(vel, s, arm):
    """The velocity [m/s] U + Omega x arm of body s's material point at ``arm`` (3,) [m] from its centre of mass,
    at velocities vel (S, 6) [m/s, rad/s]."""
    a0, a1, a2 = arm[0], arm[1], arm[2]
    w0, w1, w2 = vel[s, 3], vel[s, 4], vel[s, 5]
    return vel[s, 0] + w1 * a2 - w2 * a1, vel[s, 1] + w2 * a0 - w0 * a2, vel[s, 2] + w0 * a1 - w1 * a0


@njit(cache=True, error_model="numpy", inline="always")
def _add_wrench(out, s, arm, h, f0, f1, f2):
    """out[s] (6,) += h times the force (f0, f1, f2) and its torque arm x f about the centre of mass (force [N] or
    [N s], arm [m])."""
    a0, a1, a2 = arm[0], arm[1], arm[2]
    out[s, 0] += h * f0
    out[s, 1] += h * f1
    out[s, 2] += h * f2
    out[s, 3] += h * (a1 * f2 - a2 * f1)
    out[s, 4] += h * (a2 * f0 - a0 * f2)
    out[s, 5] += h * (a0 * f1 - a1 * f0)


@njit(cache=True, error_model="numpy")
def load_bodies(c, bd, h, vel):
    """Put the free bodies ``bd`` at end-of-step velocities vel (S, 6) [m/s, rad/s] into their rows: body_vel =
    U + Omega x arm, the surface point and the anchor moved from the start of the step by h [s] times it."""
    for k in range(c.count[0]):
        s = bd.slot[k]
        if s < 0:
            continue
        c.body_vel[k, 0], c.body_vel[k, 1], c.body_vel[k, 2] = _point_velocity(vel, s, bd.arm[k])
        for j in range(3):
            c.point[k, j] = bd.point0[k, j] + h * c.body_vel[k, j]
            c.anchor[k, j] = bd.anchor0[k, j] + h * c.body_vel[k, j]


@njit(cache=True, error_model="numpy")
def body_residual(c, bd, h, vel):
    """bodies.residual <- h (M g + F) - M (U - U_0) and h tau - I (Omega - Omega_0) [N s, N m s] of the
    velocities vel (S, 6) the rows hold (:func:`load_bodies`), F and tau the reactions of the rows' forces
    c.f_n, c.f_t (minus the force on the cable, at the arm); zero for inactive slots."""
    res = bd.residual
    for s in range(bd.active.shape[0]):
        for j in range(6):
            res[s, j] = 0.0
        if not bd.active[s]:
            continue
        for j in range(3):
            res[s, j] = bd.mass[s] * (h * bd.gravity[j] - (vel[s, j] - bd.vel[s, j]))
            acc = 0.0
            for q in range(3):
                acc += bd.inertia[s, j, q] * (vel[s, 3 + q] - bd.vel[s, 3 + q])
            res[s, 3 + j] = -acc
        for j in range(6):  # the other cables' reactions on a body they share (zero for the others)
            acc = 0.0
            for q in range(6):
                acc += bd.other_mass[s, j, q] * (vel[s, q] - bd.vel[s, q])
            res[s, j] -= acc
    _add_reactions(c, bd, h, res)
    _add_holders(bd, h, vel, res)


@njit(cache=True, error_model="numpy", inline="always")
def _holder_speed(bd, s, p, vel):
    """The normal velocity [m/s] of body s's point at its holder contact p at velocities vel (S, 6), relative to the
    holder's (bd.hold_vel; positive: leaving it)."""
    u0, u1, u2 = _point_velocity(vel, s, bd.hold_arm[s, p])
    return (u0 * bd.hold_normal[s, p, 0] + u1 * bd.hold_normal[s, p, 1] + u2 * bd.hold_normal[s, p, 2]
            - bd.hold_vel[s, p])  # (elements, not a view of the normal: a view is reference-counted)


@njit(cache=True, error_model="numpy", inline="always")
def _holder_change(bd, s, p, vel):
    """The change [N] of the normal load of body s's holder contact p from the one measured (bd.hold_load) at
    velocities vel: -hold_c v_n while the body's point leaves the holder (v_n > 0), down to -hold_load (a holder
    only pushes), else none; and whether it is in between (the load changes with v_n there)."""
    dl = -bd.hold_c[s] * _holder_speed(bd, s, p, vel)
    load = bd.hold_load[s, p]  # (read before the branches: see _gap)
    if dl >= 0.0:
        return 0.0, False
    if dl <= -load:
        return -load, False
    return dl, True


@njit(cache=True, error_model="numpy")
def _add_holders(bd, h, vel, out):
    """out (S, 6) += h times the change of the holders' loads on the active bodies at velocities vel (force [N s],
    torque about the centre of mass [N m s]; :func:`_holder_change`)."""
    for s in range(bd.active.shape[0]):
        if not bd.active[s]:
            continue
        for p in range(bd.hold_count[s]):
            dl, _ = _holder_change(bd, s, p, vel)
            n = bd.hold_normal[s, p]
            f = h * dl  # (scaled first: the same rounding as before the helper)
            _add_wrench(out, s, bd.hold_arm[s, p], 1.0, f * n[0], f * n[1], f * n[2])


@njit(cache=True, error_model="numpy")
def body_potential(bd, h, vel):
    """The free bodies' part [J] of the step's incremental potential at velocities vel (S, 6): 1/2 (delta -
    delta_0)^T (M_b + other_mass) (delta - delta_0) - h M g . U (implicit Euler; the rows' contact potential is the
    cable's) plus the holders' (:func:`_holder_change`)."""
    phi = 0.0
    for s in range(bd.active.shape[0]):
        if not bd.active[s]:
            continue
        for j in range(3):
            du = vel[s, j] - bd.vel[s, j]
            phi += 0.5 * bd.mass[s] * du * du - h * bd.mass[s] * bd.gravity[j] * vel[s, j]
            for q in range(3):
                phi += 0.5 * (vel[s, 3 + j] - bd.vel[s, 3 + j]) * bd.inertia[s, j, q] * (vel[s, 3 + q] - bd.vel[s, 3 + q])
        for j in range(6):
            for q in range(6):
                phi += 0.5 * (vel[s, j] - bd.vel[s, j]) * bd.other_mass[s, j, q] * (vel[s, q] - bd.vel[s, q])
        for p in range(bd.hold_count[s]):  # h times the holder's potential in v_n: its slope is -(change of load)
            cv, load = max(bd.hold_c[s] * _holder_speed(bd, s, p, vel), 0.0), bd.hold_load[s, p]
            phi += h * (0.5 * cv * cv if cv < load else load * cv - 0.5 * load * load) / bd.hold_c[s]
    return phi


@njit(cache=True, error_model="numpy")
def bodies_converged(bd, h, tol, floor):
    """Whether every active body's residual is within BODY_TOL ``tol`` of its momentum scale (h M |g| plus its
    momentum change; for rotation the same times its radius of gyration plus I |dOmega|), plus a round-off ``floor``
    [N s] (the cable's, of the stiff springs' forces)."""
    tol = BODY_TOL * tol
    g = math.sqrt(bd.gravity[0] ** 2 + bd.gravity[1] ** 2 + bd.gravity[2] ** 2)
    for s in range(bd.active.shape[0]):
        if not bd.active[s]:
            continue
        m = bd.mass[s]
        i_max = max(bd.inertia[s, 0, 0], bd.inertia[s, 1, 1], bd.inertia[s, 2, 2])
        du = 0.0
        dw = 0.0
        rl = 0.0
        ra = 0.0
        for j in range(3):
            du = max(du, abs(bd.vel_new[s, j] - bd.vel[s, j]))
            dw = max(dw, abs(bd.vel_new[s, 3 + j] - bd.vel[s, 3 + j]))
            rl = max(rl, abs(bd.residual[s, j]))
            ra = max(ra, abs(bd.residual[s, 3 + j]))
        lin = h * m * g + m * du
        if not rl <= tol * lin + floor:  # (NaN fails too)
            return False
        if not ra <= tol * (lin * math.sqrt(i_max / m) + i_max * dw) + floor * math.sqrt(i_max / m):
            return False
    return True


@njit(cache=True, error_model="numpy", inline="always")
def _add_reactions(c, bd, h, out):
    """out (S, 6) += h times the reactions of the rows on their free bodies over a step of h [s]: force [N s] and
    torque about the centre of mass at the rows' arms [N m s] (the body's residual, :func:`body_residual`, and the
    impulse summed over the sub-steps of a Bullet step, ``bd.impulse``)."""
    for k in range(c.count[0]):
        s = bd.slot[k]
        if s < 0:
            continue
        f0 = -(c.f_n[k] * c.normal[k, 0] + c.f_t[k, 0])
        f1 = -(c.f_n[k] * c.normal[k, 1] + c.f_t[k, 1])
        f2 = -(c.f_n[k] * c.normal[k, 2] + c.f_t[k, 2])
        _add_wrench(out, s, bd.arm[k], h, f0, f1, f2)


@njit(cache=True, error_model="numpy")
def _bodies_under_reactions(c, bd, h):
    """bd.vel_new <- each active body's velocity after a step of h [s] from bd.vel under gravity and its rows'
    reactions (as :func:`_add_reactions`): where Bullet's update takes it when the rows' forces were changed after
    the solve (:func:`felt_forces` with the bodies' rows), the start of a next sub-step."""
    load = np.zeros((bd.active.shape[0], 6))
    _add_reactions(c, bd, h, load)
    mb = np.zeros((6, 6))
    for s in range(bd.active.shape[0]):
        if not bd.active[s]:
            continue
        if np.any(bd.other_mass[s] != 0.0):  # a shared body: its mass matrix holds the other cables' reactions
            for j in range(3):
                load[s, j] += h * bd.mass[s] * bd.gravity[j]
                for q in range(6):
                    mb[j, q] = bd.other_mass[s, j, q] + (bd.mass[s] if q == j else 0.0)
                    mb[3 + j, q] = bd.other_mass[s, 3 + j, q] + (bd.inertia[s, j, q - 3] if q >= 3 else 0.0)
            dv = np.linalg.pinv(mb) @ load[s]
            for j in range(6):
                bd.vel_new[s, j] = bd.vel[s, j] + dv[j]
            continue
        turn = np.linalg.pinv(bd.inertia[s]) @ load[s, 3:]  # (pinv: a point or flat body has no turn about some axes)
        for j in range(3):
            bd.vel_new[s, j] = bd.vel[s, j] + load[s, j] / bd.mass[s] + h * bd.gravity[j]
            bd.vel_new[s, 3 + j] = bd.vel[s, 3 + j] + turn[j]


@njit(cache=True, error_model="numpy")
def impulse_scale(m, hf):
    """hf (max_i m_i |g| + max |f_ext|) [N s]: the momentum gravity and the external forces give the heaviest node
    in a step of force weight hf [s] (the scale of newton's residual tolerance)."""
    g = math.sqrt(m.gravity[0] ** 2 + m.gravity[1] ** 2 + m.gravity[2] ** 2)
    mass_max = 0.0
    fext_max = 0.0
    for i in range(m.mass.shape[0]):
        mass_max = max(mass_max, m.mass[i])
        for j in range(3):
            fext_max = max(fext_max, abs(m.f_ext[i, j]))
    return hf * (mass_max * g + fext_max) + 1e-300


@njit(cache=True, error_model="numpy")
def stall_ratio(m, ws, hf):
    """After a Newton solve: its largest momentum residual (ws.residual) [N s] over the scale newton's
    tolerance multiplies, :func:`impulse_scale` + max_i m_i |v'_i - v_avg,i| (hf [s] the step's force weight):
    1 is the momentum gravity gives in a step (a cable that coasts through a step without its forces), the
    tolerance is ``tol`` of it (1e-3 for implicit Euler). NaN counts as infinitely far."""
    dmom = 0.0
    for i in range(ws.v_new.shape[0]):
        if not m.held[i]:
            for j in range(3):
                dmom = max(dmom, m.mass[i] * abs(ws.v_new[i, j] - ws.v_avg[i, j]))
    worst = 0.0
    for q in range(ws.residual.shape[0]):
        r = abs(ws.residual[q])
        if r != r:  # (a NaN taken into a running max is lost at the next number)
            return np.inf
        worst = max(worst, r)
    return worst / (impulse_scale(m, hf) + dmom)


@njit(cache=True, error_model="numpy")
def body_stall_ratio(bd, hf):
    """After a Newton solve with free bodies: their largest momentum residual (bd.residual at the last iterate)
    over the scale :func:`bodies_converged` holds them to without its tolerance, hf M |g| [N s] (times the radius
    of gyration for the angular part; hf [s] the step's force weight): 1 is a body's weight's impulse in the step.
    The cable's own residual (:func:`stall_ratio`) does not see it: a 1 g box tipping off the cable at 60 Hz
    ended a solve with the cable balanced and itself 22 weights' impulses off (the rows pushed 0.22 N, its
    planned motion took 0.004 N), and Bullet's update under the rows' forces threw it at 3.5 m/s. 0 without an
    active body; NaN counts as infinitely far."""
    g = math.sqrt(bd.gravity[0] ** 2 + bd.gravity[1] ** 2 + bd.gravity[2] ** 2)
    worst = 0.0
    for s in range(bd.active.shape[0]):
        if not bd.active[s]:
            continue
        m = bd.mass[s]
        lin = hf * m * g + 1e-300
        ang = lin * math.sqrt(max(bd.inertia[s, 0, 0], bd.inertia[s, 1, 1], bd.inertia[s, 2, 2]) / m) + 1e-300
        for j in range(6):
            r = abs(bd.residual[s, j]) / (lin if j < 3 else ang)
            if r != r:
                return np.inf
            worst = max(worst, r)
    return worst


@njit(cache=True, error_model="numpy")
def _end_bodies(c, bd, h):
    """After the step of h [s]: the free bodies' solved velocity is their start for a next sub-step (and h times it
    joins their travel), and each row's arm turns with the body (the points stay where the step left them)."""
    for k in range(c.count[0]):
        s = bd.slot[k]
        if s < 0:
            continue
        a0, a1, a2 = bd.arm[k, 0], bd.arm[k, 1], bd.arm[k, 2]
        w0, w1, w2 = bd.vel_new[s, 3], bd.vel_new[s, 4], bd.vel_new[s, 5]
        bd.arm[k, 0] += h * (w1 * a2 - w2 * a1)
        bd.arm[k, 1] += h * (w2 * a0 - w0 * a2)
        bd.arm[k, 2] += h * (w0 * a1 - w1 * a0)
    for s in range(bd.active.shape[0]):
        if bd.active[s]:
            for j in range(6):
                bd.vel[s, j] = bd.vel_new[s, j]
                bd.travel[s, j] += h * bd.vel_new[s, j]


@njit(cache=True, error_model="numpy")
def _dense_solve(a, b, size):
    """Solve a[:size, :size] y = b[:size] in place (Gaussian elimination with partial pivoting; a destroyed)."""
    for k in range(size):
        p = k
        for i in range(k + 1, size):
            if abs(a[i, k]) > abs(a[p, k]):
                p = i
        if p != k:
            for j in range(size):
                a[k, j], a[p, j] = a[p, j], a[k, j]
            b[k], b[p] = b[p], b[k]
        for i in range(k + 1, size):
            f = a[i, k] / a[k, k]
            if f == 0.0:
                continue
            for j in range(k, size):
                a[i, j] -= f * a[k, j]
            b[i] -= f * b[k]
    for k in range(size - 1, -1, -1):
        acc = b[k]
        for j in range(k + 1, size):
            acc -= a[k, j] * b[j]
        b[k] = acc / a[k, k]


@njit(cache=True, error_model="numpy")
def _add_holder_block(bd, hf, D):
    """D += hf hold_c (J^T n)(J^T n)^T for each holder contact that still pushes at bd.vel_new, J^T n = (n, a x n)."""
    jn = np.empty(6)
    for s in range(bd.active.shape[0]):
        if not bd.active[s]:
            continue
        for p in range(bd.hold_count[s]):
            if not _holder_change(bd, s, p, bd.vel_new)[1]:
                continue
            a, n = bd.hold_arm[s, p], bd.hold_normal[s, p]
            jn[0], jn[1], jn[2] = n[0], n[1], n[2]
            jn[3], jn[4], jn[5] = a[1] * n[2] - a[2] * n[1], a[2] * n[0] - a[0] * n[2], a[0] * n[1] - a[1] * n[0]
            k = hf * bd.hold_c[s]
            for i in range(6):
                for q in range(6):
                    D[6 * s + i, 6 * s + q] += k * jn[i] * jn[q]


@njit(cache=True, error_model="numpy")
def coupled_solve(c, bd, held, x, kx, kv, hf, band, r):
    """Newton's direction of the cable and the free bodies ``bd`` together: r (3n,) [N s] in, the cable's
    direction dv [m/s] out (in place); the bodies' direction into bd.step, from their residual bd.residual.

    The system [[A, C], [C^T, D]] with A the cable's Newton matrix (``band``, destroyed: factorised once), C
    (3n, 6S) the rows' coupling -(w G) J and D = M_b + sum J^T G J, where G = kx (-dF/dx) + kv (-dF/dv) is a
    row's 3x3 contact stiffness (normal at the closest point's weights w, friction at the anchor's) and J =
    [I, -[arm]x] maps a body's (U', Omega') to its surface point's velocity; solved by the Schur complement
    S = D - C^T A^-1 C (6S x 6S, dense). Held nodes keep their identity rows (no coupling). D also holds hf hold_c
    J^T n n^T J of each holder contact that still pushes at bd.vel_new (hf [s] the step's force weight) and the other
    cables' other_mass; bd.load_mass gets each active body's block of S less those (this cable's part).
    """
    ns = bd.active.shape[0]
    size = 6 * ns
    C, D, work = bd.coupling, bd.schur, bd.work
    C[:, :] = 0.0
    D[:, :] = 0.0
    for s in range(ns):
        for j in range(3):
            if bd.active[s]:
                D[6 * s + j, 6 * s + j] = bd.mass[s]
                for q in range(3):
                    D[6 * s + 3 + j, 6 * s + 3 + q] = bd.inertia[s, j, q]
            else:  # identity rows: a zero step
                D[6 * s + j, 6 * s + j] = 1.0
                D[6 * s + 3 + j, 6 * s + 3 + j] = 1.0
        if bd.active[s]:
            for j in range(6):
                for q in range(6):
                    D[6 * s + j, 6 * s + q] += bd.other_mass[s, j, q]
    _add_holder_block(bd, hf, D)
    for s in range(ns):  # load_mass <- minus the body's own block now, plus its block of the Schur complement below
        for j in range(6):
            for q in range(6):
                bd.load_mass[s, j, q] = -D[6 * s + j, 6 * s + q] if bd.active[s] else 0.0
    G = np.empty((2, 3, 3))
    GJ = np.empty((3, 6))
    J = np.zeros((3, 6))
    u = np.empty(3)
    wts = np.empty((2, 2))
    for k in range(c.count[0]):
        s = bd.slot[k]
        if s < 0:
            continue
        _row_blocks(c, k, x, kx, kv, u, G)
        a0, a1, a2 = bd.arm[k, 0], bd.arm[k, 1], bd.arm[k, 2]
        # J = [I, -[a]x]: -[a]x = [[0, a2, -a1], [-a2, 0, a0], [a1, -a0, 0]]
        J[0, 0], J[1, 1], J[2, 2] = 1.0, 1.0, 1.0
        J[0, 4], J[0, 5] = a2, -a1
        J[1, 3], J[1, 5] = -a2, a0
        J[2, 3], J[2, 4] = a1, -a0
        wts[0, 0], wts[0, 1] = c.weight[k, 0], c.weight[k, 1]
        wts[1, 0], wts[1, 1] = 1.0 - c.anchor[k, 3], c.anchor[k, 3]
        for p in range(2):
            for i in range(3):
                for q in range(6):
                    acc = 0.0
                    for t in range(3):
                        acc += G[p, i, t] * J[t, q]
                    GJ[i, q] = acc
            for i in range(6):  # D += J^T G J
                for q in range(6):
                    acc = 0.0
                    for t in range(3):
                        acc += J[t, i] * GJ[t, q]
                    D[6 * s + i, 6 * s + q] += acc
            for aa in range(2):  # C -= w G J on the row's nodes
                na = c.node[k, aa]
                w = wts[p, aa]
                if w == 0.0 or held[na] or (aa == 1 and na == c.node[k, 0]):
                    continue
                if aa == 0 and c.node[k, 1] == na:  # a node contact: both weights on one node
                    w = wts[p, 0] + wts[p, 1]
                for i in range(3):
                    for q in range(6):
                        C[3 * na + i, 6 * s + q] -= w * GJ[i, q]
    min_pivot = gl_band_factor(band, HALF)
    gl_band_substitute(band, r, HALF)  # r <- y = A^-1 r
    # C's columns are zero outside the rows of the nodes their body's rows touch (lo[s]..hi[s]); the sums below
    # skip those zero terms (exactly: a sum that starts at +0.0 and subtracts finite products never holds -0.0, so
    # a skipped +-0 term leaves it as it was) and the substitutions of C's columns start at the first row any of
    # them fills (the zero rows before it change nothing)
    lo, hi = _support(C, bd.active)
    first = r.shape[0]
    for s in range(ns):
        if bd.active[s]:
            first = min(first, lo[s])
    rb = bd.step  # right-hand side of the Schur system: R_b - C^T y
    for s in range(ns):
        for j in range(6):
            col = 6 * s + j
            acc = bd.residual[s, j] if bd.active[s] else 0.0
            if bd.active[s]:
                for i in range(r.shape[0]):
                    acc -= C[i, col] * r[i]
            rb[s, j] = acc
    # S = D - C^T A^-1 C: A^-1 C for every column at once (each column's operations as one substitution's, in its
    # order; the columns interleaved), then one dot product per entry over the row's support
    cols = np.empty(size, np.int64)  # the active slots' columns, in order
    m = 0
    for col in range(size):
        if bd.active[col // 6]:
            cols[m] = col
            m += 1
    W = np.empty((work.shape[0], m))
    for i in range(first, work.shape[0]):
        for q in range(m):
            W[i, q] = C[i, cols[q]]
    _substitute_columns(band, W, HALF, first)
    for q in range(m):
        col = cols[q]
        for row in range(size):
            s = row // 6
            if not bd.active[s]:
                continue
            acc = 0.0
            for i in range(lo[s], hi[s] + 1):
                acc -= C[i, row] * W[i, q]
            D[row, col] += acc
    for s in range(ns):
        if bd.active[s]:
            for j in range(6):
                for q in range(6):
                    bd.load_mass[s, j, q] += D[6 * s + j, 6 * s + q]
    flat = rb.reshape(size)
    _dense_solve(D, flat, size)
    for i in range(work.shape[0]):  # dv = y - A^-1 C d_delta
        acc = 0.0
        for col in range(size):
            acc += C[i, col] * flat[col]
        work[i] = acc
    gl_band_substitute(band, work, HALF)
    for i in range(r.shape[0]):
        r[i] -= work[i]
    return min_pivot


@njit(cache=True, error_model="numpy")
def _support(C, active):
    """First and last row (lo, hi, each (S,)) where the columns of each active body slot of C (3n, 6S) are not
    zero (lo = 3n, hi = -1: none)."""
    ns = active.shape[0]
    lo = np.full(ns, C.shape[0], np.int64)
    hi = np.full(ns, -1, np.int64)
    for i in range(C.shape[0]):
        for s in range(ns):
            if not active[s]:
                continue
            for j in range(6):
                if C[i, 6 * s + j] != 0.0:
                    lo[s] = min(lo[s], i)
                    hi[s] = i
                    break
    return lo, hi


@njit(cache=True, error_model="numpy")
def _substitute_columns(band, W, half, first):
    """Solve L U Y = W in place (W (size, m), its rows before ``first`` zero and left alone) with the factors of
    :func:`~bullet_dlo.core.kernels.gauss_legendre.gl_band_factor`: per column the operations of
    :func:`~bullet_dlo.core.kernels.gauss_legendre.gl_band_substitute`, in its order (the same numbers), the
    columns interleaved (independent chains: the substitution's back sweep is bound by the latency of its sums);
    rows before ``first`` of Y are not computed (the forward sweep leaves them zero, the back sweep's rows below
    them do not depend on them)."""
    size, m = W.shape[0], W.shape[1]
    for k in range(first, size):
        last = min(k + half, size - 1)
        for i in range(k + 1, last + 1):
            f = band[i, k - i + half]
            for q in range(m):
                W[i, q] -= f * W[k, q]
    acc = np.empty(m)
    for k in range(size - 1, first - 1, -1):
        last = min(k + half, size - 1)
        for q in range(m):
            acc[q] = W[k, q]
        for j in range(k + 1, last + 1):
            u = band[k, j - k + half]
            for q in range(m):
                acc[q] -= u * W[j, q]
        d = band[k, half]
        for q in range(m):
            W[k, q] = acc[q] / d


# ----- the implicit step with contacts ------------------------------------------------------
@njit(cache=True, error_model="numpy")
def _update_friction(c, x_end):
    """After the step: stick or slide by the final normal force; the anchors of sliding contacts follow."""
    u = np.empty(3)
    gw = np.empty(12)
    hw = np.empty((12, 12))
    for k in range(c.count[0]):
        a, b = c.node[k, 0], c.node[k, 1]
        if c.kind[k] == WRAP:
            c.cap[k] = max(c.cap[k], _wrap_cap(c, k, x_end))
            active, _, _, _, _, slip, split, _ = _wrap_eval(c, k, x_end, gw, hw, False)
            if not active:  # the chord is clear of the edge: the split that a new wrap starts from
                c.anchor[k, 0] = _arc_middle(c, k, x_end)[0]
                c.anchor[k, 3] = split
                c.state[k] = STICK
                continue
            if slip == 0.0:
                c.state[k] = STICK
            else:  # the material slid over the edge: the anchor follows
                c.state[k] = SLIDE
                sig = c.anchor[k, 3] + slip / c.seg[k, 1]
                c.anchor[k, 3] = min(max(sig, SIGMA_MIN), 1.0 - SIGMA_MIN)
            _recentre_wrap(c, k, x_end)
            continue
        ul = _slip(c, k, x_end, u)
        kt = c.k_t[k]
        mu_now = c.static_friction[k] if c.state[k] == STICK else c.dynamic_friction[k]
        cap_final = max(c.cap[k], mu_now * max(c.f_n[k], 0.0))
        if kt * ul <= cap_final * (1.0 + 1e-6):
            c.state[k] = STICK
            for j in range(3):  # a flat section: the slip in the next step's terms, whose turn starts from here
                c.anchor[k, j] -= c.support[k, 6 + j]
        else:
            c.state[k] = SLIDE
            capd = c.dynamic_friction[k] * max(c.f_n[k], 0.0)
            wb = c.weight[k, 1]
            c.anchor[k, 3] = wb if a != b else 0.0
            for j in range(3):
                p = c.weight[k, 0] * x_end[a, j] + wb * x_end[b, j]
                c.anchor[k, j] = p - (capd / kt) * u[j] / ul


@njit(cache=True, error_model="numpy")
def _step_work(m, v, h, c):
    """After a contact step's solve (v [m/s]: the velocities at the step's start): c.impact, and the work of the
    bodies and the grippers on the cable over the step added to c.body_work [J]."""
    gr = c.grip
    g_h = math.sqrt(m.gravity[0] ** 2 + m.gravity[1] ** 2 + m.gravity[2] ** 2) * h
    c.impact[0] = 0
    for k in range(c.count[0]):
        if c.kind[k] != WRAP and c.f_n[k] > 0.0 and -_approach(c, k, v) > g_h:
            c.impact[0] = 1
        for j in range(3):  # work of the body on the cable: f . u_b h (self-contact: internal, not counted)
            if not c.internal[k]:
                c.body_work[0] += (c.f_n[k] * c.normal[k, j] + c.f_t[k, j]) * c.body_vel[k, j] * h
    for e in range(2):  # work of the grippers on the cable
        if gr.active[e]:
            for j in range(3):
                c.body_work[0] += gr.force[e, j] * gr.vel[e, j] * h


@njit(cache=True, error_model="numpy")
def felt_forces(c, held, r, hf, slot, bodies):
    """After a Newton solve that ended unconverged: each row's force (c.f_n, c.f_t, a wrap row's c.normal) becomes
    the force the cable's accepted step felt from it, so that its reaction (on the body, in ``contact_forces()``)
    balances the cable's momentum change. r (3n,) [N s]: the solve's residual at the accepted iterate, hf F -
    M (v' - v_avg) (0 on held nodes): node i felt hf F_i - r_i, so the contacts at i felt their forces minus
    r_i / hf [N], shared among the rows at node i by their weight there (a penalty row its closest point's
    weights, a wrap row 1 at each of its two nodes). A node without a row keeps its residual (none on the edge
    slide: docs/concepts/integrators.md, "A stalled contact step"). A penalty row's normal force stays >= 0 and
    its friction takes the rest (normal part too), a wrap row's push is the felt force's size and direction.
    Rows on a free body solved with the cable (``bodies`` > 0 and ``slot`` (M,) >= 0) keep their force: the body's
    velocity was solved with it, so its momentum balances that force (another impulse would move the body
    other than the step planned). ``bodies`` 0: they are felt too (a wildly far solve, :func:`contact_step`)."""
    nc = c.count[0]
    n = r.shape[0] // 3
    wsum = np.zeros(n)
    for k in range(nc):
        if bodies > 0 and slot[k] >= 0:
            continue
        w0 = 1.0 if c.kind[k] == WRAP else c.weight[k, 0]
        w1 = 1.0 if c.kind[k] == WRAP else c.weight[k, 1]
        wsum[c.node[k, 0]] += w0
        wsum[c.node[k, 1]] += w1
    d = np.empty(3)
    for k in range(nc):
        if bodies > 0 and slot[k] >= 0:
            continue
        d[:] = 0.0
        for e in range(2):
            i = c.node[k, e]
            w = 1.0 if c.kind[k] == WRAP else c.weight[k, e]
            if w > 0.0 and wsum[i] > 0.0 and not held[i]:
                for j in range(3):
                    d[j] -= (w / wsum[i]) * r[3 * i + j] / hf
        if c.kind[k] == WRAP:
            f2 = 0.0
            for j in range(3):
                d[j] += c.f_n[k] * c.normal[k, j]
                f2 += d[j] * d[j]
            fn = math.sqrt(f2)
            c.f_n[k] = fn
            if fn > 0.0:
                for j in range(3):
                    c.normal[k, j] = d[j] / fn
            continue
        fn = 0.0
        for j in range(3):
            d[j] += c.f_n[k] * c.normal[k, j] + c.f_t[k, j]
            fn += d[j] * c.normal[k, j]
        fn = max(fn, 0.0)
        c.f_n[k] = fn
        for j in range(3):
            c.f_t[k, j] = d[j] - fn * c.normal[k, j]


@njit(cache=True, error_model="numpy")
def contact_step(stepper, m, x, v, samples, ws, has_prev, c, bd):
    """One implicit step of (x, v) in place with the contacts ``c`` and the free bodies ``bd`` (:class:`Bodies`;
    see the module docstring).

    Like :func:`~bullet_dlo.core.kernels.steppers.advance` for the implicit methods (implicit
    midpoint takes an implicit Euler step while contacts are active). A cable with a material frame solves
    positions and twist in one Newton system (:func:`~bullet_dlo.core.kernels.twist_coupled.coupled_contact`)
    unless a free body is in the solve: then the positions with the twist held, then the twist sub-step
    (staggered, first order). Updates the friction state and c.body_work; sets c.impact. Returns (Newton
    iterations, converged).
    """
    method, h = stepper.method, stepper.h
    n = x.shape[0]
    if method == IMPLICIT_MIDPOINT:
        method = IMPLICIT_EULER
    # surface points and anchors on moving bodies: at the end of the step (where forces are evaluated); free
    # bodies (bd) move with the step's solve, by backward Euler: the step is then implicit Euler for the
    # cable too (BDF2 keeps its history), so that cable and body share one incremental potential
    if bd.active.shape[0] > 0:
        bodies = start_bodies(c, bd, h)
    else:  # no free body in the world: nothing to keep for them (the same moves as start_bodies')
        bodies = 0
        for k in range(c.count[0]):
            for j in range(3):
                c.point[k, j] += h * c.body_vel[k, j]
                c.anchor[k, j] += h * c.body_vel[k, j]
    use_prev = has_prev and method == BDF2 and bodies == 0
    twisting = has_twist(m)
    if twisting:  # as advance does
        twist_ready(m, x, samples.dir[0])
        set_clamp(m, 2)  # (implicit Euler and BDF2 evaluate at t + h)
        start_support(c, m, x, samples.dir[0])  # a flat section's rows: their turn is counted from here
    gr = c.grip
    if twisting and bodies == 0:  # positions and twist in one Newton system
        for e in range(2):  # the grippers at the end of the step (where forces are evaluated)
            for j in range(3):
                gr.center[e, j] = samples.pos[2, e, j]
                gr.axis[e, j] = samples.dir[2, e, j]
                gr.vel[e, j] = samples.vel[2, e, j]
        v0 = v.copy()
        its, converged = _twist_coupled.coupled_contact(stepper, method, m, x, v, samples, ws, use_prev, c)
        _step_work(m, v0, h, c)
        _update_friction(c, x)  # contact points stay at the end of the step: the next step's start
        _update_grips(gr, x)
        return its, converged
    imp = _start_implicit(method, m, x, v, h, samples, ws, use_prev)
    vn = ws.v_new
    for e in range(2):  # the grippers at the end of the step (where forces are evaluated)
        for j in range(3):
            gr.center[e, j] = samples.pos[2, e, j]
            gr.axis[e, j] = samples.dir[2, e, j]
            gr.vel[e, j] = samples.vel[2, e, j]
    its, converged = newton(stepper, m, x, imp, ws, c, 1e-3, 10, bd)
    _step_work(m, v, h, c)
    for i in range(n):
        for j in range(3):
            if use_prev:
                x[i, j] = ws.x_base[i, j] + imp.cx * vn[i, j]
            else:
                x[i, j] += h * vn[i, j]
    v[:, :] = vn
    _set_held(m.held, x, v, samples.pos[2], samples.vel[2])
    _update_friction(c, x)  # contact points stay at the end of the step: the next step's start
    _update_grips(gr, x)
    felt_bodies = False
    if not converged:  # the rows' forces the accepted step felt (the cable's step, friction and work as solved)
        # wildly far: the rows on the free bodies too. The body's velocity balances their forces at the last
        # iterate, but the cable's nodes there do not (a 20 g part on a cord at 120 Hz, kept at 67 times gravity's
        # impulse, was launched at 0.8 m/s and 66 rad/s); the cable's felt reaction is what its motion supports
        felt_bodies = bodies > 0 and stall_ratio(m, ws, imp.hf) > bd.felt_ratio[0]
        felt_forces(c, m.held, ws.residual, imp.hf, bd.slot, 0 if felt_bodies else bodies)
    if bodies > 0:
        _add_reactions(c, bd, h, bd.impulse)
        if felt_bodies:
            _bodies_under_reactions(c, bd, h)
        _end_bodies(c, bd, h)
    if twisting:  # with a free body in the solve: the staggered twist sub-step
        if method == BDF2:  # (the history of a coupled BDF2 step after this one)
            m.tw_prev[0, :] = m.tw_theta
            m.tw_prev[1, :] = m.tw_omega
        twist_step(m, x, samples.dir[2], h)
    return its, converged


# The coupled step of a twisting cable (twist_coupled imports this module: bound after every name it takes)
from bullet_dlo.core.kernels import twist_coupled as _twist_coupled  # noqa: E402
