"""``bullet_dlo/Routing-v0``: route a cable around vertical pegs and press it into a clip.

The left gripper holds its end fixed (it never moves); the right gripper routes the cable. At
reset (after the cable settled straight between the grippers, at ``hold_height`` above the
floor, the table top at ``table_height`` below) 1 or 2 pegs (vertical cylinders, radius
``PEG_RADIUS`` 1.5 cm, ``PEG_HEIGHT`` 0.25 m tall, standing on the table: taller than any
gripper height, so the cable always meets their sides) and a clip (two boxes on the table with
a slot of width ``CLIP_GAP`` 2.4 cm between them, ``CLIP_HEIGHT`` 9 cm tall, open at the top)
are drawn from the reset seed as a **route**: a path that leaves the fixed end A, passes each
peg on its required side and turns around it toward it by 20-40 deg (side +1: the peg on the
cable's left, walking from the fixed end, the cable turns counter-clockwise seen from above;
side -1: clockwise), then runs straight through the clip's slot (the slot's axis is the route's
last direction). All pegs of a route share one side, and the straight cable at reset already
passes each peg on that side, so sweeping the cable toward it wraps the pegs in turn. Draw
ranges (L the cable length, A = (-L/2, 0) the fixed end): the count 1 or 2 (equally likely);
peg 1 at x - A_x in [0.4, 0.55] L, |y| in [3, 6] cm; each further peg, and the clip, 8-12 cm on
along the route, the next peg touching the route's line. Rules (a draw breaking one is redrawn,
at most 200 times, then ParameterError): pegs 3 cm and the clip 4 cm (in y) off the straight
cable, all on the table (|x| <= L/2 - 8 cm, |y| <= 25 cm) and 8 cm apart; the route from A to
the clip at most 0.85 L, its last direction within 80 deg of +x; the gripper's end point (on
the clip's axis where the route with 97 % of the cable ends) at x in [-0.1, L/2 + 0.05] m,
|y| <= 0.22 m (inside the Panda's reach: IK reaches x >= -0.15 m, |y| <= 0.25 m at 5-10 cm
above the table for yaws up to 90 deg, checked on a grid) and 6 cm from pegs and clip. The
scene is laid out for the Panda: the KUKA cannot reach its holds (resets with ``robot: kuka`` are
refused as unreachable poses).

**Action** (4,) in [-1, 1]: the right gripper's linear velocity (xyz, world, fraction of
``max_speed`` [m/s]) and yaw rate about the vertical (fraction of ``max_yaw_rate`` [rad/s]);
clipped. The target stays in an absolute box: x in [-0.1 m, L/2 + 0.05 m], |y| <= 0.25 m,
z from 5 cm to 18 cm above the table (the held end never comes closer than 5 cm to it), yaw
within +-90 deg of its start. The left gripper holds still (its arm keeps its pose).

**Progress measures** (from the cable's own node positions, no sensors):

* wrap angle of peg k [rad]: the signed turning of the cable (seen from above, counter-clockwise
  positive) at the nodes next to a segment within ``radius + cable radius + WRAP_MARGIN`` of the
  peg's axis, below its top: the capstan angle. A straight cable passing the peg: 0; a cable
  bent half around it: pi. Peg k is **wrapped** when side_k x wrap_k >= ``WRAP_MIN`` (15 deg).
* clip distance [m]: the smallest distance from the cable (points every 5 mm along it) to the
  slot's centre segment (its axis between the boxes' ends, at the boxes' mid-height); the cable
  is **threaded** when a point lies inside the slot: along the axis within the boxes' length,
  across it within the gap, below the boxes' top.

``task`` (19,) = per peg slot k = 1, 2: [present (0/1), x, y [m], side (+-1), side_k wrap_k
[rad], gap between cable and peg surface [m]] (an absent peg: zeros), then the clip: [x, y [m],
top z [m], cos yaw, sin yaw, clip distance [m], threaded (0/1)].

**Reward** per step: 0.5 P + 0.5 W exp(-d / 3 cm) - 0.05 max(0, F - ``force_soft``), with P =
mean over pegs of min(p_1, ..., p_k), p_j = clip(side_j wrap_j / WRAP_MIN, 0, 1) (each peg counts
only as much as the pegs before it: the route in order), W = 1 when every peg is wrapped else 0,
d the clip distance [m], F [N] the larger of the two cable end forces (the cable model's, the
truth the wrist sensors read). **Success** (``info["is_success"]``): every peg wrapped and the
cable threaded: +10 on that step and the episode terminates. **Termination** also on overload
(F > ``overload`` [N], ``info["overload"]``: a real cell would stop) and on instability.
``info`` also has ``wraps`` (side x wrap per peg [rad]), ``clip_distance`` [m], ``threaded``,
``end_force`` [N].

**Randomisation** (``default_randomisation``): Panda arms, a soft cord 0.6 m long, 6 mm thick
(mass 20-40 g, Young's modulus 1e7-3e7 Pa log-uniform, 35 masses, friction 0.5), held
0.27-0.30 m above the floor (table top 0.2 m); the pegs and clip as above. The masses are the fewest whose
segments are shorter than the slot's free width (:func:`slot_masses`); a randomisation with fewer is refused.
A baseline that uses the observation only: :class:`RoutingPolicy` (taut-string waypoints).
"""
from __future__ import annotations

import functools
import itertools
import math
from typing import Any

import numpy as np
from gymnasium import spaces

from bullet_dlo.analysis.resolve import passage_masses
from bullet_dlo.bullet.world import add_obstacles
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.envs import params
from bullet_dlo.envs.dual_arm_env import DualArmEnv, _clip
from bullet_dlo.robots.transforms import quat_from_axes, rotation

MAX_PEGS = 2
PEG_RADIUS, PEG_HEIGHT = 0.015, 0.25  # [m] tall: the cable passes below the top at every gripper height
CLIP_GAP, CLIP_LENGTH, CLIP_WIDTH, CLIP_HEIGHT = 0.024, 0.03, 0.016, 0.09  # [m] slot width, box sizes
FRICTION = 0.6  # pegs' and clip's lateral friction
WRAP_MIN = math.radians(15.0)  # [rad] a peg counts as wrapped
WRAP_MARGIN = 0.01  # [m] beyond contact: segments this close to a peg count toward its wrap
FIRST_PEG_X, FIRST_PEG_Y = (0.4, 0.55), (0.03, 0.06)  # [L], [m] first peg from the fixed end, off the cable
TURN_RANGE = (math.radians(20.0), math.radians(40.0))  # [rad] turn of the drawn route at each peg
HOP_RANGE = (0.08, 0.12)  # [m] route length between pegs, and from the last peg to the clip
ROUTE_SHARE = 0.85  # the route up to the clip uses at most this share of the cable length
# layouts drawn before a reset gives up: two-peg layouts pass the rules in about 2.6 % of draws (0.6 m cable), so
# 200 draws failed 0.55 % of two-peg resets (a check_env that raised now and then); 5000 draws fail with odds of
# e^-130 and cost about 0.4 s when no layout exists (a cable too short: the error names its length)
MAX_DRAWS = 5000
POINT_SPACING = 0.005  # [m] of the points the clip tests sample along the cable
CLIP_SCALE = 0.03  # [m] reward scale of the clip distance
FORCE_PENALTY = 0.05  # per N above force_soft
SUCCESS_BONUS = 10.0
Z_MIN, Z_MAX = 0.05, 0.18  # [m] right gripper target above the table top
REACH = (-0.1, 0.05, 0.22)  # [m] right gripper's route end: smallest x, largest x beyond L/2, largest |y|
TASK_DIM = 6 * MAX_PEGS + 7


def left_normal(u: np.ndarray) -> np.ndarray:
    """The xy unit vector 90 deg counter-clockwise of ``u`` (2,)."""
    return np.array([-u[1], u[0]])


def unit(angle: float) -> np.ndarray:
    """The xy unit vector at ``angle`` [rad] from +x."""
    return np.array([math.cos(angle), math.sin(angle)])


def segment_distances(points: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Distance [m] in xy from ``centre`` (2,) to each segment of the polyline ``points`` (n, >= 2): (n - 1,)."""
    p = points[:, :2] - centre[:2]
    seg = np.diff(p, axis=0)
    length2 = np.maximum(np.einsum("ij,ij->i", seg, seg), 1e-18)
    t = np.clip(-np.einsum("ij,ij->i", p[:-1], seg) / length2, 0.0, 1.0)
    return np.linalg.norm(p[:-1] + t[:, None] * seg, axis=1)


def segment_distances_many(points: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """:func:`segment_distances` from each of ``centres`` (k, 2) at once, (k, n - 1): row i has the bits of
    ``segment_distances(points, centres[i])``: the same products and sums per element, broadcast over the centres,
    written out (einsum's and norm's sums of two terms are x0 + x1 too; a projection t of -0.0 instead of 0.0
    moves no point), a third of the cost after a physics step (einsum, clip and norm wrappers dominated)."""
    p = points[None, :, :2] - np.asarray(centres, dtype=float)[:, None, :2]
    a = p[:, :-1]
    seg = p[:, 1:] - a
    sx, sy = seg[..., 0], seg[..., 1]
    length2 = np.maximum(sx * sx + sy * sy, 1e-18)
    t = _clip(-(a[..., 0] * sx + a[..., 1] * sy) / length2, 0.0, 1.0)
    q = a + t[:, :, None] * seg
    q *= q
    return np.sqrt(q[..., 0] + q[..., 1])


def wrap_angles(x: np.ndarray, distances: np.ndarray, band: float, top: float = math.inf) -> list[float]:
    """:func:`wrap_angle` around several pegs at once, given the cable's xy segment distances from each peg's axis
    ``distances`` (k, n - 1) [m] (:func:`segment_distances_many`): the turning at the nodes is computed once.
    The same numbers as ``wrap_angle`` peg by peg."""
    xy = x[:, :2]
    seg = xy[1:] - xy[:-1]
    below = np.maximum(x[:-1, 2], x[1:, 2]) < top
    a, b = seg[:-1], seg[1:]
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    turn = np.arctan2(cross, np.einsum("ij,ij->i", a, b))  # at nodes 1 .. n-2
    out = []
    for d in distances:
        near = (d < band) & below
        out.append(float(turn[near[:-1] | near[1:]].sum()))
    return out


def wrap_angle(x: np.ndarray, centre: np.ndarray, band: float, top: float = math.inf) -> float:
    """Signed wrap angle [rad] of the cable ``x`` (n, 3) [m] around a vertical peg at ``centre`` (xy) [m]:
    the turning of its xy direction (counter-clockwise positive) at every node next to a segment that
    passes within ``band`` [m] of the axis with both ends below ``top`` [m] (the capstan angle)."""
    seg = np.diff(x[:, :2], axis=0)
    near = (segment_distances(x, centre) < band) & (np.maximum(x[:-1, 2], x[1:, 2]) < top)
    cross = seg[:-1, 0] * seg[1:, 1] - seg[:-1, 1] * seg[1:, 0]
    turn = np.arctan2(cross, np.einsum("ij,ij->i", seg[:-1], seg[1:]))  # at nodes 1 .. n-2
    return float(turn[near[:-1] | near[1:]].sum())


def resample(x: np.ndarray, spacing: float = POINT_SPACING) -> np.ndarray:
    """Points along the polyline ``x`` (n, 3) no further apart than ``spacing`` [m] (the nodes included).

    Segment a -> b gets k = ceil(|b - a| / spacing) points a + (j / k)(b - a), j = 1 .. k, at most 100 a
    segment (a torn cable is long, not detailed); vectorised (the same arithmetic as :func:`resample_loop`), with
    a shorter path when every segment gets the same k (a cable near its rest length: nearly every Routing step).
    """
    d = x[1:] - x[:-1]
    k = np.minimum(100, np.maximum(1, np.ceil(np.sqrt(np.einsum("ij,ij->i", d, d)) / spacing))).astype(np.int64)
    k0 = int(k[0]) if len(k) else 0
    if k0 and not (k != k0).any():  # one k: the points of segment a are x_a + t_j d_a with t_j = j / k
        t = _fractions(k0)
        points = (x[:-1, None, :] + t[None, :, None] * d[:, None, :]).reshape(-1, 3)
        return np.concatenate([x[:1], points])
    seg = np.repeat(np.arange(len(d)), k)
    j = np.arange(len(seg)) - np.repeat(np.cumsum(k) - k, k) + 1  # 1 .. k within each segment
    t = j / k[seg]
    return np.concatenate([x[:1], x[:-1][seg] + t[:, None] * d[seg]])


@functools.lru_cache(maxsize=128)
def _fractions(k: int) -> np.ndarray:
    """j / k for j = 1 .. k (the bits of an int64 array divided by k), read-only."""
    t = np.arange(1, k + 1) / np.int64(k)
    t.flags.writeable = False
    return t


def resample_loop(x: np.ndarray, spacing: float = POINT_SPACING) -> np.ndarray:
    """:func:`resample` segment by segment in Python (the reference it is tested against)."""
    out = [x[:1]]
    for a, b in itertools.pairwise(x):
        k = min(100, max(1, math.ceil(np.linalg.norm(b - a) / spacing)))
        out.append(a + np.outer(np.arange(1, k + 1) / k, b - a))
    return np.concatenate(out)


class Clip:
    """A slot between two boxes standing on the table: centre (xy) [m], axis yaw [rad], top z [m]."""

    def __init__(self, centre: np.ndarray, yaw: float, top: float):
        self.centre = np.asarray(centre, dtype=float)[:2]
        self.yaw = float(yaw)
        self.top = float(top)
        self.axis = unit(self.yaw)
        self.across = left_normal(self.axis)

    def local(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Coordinates [m] of ``points`` (m, >= 2) along the slot axis and across it, from the centre."""
        d = points[:, :2] - self.centre
        return d @ self.axis, d @ self.across

    def threaded(self, x: np.ndarray, points: np.ndarray | None = None) -> bool:
        """A point of the cable ``x`` (n, 3) inside the slot: within the boxes' length, between them, below their top.
        ``points``: ``resample(x)`` if the caller has it."""
        return self.measure(x, points)[1]

    def distance(self, x: np.ndarray, points: np.ndarray | None = None) -> float:
        """Smallest distance [m] from the cable ``x`` (n, 3) to the slot's centre segment (axis, mid-height).
        ``points``: ``resample(x)`` if the caller has it."""
        return self.measure(x, points)[0]

    def measure(self, x: np.ndarray, points: np.ndarray | None = None) -> tuple[float, bool]:
        """(:meth:`distance` [m], :meth:`threaded`) of the cable ``x`` (n, 3), the points' slot coordinates
        computed once. ``points``: ``resample(x)`` if the caller has it."""
        p = resample(x) if points is None else points
        along, across = self.local(p)
        abs_along, z = np.abs(along), p[:, 2]
        da = np.maximum(abs_along - 0.5 * CLIP_LENGTH, 0.0)
        dz = z - (self.top - 0.5 * CLIP_HEIGHT)
        # the root of the smallest square: the smallest root (sqrt is monotonic and correctly rounded)
        distance = float(np.sqrt((da * da + across * across + dz * dz).min()))
        within = abs_along <= 0.5 * CLIP_LENGTH  # (most steps no point is level with the clip: done)
        return distance, bool(within.any() and (within & (np.abs(across) < 0.5 * CLIP_GAP) & (z < self.top)).any())

    def obstacles(self) -> list[dict]:
        """The two boxes as ``bullet.obstacles`` entries."""
        half = (0.5 * CLIP_LENGTH, 0.5 * CLIP_WIDTH, 0.5 * CLIP_HEIGHT)
        quat = [0.0, 0.0, math.sin(0.5 * self.yaw), math.cos(0.5 * self.yaw)]
        out = []
        for sign in (-1.0, 1.0):
            xy = self.centre + sign * (0.5 * CLIP_GAP + 0.5 * CLIP_WIDTH) * self.across
            out.append({"type": "box", "half_extents": half, "position": [*xy, self.top - 0.5 * CLIP_HEIGHT],
                        "orientation": quat, "friction": FRICTION, "name": f"clip_{'rl'[sign > 0]}"})
        return out


def tangent_direction(start: np.ndarray, centre: np.ndarray, radius: float, side: float) -> np.ndarray:
    """Unit xy direction from ``start`` of the line that touches the circle (``centre``, ``radius``) [m]
    with the circle on its left (``side`` +1) or right (-1)."""
    v = centre - start
    d = float(np.linalg.norm(v))
    beta = math.asin(min(1.0, radius / max(d, 1e-9)))
    c, s = math.cos(-side * beta), math.sin(-side * beta)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]]) / d


class Route:
    """A drawn route: the fixed end ``start`` (xy) [m], pegs (k, 2) [m] with ``sides`` (+-1) and turn angles
    [rad], the points where the route meets and leaves each peg, the clip, the cable ``length`` [m]."""

    def __init__(self, start: np.ndarray, pegs: np.ndarray, sides: np.ndarray, turns: np.ndarray, clip_hop: float,
                 radius: float, length: float, clip_top: float):
        self.start, self.pegs, self.sides, self.turns = start, pegs, sides, turns
        self.radius, self.length = radius, length
        self.entries, self.exits, self.directions = [], [], []
        point, used = start, 0.0
        for peg, side, turn in zip(pegs, sides, turns):
            u_in = tangent_direction(point, peg, radius, side)
            entry = peg - side * radius * left_normal(u_in)
            u_out = np.array([[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]]) @ u_in
            exit_ = peg - side * radius * left_normal(u_out)
            used += float(np.linalg.norm(entry - point)) + radius * abs(turn)
            self.entries.append(entry)
            self.exits.append(exit_)
            self.directions.append(u_out)
            point = exit_
        self.clip = Clip(point + clip_hop * self.directions[-1], math.atan2(*self.directions[-1][::-1]), clip_top)
        self.used = used + clip_hop  # [m] of cable from the fixed end to the clip's centre


def draw_route(rng: np.random.Generator, start: np.ndarray, length: float, table_top: float, radius: float,
               reach: tuple[float, float, float]) -> Route:
    """A route (see the module doc) from ``rng``; ``radius`` [m]: the peg's plus the cable's; ``reach``:
    (x_min, x_max, |y| max) [m] of the right gripper beyond the clip. ParameterError after MAX_DRAWS misses."""
    half = 0.5 * length
    count = int(rng.integers(1, MAX_PEGS + 1))  # drawn once: the layout rules must not bias the count
    for _ in range(MAX_DRAWS):
        route = draw_layout(rng, count, start, length, table_top, radius)
        if _route_ok(route, half, reach):
            return route
    raise ParameterError(f"no routing scene met the layout rules in {MAX_DRAWS} draws (cable length {length} m)")


def draw_layout(rng: np.random.Generator, count: int, start: np.ndarray, length: float, table_top: float,
                radius: float) -> Route:
    """One draw of a route with ``count`` pegs, before the layout rules (:func:`draw_route`'s arguments)."""
    sides = np.full(count, rng.choice([-1.0, 1.0]))  # one side: a sweep toward it wraps the pegs in turn
    first = np.array([start[0] + rng.uniform(*FIRST_PEG_X) * length, sides[0] * rng.uniform(*FIRST_PEG_Y)])
    turns = sides * rng.uniform(*TURN_RANGE, size=count)
    hops = rng.uniform(*HOP_RANGE, size=count)
    pegs = [first]
    for k in range(1, count):  # the next peg touches the route's line after the previous peg, on its side
        partial = Route(start, np.array(pegs), sides[:k], turns[:k], hops[k - 1], radius, length, 0.0)
        u = partial.directions[-1]
        pegs.append(partial.exits[-1] + hops[k - 1] * u + sides[k] * radius * left_normal(u))
    return Route(start, np.array(pegs), sides, turns, hops[-1], radius, length, table_top + CLIP_HEIGHT)


def _route_ok(route: Route, half: float, reach: tuple[float, float, float]) -> bool:
    """The layout rules of the module doc."""
    things = [*route.pegs, route.clip.centre]
    clear = [0.03] * len(route.pegs) + [0.04]  # [m] from the straight cable at reset: pegs, clip
    if any(abs(p[1]) < c or abs(p[0]) > half - 0.08 or abs(p[1]) > 0.25 for p, c in zip(things, clear)):
        return False  # off the table, or where the straight cable lies at reset
    if any(p[1] * s <= 0.0 for p, s in zip(route.pegs, route.sides)):
        return False  # the straight cable must start on each peg's required side: sweeps then never cross a peg
    if any(np.linalg.norm(a - b) < 0.08 for i, a in enumerate(things) for b in things[i + 1:]):
        return False
    if route.used > ROUTE_SHARE * route.length or abs(route.clip.yaw) > math.radians(80.0):
        return False
    end = route.clip.centre + (route.length * 0.97 - route.used) * route.clip.axis  # the gripper, cable nearly taut
    x_min, x_max, y_max = reach
    return x_min <= end[0] <= x_max and abs(end[1]) <= y_max and all(np.linalg.norm(end - p) > 0.06 for p in things)


def slot_masses(length: float, diameter: float) -> int:
    """The fewest masses of a cable ``length`` [m] long and ``diameter`` [m] thick whose segments are shorter than
    the clip slot's free width (``CLIP_GAP`` less the diameter; resolve's passage floor): a longer straight segment
    turned across the slot spans it wall to wall and wedges there like a stick in a channel, which the real cable
    would bend out of (at n 20, 31.6 mm segments in the 18 mm free width: 0.4-1.1 kN on both boxes and the contact
    solve stalled, or not, with a change of Newton's tolerance)."""
    return passage_masses(length, diameter, CLIP_GAP)


LENGTH, DIAMETER = 0.6, 0.006  # [m] the default cable


class RoutingEnv(DualArmEnv):
    """Cable routing around pegs into a clip (see the module doc); arguments of :class:`DualArmEnv` plus:

    max_yaw_rate [rad/s] of a full yaw action, in (0, 10]; force_soft [N]: end force above which the
    reward is cut, in (0, 1000]; overload [N]: end force that ends the episode, in (0, 1000]. All checked
    at construction, before the base's (:mod:`~.params`: ParameterError). ``max_speed`` defaults to
    0.1 m/s here; ``workspace`` is checked but not used (the right gripper's box is absolute, see the module doc).
    """

    task_dim = TASK_DIM
    default_randomisation = {
        "sample": {
            "robot": {"dist": "fixed", "value": "panda"},
            "length": {"dist": "fixed", "value": LENGTH},
            "diameter": {"dist": "fixed", "value": DIAMETER},
            "mass": {"dist": "uniform", "low": 0.02, "high": 0.04},
            "youngs_modulus": {"dist": "log_uniform", "low": 1.0e7, "high": 3.0e7},
            "n_masses": {"dist": "fixed", "value": slot_masses(LENGTH, DIAMETER)},  # 35: 17.6 mm segments
            "damping": {"dist": "uniform", "low": 0.01, "high": 0.03},
            "dynamic_friction": {"dist": "fixed", "value": 0.5},
            "static_friction": {"dist": "fixed", "value": 0.5},  # (before 0.4: the default 0.3, below the dynamic)
            "hold_height": {"dist": "uniform", "low": 0.27, "high": 0.30},
        }
    }

    def __init__(self, *args, max_speed: float = 0.1, max_yaw_rate: float = 1.0, force_soft: float = 5.0,
                 overload: float = 30.0, **kwargs):
        self.max_yaw_rate = params.number("max_yaw_rate", max_yaw_rate)
        self.force_soft = params.number("force_soft", force_soft)
        self.overload = params.number("overload", overload)
        super().__init__(*args, max_speed=max_speed, **kwargs)
        self._check_slot_resolution()

    def _check_slot_resolution(self) -> None:
        """Refuse (ParameterError) a randomisation that can draw a cable whose segments wedge across the clip's slot
        (:func:`slot_masses`), and ``n_masses: auto`` (its convergence test runs without the task's obstacles)."""
        r = self.randomisation
        masses, length, diameter = r.support("n_masses"), r.support("length"), r.support("diameter")
        need = slot_masses(length[1], diameter[1])
        got = "auto" if masses is None else f"{masses[0]:g}"
        if masses is None or masses[0] < need:
            raise ParameterError(
                f"n_masses must be a number >= {need} for Routing-v0's cable (up to {length[1]} m long, {diameter[1]} "
                f"m thick), got {got}: longer segments wedge across the clip's {CLIP_GAP} m slot")

    # ----- action -----------------------------------------------------------------------------------
    def _action_space(self) -> spaces.Box:
        return spaces.Box(-1.0, 1.0, (4,), np.float32)

    def _apply_action(self, a: np.ndarray) -> None:
        """Right gripper: velocity (3 values) and yaw rate (1) over one control period, kept in its box."""
        a = a.reshape(4)
        self.target[1] = _clip(self.target[1] + a[:3] * self.max_speed * self.control_dt, self._box[0], self._box[1])
        yaw = float(self.yaw + a[3] * self.max_yaw_rate * self.control_dt)  # finite: the action is clean
        self.yaw = min(max(yaw, -0.5 * math.pi), 0.5 * math.pi)  # np.clip of a finite number
        self._quat[1] = self.grasp_quat(self.yaw)

    @staticmethod
    def grasp_quat(yaw: float) -> np.ndarray:
        """Right grasp frame for a cable end direction at ``yaw`` [rad]: z down, x pointing into the cable."""
        return quat_from_axes((-math.cos(yaw), -math.sin(yaw), 0.0), (0.0, 0.0, -1.0))

    # ----- the scene --------------------------------------------------------------------------------
    def _task_reset(self, rng: np.random.Generator) -> None:
        setup = self.physics.spec
        table, length = setup.table_height, setup.cable.length
        self.yaw = 0.0
        self.target[0] = self.home[0]
        half = 0.5 * length
        self._box = (np.array([REACH[0], -0.25, table + Z_MIN]), np.array([half + REACH[1], 0.25, table + Z_MAX]))
        self.cable_radius = 0.5 * setup.cable.diameter
        self.route = draw_route(rng, self.home[0, :2], length, table, PEG_RADIUS + self.cable_radius,
                                (REACH[0], half + REACH[1], REACH[2]))
        self.peg_top = table + PEG_HEIGHT
        pegs = [{"type": "cylinder", "radius": PEG_RADIUS, "height": PEG_HEIGHT,
                 "position": [*p, table + 0.5 * PEG_HEIGHT], "friction": FRICTION, "name": f"peg_{k}"}
                for k, p in enumerate(self.route.pegs)]
        self.task_obstacles = pegs + self.route.clip.obstacles()
        add_obstacles(self.physics.world, self.task_obstacles)
        self._measures = None

    # ----- measures ---------------------------------------------------------------------------------
    def wraps(self, x: np.ndarray | None = None) -> np.ndarray:
        """side_k x wrap angle of peg k [rad] for the cable ``x`` (n, 3) (default: now): (pegs,)."""
        x = self.physics.cable.x if x is None else x
        band = PEG_RADIUS + self.cable_radius + WRAP_MARGIN
        return np.array([s * wrap_angle(x, p, band, self.peg_top) for p, s in zip(self.route.pegs, self.route.sides)])

    def measures(self) -> dict[str, Any]:
        """This step's progress measures (computed once per step): wraps [rad], gaps [m], clip distance [m],
        threaded, end force [N]."""
        world = self.physics.world
        if self._measures is not None and self._measures["time"] == world.time:
            return self._measures
        x = self.physics.cable.x  # read only here
        if not np.isfinite(x).all():  # an unstable step: the episode ends, the measures stay finite
            x = np.nan_to_num(x)
        route = self.route
        distances = segment_distances_many(x, route.pegs)  # every peg at once, shared by the gaps and the wraps
        gaps = distances.min(axis=1) - PEG_RADIUS - self.cable_radius
        band = PEG_RADIUS + self.cable_radius + WRAP_MARGIN
        wraps = np.array([s * w for s, w in zip(route.sides, wrap_angles(x, distances, band, self.peg_top))])
        clip_distance, threaded = route.clip.measure(x, resample(x))
        f = self.physics.cable.end_forces()
        f *= f  # np.linalg.norm(f, axis=1)'s sums of squares, without its wrapper
        self._measures = {"time": world.time, "wraps": wraps, "gaps": gaps,
                          "clip_distance": clip_distance, "threaded": threaded,
                          "end_force": float(np.sqrt(f[:, 0] + f[:, 1] + f[:, 2]).max())}
        return self._measures

    def _task_observation(self) -> np.ndarray:
        m, route = self.measures(), self.route
        out = np.zeros(TASK_DIM)
        for k, (p, s) in enumerate(zip(route.pegs, route.sides)):
            out[6 * k: 6 * k + 6] = [1.0, p[0], p[1], s, m["wraps"][k], m["gaps"][k]]
        clip = route.clip
        out[6 * MAX_PEGS:] = [*clip.centre, clip.top, math.cos(clip.yaw), math.sin(clip.yaw), m["clip_distance"],
                              float(m["threaded"])]
        return out

    def progress(self) -> tuple[float, bool]:
        """(P, all wrapped): P the mean over pegs of min(p_1 .. p_k) (see the module doc)."""
        m = self.measures()
        cached = getattr(self, "_progress", None)
        if cached is not None and cached[0] is m:  # asked twice a step (reward, info): once per measures
            return cached[1]
        p = _clip(m["wraps"] / WRAP_MIN, 0.0, 1.0)
        first = np.minimum.accumulate(p)
        out = float(np.add.reduce(first) / len(first)), bool((p >= 1.0).all())  # mean(): its sum and division
        self._progress = (m, out)
        return out

    def is_success(self) -> bool:
        return self.progress()[1] and self.measures()["threaded"]

    def _task_reward(self) -> tuple[float, bool]:
        m = self.measures()
        progress, wrapped = self.progress()
        reward = 0.5 * progress + 0.5 * float(wrapped) * math.exp(-m["clip_distance"] / CLIP_SCALE)
        reward -= FORCE_PENALTY * max(0.0, m["end_force"] - self.force_soft)
        success = wrapped and m["threaded"]
        return reward + SUCCESS_BONUS * success, success or m["end_force"] > self.overload

    def scripted_policy(self) -> "RoutingPolicy":
        """A fresh :class:`RoutingPolicy` (observation only; plans at ``reset(obs)``)."""
        return RoutingPolicy()

    def _task_info(self) -> dict[str, Any]:
        m = self.measures()
        return {"wraps": m["wraps"].copy(), "clip_distance": m["clip_distance"], "threaded": bool(m["threaded"]),
                "end_force": m["end_force"], "overload": bool(m["end_force"] > self.overload),
                "is_success": self.is_success()}


def yaw_of(quat: np.ndarray) -> float:
    """Yaw [rad] of the right grasp frame ``quat``: the direction of the cable end it holds (minus its x axis)."""
    x_axis = rotation(quat)[:, 0]
    return math.atan2(-x_axis[1], -x_axis[0])


class RoutingPolicy:
    """A scripted baseline from the observation only: taut-string waypoints for the right gripper.

    At the first observation (:meth:`reset`) it plans, with the cable length taken as the grippers'
    distance then (the cable settles nearly straight) and ``slack`` of it in use: for each peg, a point
    from which the cable passes the peg ``clearance`` [m] outside its required side, then an arc of points
    that swings the cable around the peg (the gripper on a circle of the remaining length about the
    contact point, its yaw along the cable) to the route's next direction (the common tangent to the
    next peg, or the clip's axis after the last); then beyond the clip on its axis, high
    (``z_high`` [m] above the table), lowered to ``z_low`` [m], and pulled along the axis until the
    wrist reads ``pull_force`` [N]. A P-controller (``gain`` action per m, ``yaw_gain`` per rad)
    follows the points, moving on within ``tolerance`` [m].
    """

    def __init__(self, slack: float = 0.97, clearance: float = 0.03, z_high: float = 0.16, z_low: float = 0.055,
                 pull_force: float = 1.5, gain: float = 20.0, yaw_gain: float = 2.0, tolerance: float = 0.01,
                 arc_step: float = math.radians(10.0)):
        self.slack, self.clearance, self.z_high, self.z_low = slack, clearance, z_high, z_low
        self.pull_force, self.gain, self.yaw_gain, self.tolerance = pull_force, gain, yaw_gain, tolerance
        self.arc_step = arc_step
        self.plan: list[tuple[np.ndarray, float]] | None = None

    def reset(self, obs: dict[str, np.ndarray]) -> None:
        """Plan the waypoints ((x, y, z) [m], yaw [rad]) from the episode's first observation."""
        task = np.asarray(obs["task"], dtype=float)
        grippers = np.asarray(obs["gripper_pos"], dtype=float)
        start = grippers[0, :2]
        budget = self.slack * float(np.linalg.norm(grippers[1] - grippers[0]))
        clip = Clip(task[6 * MAX_PEGS: 6 * MAX_PEGS + 2], math.atan2(task[-3], task[-4]), task[6 * MAX_PEGS + 2])
        table = clip.top - CLIP_HEIGHT
        rho = PEG_RADIUS + 0.003  # peg and a nominal cable radius [m]
        pegs = [(task[6 * k + 1: 6 * k + 3], task[6 * k + 3]) for k in range(MAX_PEGS) if task[6 * k] > 0.5]
        plan, point, used = [], start, 0.0
        high = table + self.z_high
        for k, (peg, side) in enumerate(pegs):
            u_in = tangent_direction(point, peg, rho, side)
            u_pre = tangent_direction(point, peg, rho + self.clearance, side)
            plan.append((np.array([*(point + (budget - used) * u_pre), high]), math.atan2(u_pre[1], u_pre[0])))
            u_out = clip.axis if k == len(pegs) - 1 else self._common_tangent(peg, side, *pegs[k + 1], rho)
            entry = peg - side * rho * left_normal(u_in)
            used += float(np.linalg.norm(entry - point))
            phi_in = math.atan2(u_in[1], u_in[0])
            turn = math.remainder(math.atan2(u_out[1], u_out[0]) - phi_in, 2 * math.pi)
            steps = max(1, math.ceil(abs(turn) / self.arc_step))
            for j in range(1, steps + 1):
                phi = phi_in + turn * j / steps
                u = unit(phi)
                contact = peg - side * rho * left_normal(u)
                plan.append((np.array([*(contact + (budget - used - rho * abs(phi - phi_in)) * u), high]), phi))
            used += rho * abs(turn)
            point = peg - side * rho * left_normal(u_out)
        used += float(np.linalg.norm(clip.centre - point))
        end = clip.centre + (budget - used) * clip.axis
        plan.append((np.array([*end, high]), clip.yaw))
        plan.append((np.array([*end, table + self.z_low]), clip.yaw))
        self.plan, self.index, self.axis = plan, 0, clip.axis

    @staticmethod
    def _common_tangent(peg: np.ndarray, side: float, nxt: np.ndarray, nxt_side: float, rho: float) -> np.ndarray:
        """Direction of the line leaving ``peg`` on ``side`` that touches ``nxt`` on ``nxt_side`` (fixed point)."""
        u = (nxt - peg) / np.linalg.norm(nxt - peg)
        for _ in range(8):
            d = (nxt - nxt_side * rho * left_normal(u)) - (peg - side * rho * left_normal(u))
            u = d / np.linalg.norm(d)
        return u

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """The action (4,) for ``obs`` (plans on the first call after :meth:`reset`... or plans now if never reset)."""
        if self.plan is None:
            self.reset(obs)
        gripper = np.asarray(obs["gripper_pos"][1], dtype=float)
        yaw = yaw_of(obs["gripper_quat"][1])
        target, target_yaw = self.plan[self.index]
        error = target - gripper
        last = self.index == len(self.plan) - 1
        if not last and np.linalg.norm(error) < self.tolerance:
            self.index += 1
            target, target_yaw = self.plan[self.index]
            error = target - gripper
        move = self.gain * error
        if last and np.linalg.norm(error) < self.tolerance:  # in place: take up the slack along the clip's axis
            force = float(np.linalg.norm(obs["wrench"][1, :3]))
            move[:2] += self.axis * (0.3 if force < self.pull_force else 0.0)
        action = np.append(move, self.yaw_gain * math.remainder(target_yaw - yaw, 2 * math.pi))
        return np.clip(action, -1.0, 1.0).astype(np.float32)
