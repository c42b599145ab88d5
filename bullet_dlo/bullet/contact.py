"""Contact detection for a cable in a Bullet world: body shapes, closest points, persistent friction anchors.

The cable's own spheres do not collide in Bullet when the model handles contact
(:class:`BulletCable` with ``contact="model"``): each step, before the cable's implicit step, the
contacts are found analytically from the bodies' primitive shapes (box, sphere, cylinder, capsule;
the ground plane is a box) at their current Bullet poses, and written into the core's
:class:`~bullet_dlo.core.kernels.contact.Contacts`:

- segments of the cable against the segments of other cables that model contact (:class:`Others`):
  each cable's step holds the other's capsule moving over its planned step (it stepped before this
  one) or held where it is (it steps after), with the pair's mean-mass stiffness and the geometric
  mean of the two cables' friction; the other cable does the same, so at rest the normal forces are
  equal and opposite (docs/concepts/contact.md, "Cable on cable");
- segments of the cable against each other when they are not close along it (a cable lying across
  itself): each side's contact treats the other segment's capsule as a body held at its start-of-step
  place (lagged, so the Newton matrix stays banded), with the cable's own friction;

- every node, as a sphere of the cable radius, against the solid (closest point on its surface;
  a node inside a box takes the nearest face);
- every segment interior, as a capsule of the cable radius, against cylinders and capsules
  (closest point between the segment and the axis), spheres (closest point to the centre) and the
  twelve edges of boxes (segments against zero-radius edges): nothing thicker than the cable
  passes between two masses, at any n.

Contacts are kept when the gap is below a margin (cable radius + twice the distance the fastest
node moves in a step + 1 mm), so the implicit step sees a contact before it closes. Each
(body, feature, node or segment) has a key; a contact seen again keeps its friction anchor and
stick/slide state.

Friction: the spec's ``static_friction`` and ``friction`` (dynamic) are the cable's; a body's
Bullet ``lateralFriction`` mu_b combines with them by the geometric mean, mu = sqrt(mu_cable mu_b)
(Bullet multiplies the two, so a cable of 0.3 on a body of 0.5 slides at 0.15, below both; the
geometric mean is symmetric like Bullet's rule, lies between the two, and equals the cable's own
coefficient on a body given the same value).

A link whose one shape is a convex hull (a mesh made from vertices, a URDF's convex mesh: the arms' links
and fingers) is a HULL row on the project's exact geometry (:class:`Hulls`, :func:`_hull_contacts`): its
polytope from ``getMeshData``'s vertices, grown by Bullet's collision margin, used once Bullet's own distances
agree with it at set-up (:meth:`ContactSet._hull`); a static hull's sharp edges wrap segments like a box's.

Everything else a body can carry (triangle meshes, compounds of hulls, planes, heightfields, links with several
shapes, the other shapes of a URDF's child links) is measured by Bullet's own narrow phase
(:meth:`ContactSet._probe`): each such link is a PROBE row, and before the step every node (a point
capsule of the cable radius) and every segment (a capsule of the cable radius) within reach of the link's
bounding box asks ``getClosestPoints`` for the link's closest point within the margin. The answer
(point on the link, normal from Bullet, distance) becomes a contact of the same kind and law as the
primitives' (a segment contact only where the link comes closer between the nodes than at them), on
the link's current pose and velocity; the reaction goes to that link. No query is made while no
such link's broad-phase box overlaps the cable's (``getOverlappingObjects``, one call per step).
"""
from __future__ import annotations

import math
import warnings
from typing import NamedTuple

import numpy as np
import pybullet as pb

from bullet_dlo.bullet import bvh, held_bodies
from bullet_dlo.bullet.body_energy import BodyEnergy
from bullet_dlo.bullet.contact_call import make_broad_args, make_set_args
from bullet_dlo.bullet.kernels import bind
from bullet_dlo.bullet.native import (BASE_STATE, HANDLE, collision_info_init, disabled_warning, kernel_api,
                                      overlapping, read_base_states, status_aabb, submit)
from bullet_dlo.bullet.shape_data import collision_shapes, fixed_link
from bullet_dlo.core.kernels.contact import (PENALTY, STICK, WRAP, Bodies, Contacts, _arc_middle, _gap, _wrap_cap,
                                             make_bodies, make_contacts, mark_wrap_neighbours, wrap_active,
                                             wrap_arc_share, wrap_energy, wrap_start)
from bullet_dlo.core.kernels.jit import njit

BOX, SPHERE, CYLINDER, CAPSULE, PROBE, HULL = range(6)  # PROBE: a link measured by Bullet's narrow phase
# HULL: a convex hull mesh on the project's exact geometry (:class:`Hulls`), checked against Bullet at set-up
N_EDGES = 12  # a box's edges, each a segment feature of its own
NEAR_SPARE = 0.01  # [m] a free body this much beyond the cable's reach has its held load measured (_near_free_bodies)
BOUNDING = math.sqrt(3.0)  # a body's bounding radius over the largest side of its axis-aligned box (its diagonal)
SKIP_QUIET = True  # skip detect() when quiet() proves it finds nothing (False: always detect; for the A/B test)
PACK_ARGS = True  # call detect, quiet and _probe_broad on the set's packed arrays (contact_call.py; False: plain calls)
SMALL_N = 64  # self-contact candidates of cables up to this many nodes: every pair tried (faster there)
S_MIN = 1e-3  # segment interior: 0 < s < 1 away from the nodes by this much (nodes are contacts of their own)
# a probed segment contact must come closer than both its nodes by this much [m] (above the narrow phase's
# noise, 1e-9 m measured): on a flat face a capsule's closest point is anywhere along it, and the nodes carry it
SEGMENT_DIP = 1e-7
ALONG_EDGE = 0.1  # [rad] a segment this close to parallel to a box edge has no well-defined closest point to it
WRAP_ALONG = math.radians(15.0)  # [rad] a segment this close to parallel to an edge lies along it: no wrap (detect)
WRAP_ALONG_SIN2 = math.sin(WRAP_ALONG) ** 2
# Bullet answers a query against a triangle mesh triangle by triangle: answers whose normals lie within this angle
# of a closer one are the same contact (a face split into triangles, an edge seen from its two faces); the others
# are further contacts of the same node (segment), up to PROBE_EXTRA of them (a concave corner's other faces)
PROBE_SAME_COS = math.cos(math.radians(30.0))
PROBE_EXTRA = 2
# [m] and only where the other face rises above the closest one's plane by this much (a concave corner): a coplanar
# neighbour triangle answers with its edge, a contact whose linearised plane would be a phantom step on a flat
# surface (measured on a heightfield slope: it held a sliding cable)
PROBE_RISE = 1e-5
WRAP_BENDS = True  # a wrapped segment's bends: at its nodes against the path, the turn at the edge (contact.md)
FOLLOW_TIME = 0.05  # [s] time constant of the low-pass over a free body's unplanned motion that stuck anchors follow
SINK_TIME = 0.05  # [s] time constant over which the penetration a body's unplanned move left is let out (Store.sink)
# A row a free body presses, and a static row under a node it presses, stiffens to its load: no body's weight presses
# it deeper than LOAD_DEPTH of the cable radius, up to LOAD_STIFFNESS_MAX times alpha m_c / h^2 (:func:`_follow_loads`)
LOAD_DEPTH = 0.05
LOAD_STIFFNESS_MAX = 100.0
NEAR_NODES = 2  # a static row takes the load free bodies press within this many nodes of its own (_follow_loads)
DRIVEN_INV_MASS = 1e-200
"""[1/kg, 1/(kg m^2)] The inverse mass and inertia a link of a driven body (a position-controlled arm) has in the
cable's step: infinite in effect (the condensed contact's softening 1 / (1 + h^2 lambda) is exactly 1, so the link
is a kinematic obstacle moving with its own velocity), yet not 0, which the kernels read as static (a static hull's
edges wrap a segment; the work check would not correct a static body's motion)."""
EXACT_HULLS = True  # convex hulls on the project's geometry (False: Bullet's narrow phase, as for other meshes)
# [m] a hull's distances (margin included) must match Bullet's within this at half the check points 2-3 mm off it or
# more, with one common margin, and nowhere be larger; a compound of hulls or another frame or scale differs by
# millimetres. Elsewhere Bullet may be farther by up to HULL_GJK_TOL: its GJK takes support points within 1 cm of
# one already in its simplex for the same point (the simplex solver's equal-vertex threshold, 1e-4 m^2) and stops,
# so on a finely faceted hull its distance is too large (measured: pybullet_data's duck scaled 0.08, 0.15 mm; 0.03,
# 0.29 mm; its sphere_smooth at 0.05, 0.14 mm; 4e-5 m near the Panda's vertices), never too small, and its closest
# point is still a point of the hull (checked)
HULL_CHECK_TOL = 1e-4
HULL_GJK_TOL = 5e-4
INSIDE_REPORTED = 0.5  # a dynamic body holding the cable's centre line this many radii deep is reported (a box
# dropped 1 cm crosses it by 0.2 mm for a step at 240 Hz and rests 1.6 mm outside; at 60 Hz it ends 2 mm inside)
INSIDE_KEPT = 0.1  # [s] ... or holding it inside at all for this long: a 2 kg box resting on an 8 g cable at 60 Hz
# kept its centre line 0.08 mm inside, silently (an independent check, 2026-12-07)
EMPTY_LINK_BOX = 3e-3  # [m] broad-phase box of a link without a collision shape is at most this wide (2 mm measured)
HULL_MAX_FACES = 4096  # hulls with more triangles stay with Bullet's narrow phase (the exact query loops over faces)
_HULL_MEMO: dict = {}  # ContactSet._hull's answers by their inputs: an environment's reset and each exclusion rebuild
HULL_MEMO_SIZE = 256  # the contact set with the same arm links at the same poses (the checks were 45 % of a reset)
WRAP_EDGE_MIN = math.pi / 4  # [rad] a hull edge whose faces turn by at least this is wrapped like a box edge
_GEOMS = {pb.GEOM_BOX: BOX, pb.GEOM_SPHERE: SPHERE, pb.GEOM_CYLINDER: CYLINDER, pb.GEOM_CAPSULE: CAPSULE}


class Shapes(NamedTuple):
    """The bodies a cable touches, as the detection kernel takes them (B shapes).

    kind (B,) int: BOX/SPHERE/CYLINDER/CAPSULE, or PROBE (a link Bullet's narrow phase measures:
    pos and rot are its centre-of-mass frame, size unused); pos [m] (B, 3) and rot (B, 3, 3) (world from
    shape frame) of each shape; size (B, 3) [m]: box half extents, or (radius, half length, 0);
    com (B, 3) [m]: the body's centre of mass; lin_vel [m/s], ang_vel [rad/s] (B, 3): the body's
    velocity; static_friction, dynamic_friction (B,): combined friction coefficients with the cable; inv_mass (B,) [1/kg]
    and inv_inertia (B,) [1/(kg m^2)]: the body's inverse mass and the largest eigenvalue of its
    inverse inertia (both 0 for a static body); owner (B,) int: the first shape of the same body and
    link (the shapes of one link share its inertia); slot (B,) int: the free body's slot in the contact step's
    :class:`~bullet_dlo.core.kernels.contact.Bodies` (-1: static, or a link of an articulated body); inertia
    (B, 3, 3) [kg m^2]: a free body's inertia tensor in the world frame now (zero otherwise); impact (B,) bool: the
    free body gained a Bullet contact (the ground, another body) in the last Bullet step, a collision the cable's step
    did not plan (its penetration into the cable is let out slowly: :class:`Store`, sink).
    """

    kind: np.ndarray
    pos: np.ndarray
    rot: np.ndarray
    size: np.ndarray
    com: np.ndarray
    lin_vel: np.ndarray
    ang_vel: np.ndarray
    static_friction: np.ndarray
    dynamic_friction: np.ndarray
    inv_mass: np.ndarray
    inv_inertia: np.ndarray
    owner: np.ndarray
    slot: np.ndarray
    inertia: np.ndarray
    impact: np.ndarray


class Store(NamedTuple):
    """Friction state by contact key, kept from step to step: anchor (K, 4), state (K,), active (K,) bool;
    keys (M,) int: the key of each row of the current Contacts; body (M,) int: its shape index; wrap (K,)
    bool: the key's row was a segment wrapped round an edge (kept while it wraps, however far the chord); drift
    (K, 3) [m/s]: the part of a free body's velocity at a stuck row that the cable's steps did not plan, in the row's
    tangent plane, low-passed over FOLLOW_TIME (the anchor follows it: see :func:`detect`); sink (K,) [m]: the
    penetration of a row on a free body that Bullet's moves of the body, not the cable's step, made, not yet let out
    (the row's surface point sits that much inside the body; it decays over SINK_TIME: see :func:`detect`); depth (K,)
    [m]: how far inside the cable the last step planned the row to end (0: outside, or a new key), against which a
    body in a collision's unplanned move is measured (:func:`_sink_unplanned`); load (K,) [N] and stiffness (K,) [N/m]:
    the row's normal force at the end of the last step and its normal stiffness then (:func:`_follow_loads`)."""

    anchor: np.ndarray
    state: np.ndarray
    active: np.ndarray
    keys: np.ndarray
    body: np.ndarray
    wrap: np.ndarray
    drift: np.ndarray
    sink: np.ndarray
    depth: np.ndarray
    load: np.ndarray
    stiffness: np.ndarray


class Probes(NamedTuple):
    """Bullet's closest points of the coming step (:meth:`ContactSet._probe`), P rows, count[0] used: shape
    (P,) int: the PROBE row; node (P, 2) int and weight (P,): the nodes (i, i) of a node contact or (i, i + 1)
    of a segment contact and the weight s of node i + 1; point [m] (P, 3) on the link; normal (P, 3) unit,
    from the link to the cable; key (P,) int: the row's friction key within its link's block (:func:`_probe_key`)."""

    count: np.ndarray
    shape: np.ndarray
    node: np.ndarray
    weight: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    key: np.ndarray


class Hulls(NamedTuple):
    """Convex hulls on the project's own geometry, H hulls packed one after another (link centre-of-mass frame).

    row (B,) int: the hull of each Shapes row (-1: none); near (B,) bool: the row's pose is current and it is
    near the cable this step (a base link's always; a child link's when Bullet's broad phase names it);
    margin (H,) [m]: Bullet's collision margin (the surface is the polytope grown by it); lo, hi (H, 3) [m]:
    the vertices' box. Faces: plane_first (H + 1,) int, plane (F, 4): outward unit normal and offset d (n.x = d
    on the face); tri_first (H + 1,), tri (T, 3, 3) [m]: the faces' triangles, tri_plane (T,) int: each one's
    plane. Sharp edges (between two different planes): edge_first (H + 1,), edge_p (E, 3) [m] midpoint,
    edge_a (E, 3) unit direction, edge_hl (E,) [m] half length, edge_n (E, 2, 3) the two faces' normals.
    Hierarchies (:mod:`bullet_dlo.bullet.bvh`) of a hull with at least :data:`TREE_MIN_TRIANGLES` triangles: tri_root,
    edge_root (H,) int the roots of its triangles' and its edges' trees (-1: none, every feature is tested);
    tree_lo, tree_hi (N, 3) [m], tree_right, tree_first, tree_count (N,) int, tree_item (I,) int: every tree's
    nodes and items (:class:`bullet_dlo.bullet.bvh.Tree`, node indices global, items local to their hull). With the
    trees, a grid of cubes over the hull's box (:func:`_outside_cells`): grid_cell (H,) [m] the cubes' edge, grid_dims
    (H, 3) int their counts (from ``lo``), grid_first (H + 1,) int, grid_out (K,) bool: a cube lies wholly outside the
    polytope (beyond one face's plane). hint (H, 4 n) int: the nearest triangle when last measured (-1: none) of
    each node (first n) and of each segment's three points beside edges (3 i + pick after them), tried first
    (:func:`_hull_distance_at`); (H, 0): no hints.
    """

    row: np.ndarray
    near: np.ndarray
    margin: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    plane_first: np.ndarray
    plane: np.ndarray
    tri_first: np.ndarray
    tri: np.ndarray
    tri_plane: np.ndarray
    edge_first: np.ndarray
    edge_p: np.ndarray
    edge_a: np.ndarray
    edge_hl: np.ndarray
    edge_n: np.ndarray
    tri_root: np.ndarray
    edge_root: np.ndarray
    tree_lo: np.ndarray
    tree_hi: np.ndarray
    tree_right: np.ndarray
    tree_first: np.ndarray
    tree_count: np.ndarray
    tree_item: np.ndarray
    grid_cell: np.ndarray
    grid_dims: np.ndarray
    grid_first: np.ndarray
    grid_out: np.ndarray
    hint: np.ndarray


TREE_SLACK = 1e-9  # [m] a tree's query box is grown by this beyond the exact test that follows it
GRID_CELLS = 16  # cubes of a hull's grid along its box's longest side
TREE_MIN_TRIANGLES = 64
"""A hull of at least this many triangles gets trees of its triangles and edges (a finely faceted mesh: the duck's
1070 triangles cost a node 2.5 us when each was tested); a smaller one is tested feature by feature."""

_HULL_GEOMETRY: dict = {}
""":func:`_hull_geometry` by vertex content: a robot's links are the same meshes in every world a process
builds (qhull and the face merge cost ~0.1 s a link)."""


def _hull_geometry(vertices: np.ndarray):
    """Planes (F, 4), triangles (T, 3, 3), their planes (T,) and sharp edges (midpoint, unit direction, half
    length, the two normals) of the convex hull of ``vertices`` [m] (V, 3); None if it is degenerate (flat).
    The arrays are shared between calls with equal vertices: read only."""
    key = (vertices.shape, vertices.tobytes())
    if key not in _HULL_GEOMETRY:
        _HULL_GEOMETRY[key] = _hull_geometry_of(vertices)
    return _HULL_GEOMETRY[key]


def _hull_geometry_of(vertices: np.ndarray):
    from scipy.spatial import ConvexHull, QhullError

    try:
        hull = ConvexHull(vertices)
    except (QhullError, ValueError):
        return None
    scale = float(np.ptp(vertices, axis=0).max())
    planes = np.empty((len(hull.equations), 4))
    n_planes = 0
    tri_plane = []
    for eq in hull.equations:  # merge the coplanar triangles of one face (qhull triangulates)
        nrm, off = eq[:3], -eq[3]
        same = np.flatnonzero((planes[:n_planes, :3] @ nrm > 1.0 - 1e-9)
                              & (np.abs(off - planes[:n_planes, 3]) < 1e-9 * scale))
        if same.size:
            tri_plane.append(int(same[0]))
        else:
            tri_plane.append(n_planes)
            planes[n_planes, :3], planes[n_planes, 3] = nrm, off
            n_planes += 1
    planes = planes[:n_planes].copy()
    tri = vertices[hull.simplices]
    owners: dict = {}
    for t, simplex in enumerate(hull.simplices.tolist()):
        for a, b in ((0, 1), (1, 2), (2, 0)):
            owners.setdefault(tuple(sorted((simplex[a], simplex[b]))), []).append(tri_plane[t])
    edges = []
    for (a, b), fs in owners.items():
        if len(fs) != 2 or fs[0] == fs[1]:
            continue  # a diagonal inside a face
        pa, pb_ = vertices[a], vertices[b]
        d = pb_ - pa
        hl = 0.5 * float(np.linalg.norm(d))
        edges.append((0.5 * (pa + pb_), d / (2 * hl), hl, planes[fs[0]][:3], planes[fs[1]][:3]))
    tri_plane = np.array(tri_plane, np.int64)
    for arr in (planes, tri, tri_plane):
        arr.setflags(write=False)
    return planes, tri, tri_plane, edges


HULL_CHECK_POINTS = 64
"""About this many check points per kind (faces, vertices, edges) compare a hull with Bullet's distances (one
``getClosestPoints`` each, when a world meets a mesh link; 24 let the Panda's base through, whose hull is not
Bullet's within HULL_CHECK_TOL)."""


def _hull_points(vertices: np.ndarray, planes: np.ndarray, tri: np.ndarray, tri_plane: np.ndarray, edges,
                 radius: float) -> np.ndarray:
    """Check points [m] (link frame) just outside a hull: off each face's centre, each vertex and each edge's
    midpoint (at most about HULL_CHECK_POINTS of each), where a compound of hulls, a mesh read at another scale or in
    another frame would differ."""
    pts = []
    for f in range(min(len(planes), HULL_CHECK_POINTS)):
        centre = tri[tri_plane == f].reshape(-1, 3).mean(axis=0)
        pts.append(centre + (radius + 2e-3) * planes[f, :3])
    mid = vertices.mean(axis=0)
    for v in vertices[:: max(1, len(vertices) // HULL_CHECK_POINTS)]:
        d = v - mid
        pts.append(v + (radius + 2e-3) * d / max(float(np.linalg.norm(d)), 1e-12))
    for centre, _, _, n1, n2 in edges[:: max(1, len(edges) // HULL_CHECK_POINTS)]:
        b = n1 + n2
        pts.append(centre + (radius + 1e-3) * b / max(float(np.linalg.norm(b)), 1e-12))
        pts.append(centre + (radius + 1e-3) * n1)
    return np.array(pts)


_CHECK_POINTS: dict = {}
""":func:`_check_points` by the hull geometry's identity and the radius, with the geometry (kept alive, so the id is
not reused): the points and their distances do not depend on the link's pose, which the check's queries do."""


def _check_points(vertices: np.ndarray, geo: tuple, radius: float) -> tuple[np.ndarray, Hulls, np.ndarray]:
    """The check points round a hull (:func:`_hull_points`, link frame [m]), the hull packed alone (no margin) and
    its distances [m] at them: once per hull geometry and radius (an environment's reset checks the same arm
    links at new poses)."""
    key = (id(geo), radius)
    hit = _CHECK_POINTS.get(key)
    if hit is not None and hit[0] is geo:
        return hit[1]
    planes, tri, tri_plane, edges = geo
    points = _hull_points(vertices, planes, tri, tri_plane, edges, radius)
    hu = _pack_hulls([(planes, tri, tri_plane, edges, 0.0)], [0], 1, keep=False)
    answer = (points, hu, hull_distances(hu, 0, points))
    if len(_CHECK_POINTS) >= HULL_MEMO_SIZE:
        _CHECK_POINTS.clear()
    _CHECK_POINTS[key] = (geo, answer)
    return answer


def _pack_hulls(hulls: list, row: list, n_exact: int, n: int = 0, keep: bool = True) -> Hulls:
    """The :class:`Hulls` of ``hulls`` [(planes, triangles, their planes, sharp edges, margin)], ``row``: each
    Shapes row's hull (-1: none); the rows below n_exact (base links, read every step) are always near; n: the
    cable's nodes (their hints). The hulls' own arrays are packed once per list of hulls (:func:`_packed_geometry`;
    ``keep`` False: not kept); ``row``, ``near`` and ``hint``, which a contact set writes, are its own."""
    row_a = np.array(row, np.int64)
    return Hulls(row=row_a, near=(row_a >= 0) & (np.arange(len(row)) < n_exact),
                 hint=np.full((len(hulls), 4 * n if n else 0), -1, np.int64), **_packed_geometry(hulls, keep))


_PACKED_HULLS: dict = {}
"""The packed arrays of a list of hulls (:func:`_packed_geometry`) by the ids of its hulls, with the hulls (kept
alive, so that the ids are not reused while the entry lives). A world rebuilds its contact sets as bodies come
and go, and an environment's reset builds a new world of the same meshes: packing them took 9 ms a set with the
Panda's links (three sets a dual-arm reset)."""
PACKED_HULLS_SIZE = 32  # entries kept (the dict is emptied when full)


def _packed_geometry(hulls: list, keep: bool = True) -> dict:
    """The fields of :class:`Hulls` that hold the hulls themselves (all but row, near and hint), packed once per list
    of the same hull objects (their arrays are only read: the contact sets that share them cannot change them)."""
    key = (TREE_MIN_TRIANGLES, *map(id, hulls))  # (the trees depend on that threshold)
    hit = _PACKED_HULLS.get(key)
    if hit is not None and all(a is b for a, b in zip(hit[0], hulls)):
        return hit[1]

    def cat(parts, shape, dtype=float):
        return np.concatenate(parts).astype(dtype) if parts else np.zeros(shape, dtype)

    first = [np.cumsum([0] + [len(h[i]) for h in hulls]).astype(np.int64) for i in (0, 1, 3)]
    edges = [e for h in hulls for e in h[3]]
    verts = [h[1].reshape(-1, 3) for h in hulls]
    fields = dict(margin=np.array([h[4] for h in hulls], float),
                  lo=np.array([v.min(axis=0) for v in verts]).reshape(-1, 3),
                  hi=np.array([v.max(axis=0) for v in verts]).reshape(-1, 3),
                  plane_first=first[0], plane=cat([h[0] for h in hulls], (0, 4)),
                  tri_first=first[1], tri=cat([h[1] for h in hulls], (0, 3, 3)),
                  tri_plane=cat([h[2] + f for h, f in zip(hulls, first[0][:-1])], (0,), np.int64),
                  edge_first=first[2], edge_p=np.array([e[0] for e in edges], float).reshape(-1, 3),
                  edge_a=np.array([e[1] for e in edges], float).reshape(-1, 3),
                  edge_hl=np.array([e[2] for e in edges], float),
                  edge_n=np.array([(e[3], e[4]) for e in edges], float).reshape(-1, 2, 3), **_pack_trees(hulls))
    if keep:
        if len(_PACKED_HULLS) >= PACKED_HULLS_SIZE:
            _PACKED_HULLS.clear()
        _PACKED_HULLS[key] = (tuple(hulls), fields)
    return fields


_HULL_TREES: dict = {}
"""The trees of a hull geometry by the id of its triangles' array (shared and kept alive by _HULL_GEOMETRY; the
entry holds it too, so the id is not reused)."""


def _hull_trees(planes: np.ndarray, tri: np.ndarray, edges: list) -> tuple | None:
    """The trees of a hull's triangles and sharp edges and its grid of outside cells (cube edge [m], counts (3,),
    flags), or None below TREE_MIN_TRIANGLES (or without edges)."""
    if len(tri) < TREE_MIN_TRIANGLES or not edges:
        return None
    if id(tri) not in _HULL_TREES or _HULL_TREES[id(tri)][0] is not tri:
        p = np.array([e[0] for e in edges], float)
        a = np.array([e[1] for e in edges], float)
        hl = np.array([e[2] for e in edges], float)
        _HULL_TREES[id(tri)] = (tri, bvh.build(*bvh.triangle_boxes(tri)), bvh.build(*bvh.edge_boxes(p, a, hl)),
                                _outside_cells(planes, tri.reshape(-1, 3).min(axis=0), tri.reshape(-1, 3).max(axis=0)))
    return _HULL_TREES[id(tri)][1:]


def _outside_cells(planes: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """A grid of cubes from ``lo`` covering the box [lo, hi] [m], GRID_CELLS along its longest side: the cube edge
    [m], the counts (3,) int and, per cube (x fastest), whether it lies wholly beyond one of the faces' ``planes``
    (F, 4): min over the cube of n.q - d > 0 (n.centre - d - edge / 2 sum |n_j|), so every point in it is outside."""
    cell = float(max((hi - lo).max(), 1e-9)) / GRID_CELLS
    dims = np.maximum(1, np.ceil((hi - lo) / cell - 1e-9)).astype(np.int64)
    iz, iy, ix = np.meshgrid(*(np.arange(d) for d in dims[::-1]), indexing="ij")  # x fastest
    centre = lo + cell * (np.stack([ix.ravel(), iy.ravel(), iz.ravel()], axis=1) + 0.5)
    slack = 0.5 * cell * np.abs(planes[:, :3]).sum(axis=1) + planes[:, 3]
    out = np.zeros(len(centre), np.bool_)
    for k in range(0, len(centre), 512):
        out[k:k + 512] = ((centre[k:k + 512] @ planes[:, :3].T - slack) > 0.0).any(axis=1)
    return cell, dims, out


def _pack_trees(hulls: list) -> dict:
    """The tree fields of :class:`Hulls` for ``hulls`` (as :func:`_pack_hulls` takes them)."""
    roots = np.full((2, len(hulls)), -1, np.int64)
    parts: list[bvh.Tree] = []
    nodes = items = 0
    grid_cell, grid_dims = np.ones(len(hulls)), np.ones((len(hulls), 3), np.int64)
    grid_first, grid_out = [0], []
    for h, hull in enumerate(hulls):
        trees = _hull_trees(hull[0], hull[1], hull[3])
        if trees is None:
            grid_out.append(np.zeros(1, np.bool_))  # (one cube, never outside)
            grid_first.append(grid_first[-1] + 1)
            continue
        grid_cell[h], grid_dims[h], flags = trees[2]
        grid_out.append(flags)
        grid_first.append(grid_first[-1] + len(flags))
        for kind, tree in enumerate(trees[:2]):
            roots[kind, h] = nodes
            parts.append(tree._replace(right=np.where(tree.right >= 0, tree.right + nodes, -1),
                                       first=tree.first + items))
            nodes += len(tree.right)
            items += len(tree.item)

    def cat(field, shape, dtype):
        return np.concatenate([getattr(t, field) for t in parts]).astype(dtype) if parts else np.zeros(shape, dtype)

    return dict(tri_root=roots[0], edge_root=roots[1], tree_lo=cat("lo", (0, 3), float),
                tree_hi=cat("hi", (0, 3), float), tree_right=cat("right", (0,), np.int64),
                tree_first=cat("first", (0,), np.int64), tree_count=cat("count", (0,), np.int64),
                tree_item=cat("item", (0,), np.int64), grid_cell=grid_cell, grid_dims=grid_dims,
                grid_first=np.array(grid_first, np.int64),
                grid_out=np.concatenate(grid_out) if grid_out else np.zeros(0, np.bool_))


class Others(NamedTuple):
    """Other cables this cable touches through the model (packed one after another, N nodes in all).

    x (N, 3) [m]: their centre lines at the start of the step; u (N, 3) [m/s]: the velocity their
    surface moves at over the step (their planned step when they have planned it already this world
    step, else 0: held where they are); mass (N,) [kg], radius (N,) [m]; static_friction, dynamic_friction (N,): friction
    combined with this cable's (geometric mean); first (C + 1,) int: where each cable starts;
    vmax (1,) [m/s]: their fastest node. Per contact row (M): row_node (M, 2), row_w (M, 2): the
    other cable's nodes and weights at the contact; row_p0 (M, 3) [m]: that point at detection.
    """

    x: np.ndarray
    u: np.ndarray
    mass: np.ndarray
    radius: np.ndarray
    static_friction: np.ndarray
    dynamic_friction: np.ndarray
    first: np.ndarray
    vmax: np.ndarray
    row_node: np.ndarray
    row_w: np.ndarray
    row_p0: np.ndarray


CABLE = -2  # Store.body of a contact with another cable (-1: the cable itself)


_ORIGIN = [0.0, 0.0, 0.0]
_UNTURNED = [0.0, 0.0, 0.0, 1.0]


def _distance(point) -> float:
    """The distance [m] of a getClosestPoints answer."""
    return point[8]


def keys_per_shape(n: int) -> int:
    """Friction keys of one shape for a cable of n nodes: its nodes, then per feature (0: a segment's own row,
    1-12: a box's edges, a hull's blunt edges; a probed link's further answers: 1-6 for segments) n - 1 segments; a
    probed link's further node answers take six blocks of n from feature 7 on, 6 keys past the 13 features
    (:func:`_probe_key`); then two more segment features, a probed segment's answers beside its closest one."""
    return n + (N_EDGES + 3) * (n - 1) + 6


def self_keys(n: int) -> int:
    """Friction keys of self-contact for a cable of n nodes, two sides each (:func:`_self_contacts`): a pair of
    segments' edges, (n - 1)^2, then a node on a segment, n (n - 1)."""
    return 2 * (n - 1) * (2 * n - 1)


def _probe_key(n: int, i: int, segment: bool, extra: bool, normal) -> int:
    """The key (within its link's block) of a probed row: node i's or segment i's own (its closest answer), or,
    for a further answer (``extra``), one of six by the normal's main direction (+-x, +-y, +-z), so that a
    corner's contacts keep their friction anchors from step to step."""
    if not extra:
        return n + i if segment else i
    a = max(range(3), key=lambda j: abs(normal[j]))
    d = 2 * a + (normal[a] < 0.0)
    return n + (n - 1) * (1 + d) + i if segment else n + 7 * (n - 1) + d * n + i


def _beside_key(n: int, i: int, after: bool) -> int:
    """The key (within its link's block) of probed segment i's answer beside its closest one, before or ``after``
    it along the segment (:func:`keys_per_shape`)."""
    return n + (N_EDGES + 1) * (n - 1) + 6 + (n - 1) * after + i


def _along(answer, at, xa, xb, radius: float) -> float:
    """Where along segment xa-xb [m] a capsule query's answer lies (0 at xa, 1 at xb): the capsule's axis point
    (the answer's point on the capsule plus ``radius`` along its normal), moved back by the query's shift ``at``,
    projected on the segment."""
    pa, nb = answer[5], answer[7]
    num = den = 0.0
    for j in range(3):
        e_j = xb[j] - xa[j]
        num += (pa[j] - at[j] + radius * nb[j] - xa[j]) * e_j
        den += e_j * e_j
    return num / den


def _beside(res, first, s_first: float, apart: float, at, xa, xb, radius: float) -> list:
    """A segment's answers beside its closest one ``first`` (at ``s_first`` along it): of the answers facing the same
    way (normals within PROBE_SAME_COS), the closest at least ``apart`` before it and the closest as far after it,
    as (answer, s, after). A segment lying across a finely faceted triangle mesh rests on the next ridge as soon as
    it tilts: that ridge must already be a row (as a hull's blunt edges beside the closest, :func:`_hull_contacts`)."""
    m = first[7]
    out = {}
    for p in sorted(res, key=_distance):
        n0, n1, n2 = p[7]
        if n0 * m[0] + n1 * m[1] + n2 * m[2] <= PROBE_SAME_COS:
            continue
        sp = _along(p, at, xa, xb, radius)
        after = sp > s_first + apart
        if (after or sp < s_first - apart) and after not in out:
            out[after] = (p, sp, after)
    return list(out.values())


def _distinct(res) -> list:
    """Bullet's answers to one query (closest first), one per contact: an answer whose normal lies within
    PROBE_SAME_COS of a closer one's is dropped, and so is one whose point does not rise PROBE_RISE above the
    closest answer's plane (only a concave corner's other faces count); at most 1 + PROBE_EXTRA."""
    res = sorted(res, key=_distance) if len(res) > 1 else res
    kept: list = [res[0]]
    c, m = res[0][6], res[0][7]  # the closest answer's point and normal: its face's plane
    for p in res[1:]:
        n0, n1, n2 = p[7]
        if any(n0 * q[7][0] + n1 * q[7][1] + n2 * q[7][2] > PROBE_SAME_COS for q in kept):
            continue
        a = p[6]
        if m[0] * (a[0] - c[0]) + m[1] * (a[1] - c[1]) + m[2] * (a[2] - c[2]) < PROBE_RISE:
            continue  # not above the closest face: a coplanar or falling neighbour's edge, no contact of its own
        kept.append(p)
        if len(kept) > PROBE_EXTRA:
            break
    return kept


def _unlisted_shape(body: int, link: int, client: int) -> bool:
    """Does a link for which PyBullet lists no collision shape have one all the same? PyBullet's
    getCollisionShapeData does not list a heightfield (it prints "Unexpected collision shape type"), so the
    link's box in the broad phase decides: a link without a collision shape has a point box grown by Bullet's
    margin (measured: 2.0 mm wide for the Panda's panda_link8 and panda_grasptarget, 0 for a visual-only body)."""
    lo, hi = pb.getAABB(body, link, physicsClientId=client)
    return max(h - l for l, h in zip(lo, hi)) > EMPTY_LINK_BOX


def _rotation(quat) -> np.ndarray:
    return np.array(pb.getMatrixFromQuaternion(quat)).reshape(3, 3)


@njit(cache=True, error_model="numpy")
def _quaternion_matrix(x, y, z, w, out):
    """out (3, 3) <- the rotation of the quaternion (x, y, z, w) as Bullet builds it (``btMatrix3x3::setRotation``,
    what ``getMatrixFromQuaternion`` returns): the same operations in the same order, so the same bits."""
    s = 2.0 / (x * x + y * y + z * z + w * w)
    xs, ys, zs = x * s, y * s, z * s
    wx, wy, wz = w * xs, w * ys, w * zs
    xx, xy, xz = x * xs, x * ys, x * zs
    yy, yz, zz = y * ys, y * zs, z * zs
    out[0, 0], out[0, 1], out[0, 2] = 1.0 - (yy + zz), xy - wz, xz + wy
    out[1, 0], out[1, 1], out[1, 2] = xy + wz, 1.0 - (xx + zz), yz - wx
    out[2, 0], out[2, 1], out[2, 2] = xz - wy, yz + wx, 1.0 - (xx + yy)


@njit(cache=True, error_model="numpy")
def set_frames(bases, moved, lpos, lrot, free_slot, inertia_diag, com, pos, rot, inertia):
    """Each shape s with ``moved[s]``: its frame from its body's base state ``bases[s]`` (CoM position [m], then the
    quaternion x, y, z, w): com, pos = com + R lpos, rot = R lrot and, for a free body's base (``free_slot[s]`` >= 0),
    the world inertia R diag R^T [kg m^2]; R the quaternion's rotation. :meth:`ContactSet._set_pose` for all of them in
    one call (the products are NumPy's, through the same BLAS, so the same bits)."""
    r = np.empty((3, 3))
    for s in range(moved.shape[0]):
        if not moved[s]:
            continue
        _quaternion_matrix(bases[s, 3], bases[s, 4], bases[s, 5], bases[s, 6], r)
        com[s, :] = bases[s, 0:3]
        pos[s, :] = bases[s, 0:3] + np.dot(r, lpos[s])
        rot[s, :, :] = np.dot(r, lrot[s])
        if free_slot[s] >= 0:
            inertia[s, :, :] = np.dot(r * inertia_diag[s], r.T)


def _constrained_bodies(client: int) -> set[int]:
    """The bodies some user constraint (``createConstraint``) joins to the world or to another body."""
    out = set()
    for i in range(pb.getNumConstraints(physicsClientId=client)):
        info = pb.getConstraintInfo(pb.getConstraintUniqueId(i, physicsClientId=client), physicsClientId=client)
        out.update(b for b in (info[0], info[2]) if b >= 0)
    return out


class ContactSet:
    """Shapes of the bodies in a world, the cable's Contacts and their persistence.

    ``bodies``: the body ids to collide with (every body of the world but the cables' spheres). Each
    link with collision shapes is a row: its base-link primitives one row per shape on their exact
    geometry, any other link (a child link, a mesh, a hull, a compound with a mesh) one PROBE row that
    Bullet's narrow phase measures (:meth:`_probe`). The exact rows' poses are read every step, a PROBE
    row's when the cable is near it; dynamic links (mass > 0) also their velocities, and they receive
    the contact forces (:meth:`apply_to_bodies`, on their link) during the coming Bullet step.

    Two-way contact with a dynamic body. A free body (one dynamic link, no joints) moves inside the cable's
    implicit step (:class:`~bullet_dlo.core.kernels.contact.Bodies`): its end-of-step velocity is solved with the
    cable's, and the reactions applied to it during the coming Bullet step make Bullet's semi-implicit update
    land on that velocity when nothing else touches it. A free body that Bullet also supports (a contact with the
    ground or another body in the last step) or a user constraint holds moves in the step too, under that load as
    measured over Bullet's last step (:mod:`bullet_dlo.bullet.held_bodies`); one that other cables touch too moves in
    it with its whole mass and their reactions, held or not, and all the cables' reactions are combined before
    Bullet's step (:func:`~bullet_dlo.bullet.held_bodies.couple`, :func:`~bullet_dlo.bullet.held_bodies.settle`). A
    body that another sub-stepped cable touches and something else holds, and every link of an articulated body that
    no motor drives, meets the cable explicitly through Bullet instead (a driven link, ``driven``, is a kinematic
    obstacle: see ``__init__``): with the penalty
    stiffness k_n = alpha m_k / h^2 (alpha = 1e4) and a body of mass M that force has k_n h^2 / M = alpha m_k / M
    per contact, 500 for a 30 g box on one 1.6 g node, far past the explicit limit (about 1), so the detector
    condenses the body's inertia into those contacts (:func:`_condense_bodies`): lambda [1/s^2], the body's fastest
    contact mode squared (largest eigenvalue of the 6 x 6 stiffness of its loaded contacts scaled by 1/M and
    1/I_min, both upper bounds), scales every contact on the body, stiffness, damping and friction cap, by 1 / (1 +
    h^2 lambda), h [s] the Bullet step: the penalty in series with the body's inertia, stable, but the body sinks
    about g h^2 more at rest (0.2-0.4 mm at 240 Hz, 2.7 mm at 60 Hz). Static bodies keep the full stiffness.
    The inertia is read at set-up (a later changeDynamics of mass is not seen).

    The energy check counts the work the bodies did on the cable with their velocity after
    Bullet's step (what they actually did), so energy a body gains from contact shows up as
    energy growth (the cable reports it as unstable) instead of passing unseen.
    """

    def __init__(self, client: int, bodies, n: int, radius: float, mu_s: float, mu_d: float,
                 alpha: float, damping_ratio: float, self_contact: bool = True, grip=None, native: int = 0,
                 others=(), exclude=None, rest_length: float = 0.0, segments=None, driven=None,
                 section: tuple[float, float] = (0.0, 0.0)):
        """``section``: a flat cable's (width, thickness) [m] (docs/concepts/contact.md, "Flat sections"; (0, 0):
        round): its penalty rows press with the rectangle's support distance, and the contacts are looked for within
        its half diagonal. ``driven``: {body: None (every link) or a set of links} whose links motors hold
        (:attr:`BulletWorld.driven_bodies <bullet_dlo.bullet.world.BulletWorld.driven_bodies>`): those dynamic links meet the cable as kinematic
        obstacles moving with the link's velocity (:data:`DRIVEN_INV_MASS`), their reactions still applied to the
        link in Bullet. ``others``: the other cables (BulletCable) whose contacts with this one the model handles;
        ``exclude``: {(body, link): None (no contact) or a set of node indices that do not touch it (nor do the
        segments next to them)}, link None meaning every link of the body; ``rest_length`` [m]: the length of
        the capsule that probes a segment (the cable's rest segment length; 0: nodes only); ``segments``: the
        cable's segment stretch stiffnesses [N/m] and rest lengths [m], each (n - 1,), and bending constants
        [N m/rad^2] (n,), which a segment wrapped
        round a sharp edge of a static box needs (docs/concepts/contact.md, "Edges"), and optionally which nodes
        are held (n,) bool: a segment next to a held node does not wrap (a holder's work through the wrap is not
        in the end loads the energy check counts); None: such a segment meets the edge as a capsule (penalty
        contact, as before)."""
        self.client = client
        self.n = n
        driven = driven or {}
        self._seg_held = np.zeros(0, dtype=np.bool_)
        if segments is None:
            self._seg_k = self._seg_l = self._seg_b = np.zeros(0)
        else:
            self._seg_k, self._seg_l, self._seg_b = (np.ascontiguousarray(a, dtype=float) for a in segments[:3])
            if len(segments) > 3:  # which nodes are held now (changed in place by grasp and release)
                self._seg_held = segments[3]
            if not WRAP_BENDS:
                self._seg_b = np.zeros_like(self._seg_b)
        self.alpha = float(alpha)
        self.zeta = float(damping_ratio)
        exclude = exclude or {}
        exact, probed = [], []  # (body id, link, kind, local pos, local rot, size, dynamic, mu_b, 1/mass, 1/I_min, nodes out,
        #                            free, principal inertia)
        constrained = _constrained_bodies(client)  # a free body a user constraint holds: its load is measured
        hulls: list = []  # (planes, triangles, their planes, sharp edges, margin [m]) of the HULL rows
        self._hull_probe = -1  # Bullet's point capsule that checks a hull (made on first use)
        for body in bodies:
            for link in range(-1, pb.getNumJoints(body, physicsClientId=client)):
                data = collision_shapes(client, body, link)  # () where PyBullet would crash: a PROBE row
                if not data and not _unlisted_shape(body, link, client):
                    continue  # no collision shape
                out = exclude.get((body, link), exclude.get((body, None), ()))
                if out is None:
                    continue  # excluded: no contact with this link
                info = pb.getDynamicsInfo(body, link, physicsClientId=client)
                mass, mu_b = info[0:2]
                i_min = min(info[2]) if mass > 0.0 else 0.0
                # a link fixed to a fixed base cannot move, whatever mass its URDF gives it: static in the cable's step
                # (as a movable link's condensed contact, a fixture's 0.2 kg peg was 170 times softer at 60 Hz: the
                # cable sank 5 mm into it); still dynamic for Bullet, so its reactions reach its joint sensors
                fixed = mass > 0.0 and link >= 0 and fixed_link(client, body, link)
                # a free body (one dynamic link, no joints) moves in the cable's step (contact.Bodies), with what
                # else holds it (a user constraint, Bullet's contacts) as measured over the last step; the links of
                # an articulated body (an arm) keep the condensed contact (_condense_bodies)
                free = (mass > 0.0 and link < 0 and pb.getNumJoints(body, physicsClientId=client) == 0 and i_min > 0.0
                        and body not in driven)
                inv_m = 1.0 / mass if mass > 0.0 and not fixed else 0.0
                inv_i = 1.0 / i_min if i_min > 0.0 and not fixed else 0.0
                if mass > 0.0 and not fixed and body in driven and (driven[body] is None or link in driven[body]):
                    # a motor-held link: kinematic in the cable's step
                    inv_m = inv_i = DRIVEN_INV_MASS
                common = (mass > 0.0, float(mu_b), inv_m, inv_i, frozenset(out), free, np.asarray(info[2], float))
                hull = (self._hull(body, link, data, radius)
                        if EXACT_HULLS and len(data) == 1 and data[0][2] == pb.GEOM_MESH else None)
                if hull is not None:  # a convex hull Bullet agrees with: the project's exact geometry
                    row = (body, link, HULL, np.zeros(3), np.eye(3), np.array([hull[4], len(hulls), 0.0])) + common
                    hulls.append(hull)
                    (exact if link < 0 else probed).append(row)  # a base link's pose is read every step
                    continue
                if not data or link >= 0 or out or any(d[2] not in _GEOMS for d in data):
                    # a child link (its pose is the link's), a node exclusion or a shape the exact geometry does
                    # not cover: the whole link goes to Bullet's narrow phase (one query answers for all its shapes)
                    probed.append((body, link, PROBE, np.zeros(3), np.eye(3), np.zeros(3)) + common)
                    continue
                for shape in data:
                    geom, dims, lpos, lorn = shape[2], shape[3], shape[5], shape[6]
                    kind = _GEOMS[geom]
                    if kind == BOX:
                        size = 0.5 * np.asarray(dims[:3], float)
                    elif kind == SPHERE:
                        size = np.array([dims[0], 0.0, 0.0])
                    else:  # cylinder, capsule: (length, radius)
                        size = np.array([dims[1], 0.5 * dims[0], 0.0])
                    exact.append((body, -1, kind, np.asarray(lpos, float), _rotation(lorn), size) + common)
        rows = exact + probed  # the exact shapes first: their poses are read every step
        self.rows = rows
        self.n_exact = len(exact)
        self.body_ids = np.array([r[0] for r in rows], dtype=np.int64)
        self.links = np.array([r[1] for r in rows], dtype=np.int64)
        self.dynamic = np.array([r[6] for r in rows], dtype=np.bool_)
        self._any_dynamic = bool(self.dynamic[:self.n_exact].any())
        self._dynamic_exact = np.flatnonzero(self.dynamic[:self.n_exact]).tolist()  # their rows, read every step
        self._dynamic_rows = bool(self.dynamic.any())
        nb = len(rows)
        mu_b = np.array([r[7] for r in rows])
        pairs = [(r[0], r[1]) for r in rows]
        free_bodies = sorted({r[0] for r in rows if r[11]})
        self.free_bodies = free_bodies  # body ids of the free bodies, by slot (contact.Bodies)
        self._inertia_diag = np.array([r[12] for r in rows]).reshape(nb, 3)  # [kg m^2] principal, CoM frame
        # each exact shape's place in its body's base frame: position [m] (k, 3) and rotation (k, 3, 3)
        self._local = (np.array([r[3] for r in exact], float).reshape(-1, 3),
                       np.array([r[4] for r in exact], float).reshape(-1, 3, 3))
        self._frames = None  # set_frames bound to its argument types (at the first pose read)
        self.shapes = Shapes(kind=np.array([r[2] for r in rows], dtype=np.int64), pos=np.zeros((nb, 3)),
                             rot=np.zeros((nb, 3, 3)), size=np.array([r[5] for r in rows]).reshape(nb, 3),
                             com=np.zeros((nb, 3)), lin_vel=np.zeros((nb, 3)), ang_vel=np.zeros((nb, 3)),
                             static_friction=np.sqrt(mu_s * mu_b), dynamic_friction=np.sqrt(mu_d * mu_b),
                             inv_mass=np.array([r[8] for r in rows]), inv_inertia=np.array([r[9] for r in rows]),
                             owner=np.array([pairs.index(pr) for pr in pairs], dtype=np.int64),
                             slot=np.array([free_bodies.index(r[0]) if r[11] else -1 for r in rows], dtype=np.int64),
                             inertia=np.zeros((nb, 3, 3)), impact=np.zeros(nb, np.bool_))
        self._free_slot = self.shapes.slot.copy()  # each row's slot; -1 in shapes.slot while the body is condensed
        self._shared: frozenset = frozenset()  # free bodies another cable touched in the last step
        self._condensed: frozenset = frozenset()  # those of them held by something else too: condensed contact
        self._split: dict[int, int] = {}  # the others, by the number of cables sharing them: in the step (couple)
        self._coupled = False  # bodies.other_mass holds other cables' reactions (held_bodies.couple)
        self._was_supported: frozenset = frozenset()  # the free bodies in a Bullet contact the step before (impacts)
        self._spared: set[int] = set()  # free bodies handed less than the cable felt (held_bodies.spare_thrown)
        # the load on each free body from everything but this cable and gravity, measured over the last Bullet
        # step (see update): its base row, velocity then [m/s, rad/s], the reaction applied in it, the load
        ns = len(free_bodies)
        self._slot_row = np.array([int(np.flatnonzero(self._free_slot == o)[0]) for o in range(ns)], np.int64)
        self._held = frozenset(b for b in free_bodies if b in constrained)
        self._slot_of = {b: o for o, b in enumerate(free_bodies)}
        self._vel_before = np.zeros((ns, 6))
        self._seen = np.zeros(ns, np.bool_)
        self._applied = np.zeros((ns, 6))
        self._inv_dt = np.ones(1)  # [1/s] of the Bullet step planned (a free body's mean reaction, _body_loads)
        self.held_load = np.zeros((ns, 6))  # [N, N m] force and torque about the centre of mass, world frame
        self.support_load = np.zeros((ns, 6))  # [N, N m] the part of it Bullet's contact points pressed (normal)
        self._support: list[list] = [[] for _ in range(ns)]  # those points (held_bodies.measure)
        self._measured: list[int] = []
        self._probe_rows = {pairs[s]: s for s in range(self.n_exact, nb)}
        self._probe_out = np.zeros((nb, n), np.bool_)  # nodes that do not touch a probed link or a hull
        for s in range(nb):
            self._probe_out[s, sorted(rows[s][10])] = True
        self.hulls = _pack_hulls(hulls, [int(r[5][1]) if r[2] == HULL else -1 for r in rows], self.n_exact, n)
        cap_p = 2 * (2 + PROBE_EXTRA) * n * max(1, len(probed))  # (segments: two answers beside the closest)
        self.probes = Probes(count=np.zeros(1, np.int64), shape=np.zeros(cap_p, np.int64),
                             node=np.zeros((cap_p, 2), np.int64), weight=np.zeros(cap_p), point=np.zeros((cap_p, 3)),
                             normal=np.zeros((cap_p, 3)), key=np.zeros(cap_p, np.int64))
        self._radius = float(radius)
        if probed:
            # a node is a capsule of (almost) no length, not a sphere: Bullet answers a sphere against a
            # triangle mesh without the mesh's collision margin (1 mm) but a capsule with it, and the two
            # probes must see the same surface (measured; the 5e-9 m of length shift it by less than that)
            self._sphere = pb.createCollisionShape(pb.GEOM_CAPSULE, radius=radius, height=1e-8,
                                                   physicsClientId=client)
            self._capsule = (pb.createCollisionShape(pb.GEOM_CAPSULE, radius=radius, height=rest_length,
                                                     physicsClientId=client) if rest_length > 0.0 else -1)
            self._cand = (np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros((n, 3)), np.zeros((n, 4)),
                          np.full(n, np.inf))
            self._box = np.zeros((2, 3))
            self._cable_box = np.zeros((2, 3))
            self._reach = None  # _reach_box bound on first use
            self._candidates = None  # _probe_candidates bound on first use
            self._near_set = False  # a probed row's hull is marked near (hulls.near; cleared at the next probe)
            self._prev_rows: set = set()
            self._broad = None  # probe_broad_with bound on first use (native reads only)
            self._broad_pack = None  # _probe_broad's arrays packed (contact_call.BroadArgs), on first use
            self._broad_args = self._native_broad(native, pairs, nb, n) if native else None
        self.keys_per_shape = keys_per_shape(n)
        self.other_cables = list(others)
        n_other = sum(o.model.n for o in self.other_cables)
        nkeys = max(1, nb * self.keys_per_shape + self_keys(n) + (3 * n - 2) * n_other)  # _cable_contacts' keys
        capacity = max(1, nb * (n + 2 * (n - 1)) + 8 * n + 2 * (n * len(self.other_cables) + n_other)
                       + 2 * (1 + PROBE_EXTRA) * n * len(probed)  # a probed link's further answers
                       + (n - 1) * len(hulls))  # a hull's segments: up to three rows each (_hull_contacts)
        # self-contact friction: the cable's own coefficients (negative: no self-contact)
        self.self_mu = np.array([mu_s, mu_d]) if self_contact else np.array([-1.0, -1.0])
        self.contacts: Contacts = make_contacts(n, capacity, radius, grip, section)  # grip: the cable's
        # the free bodies solved with the cable's step (beside the contacts: the contact kernels do not pass them)
        self.bodies: Bodies = make_bodies(n, capacity, len(free_bodies))
        par = pb.getPhysicsEngineParameters(physicsClientId=client)  # the bodies fall by the world's gravity
        self.bodies.gravity[:] = [par["gravityAccelerationX"], par["gravityAccelerationY"],
                                           par["gravityAccelerationZ"]]
        # their own energy check (body_energy.py) and their velocities read after Bullet's last step [m/s, rad/s]
        self.energy_check = BodyEnergy(client, free_bodies, 1.0 / self.shapes.inv_mass[self._slot_row],
                                       self.bodies.gravity)
        self.velocity_now = np.zeros((ns, 6))
        # [m] how far from the nodes' box a free body counts as near (_near_free_bodies): its bounding radius (its
        # box read at set-up), the cable's radius and a spare
        self._near_bound = BOUNDING * self.energy_check.size + self._radius + NEAR_SPARE
        self._near = np.zeros(ns, np.bool_)
        self._near_call = None  # _near_bodies bound on first use
        self.store = Store(anchor=np.zeros((nkeys, 4)), state=np.zeros(nkeys, np.int64),
                           active=np.zeros(nkeys, np.bool_), keys=np.zeros(capacity, np.int64),
                           body=np.zeros(capacity, np.int64), wrap=np.zeros(nkeys, np.bool_),
                           drift=np.zeros((nkeys, 3)), sink=np.zeros(nkeys), depth=np.zeros(nkeys),
                           load=np.zeros(nkeys), stiffness=np.zeros(nkeys))
        first = np.cumsum([0] + [o.model.n for o in self.other_cables]).astype(np.int64)
        mu_o = [(o.model.spec.static_friction, o.model.spec.dynamic_friction) for o in self.other_cables]
        reps = [o.model.n for o in self.other_cables]
        self.others = Others(
            x=np.zeros((n_other, 3)), u=np.zeros((n_other, 3)),
            mass=np.concatenate([o.arrays.mass for o in self.other_cables]) if reps else np.zeros(0),
            radius=np.repeat([o.radius for o in self.other_cables], reps).astype(float),
            static_friction=np.repeat([math.sqrt(mu_s * m[0]) for m in mu_o], reps).astype(float),
            dynamic_friction=np.repeat([math.sqrt(mu_d * m[1]) for m in mu_o], reps).astype(float),
            first=first, vmax=np.zeros(1), row_node=np.zeros((capacity, 2), np.int64),
            row_w=np.zeros((capacity, 2)), row_p0=np.zeros((capacity, 3)))
        self._poses: list = [None] * nb
        for s in range(self.n_exact):
            self._read_pose(s, with_velocity=False)
        # detect()'s and quiet()'s arrays, packed once (contact_call.py: Numba unboxes one pointer a call, not ~80
        # arrays); None where nothing is compiled (NUMBA_DISABLE_JIT): the plain calls
        self._set_args = (make_set_args(self.shapes, self.hulls, self.contacts, self.bodies, self.store, self.others,
                                        self.probes, self._seg_k, self._seg_l, self._seg_b, self._seg_held,
                                        self._probe_out, self.self_mu, self.zeta)
                          if PACK_ARGS and hasattr(detect, "compile") else None)
        self._detect = None  # detect_with (detect on the packed arrays), bound on first use (skips Numba's dispatch)
        self._quiet = None  # quiet_with, bound likewise
        self._deepest = None  # _deepest_dynamic, bound likewise
        self._loads = None  # apply_to_bodies' per-row force, torque and touched rows (made on first use)
        self._inside_reported: set[int] = set()  # bodies already reported holding the cable's centre line
        self._inside_since: dict[int, int] = {}  # body -> consecutive steps it has held the centre line inside
        # native reads of every row's base state (bullet.native), once checked against PyBullet's
        ne = self.n_exact
        self._bases = np.zeros((ne, BASE_STATE))
        self._base_args = (kernel_api(native) if native else None, self.body_ids[:ne].astype(np.int32), self._bases,
                           np.full((ne, 7), np.nan), np.zeros(ne, dtype=np.bool_))
        self._read_bases = bind(read_base_states, *self._base_args) if native and ne and self._native_ok() else None

    def _hull(self, body: int, link: int, data, radius: float):
        """The convex hull of a link's one mesh shape (``getMeshData``'s vertices, link centre-of-mass frame) as
        (planes, triangles, their planes, sharp edges, margin [m]) when Bullet's own distances agree with it at
        check points round it (:func:`_hull_points`, within HULL_CHECK_TOL after one common margin); None
        otherwise (a triangle mesh, a compound of hulls or an unreadable mesh stay with Bullet's narrow phase; a
        scaled mesh's vertices come scaled, and its hull is taken)."""
        cid = self.client
        try:
            count, verts = pb.getMeshData(body, link, physicsClientId=cid)[:2]
        except pb.error:
            return None
        if count < 4:
            return None
        vertices = np.asarray(verts, float).reshape(-1, 3)
        if link < 0:
            com, orn = pb.getBasePositionAndOrientation(body, physicsClientId=cid)
        else:
            com, orn = pb.getLinkState(body, link, physicsClientId=cid)[0:2]
        # the answer is a function of the mesh, its shape data, the link's pose and the radius: the same inputs to
        # the bit give the same hull and margin without the ~200 distance queries
        key = (vertices.tobytes(), repr([shape[2:] for shape in data]), tuple(com), tuple(orn), radius)  # not the body id
        if key not in _HULL_MEMO:
            if len(_HULL_MEMO) >= HULL_MEMO_SIZE:
                _HULL_MEMO.clear()
            _HULL_MEMO[key] = self._checked_hull(body, link, vertices, com, orn, radius)
        return _HULL_MEMO[key]

    def _checked_hull(self, body: int, link: int, vertices: np.ndarray, com, orn, radius: float):
        """:meth:`_hull` computed: the hull of ``vertices`` and its margin if Bullet's distances agree at the check
        points round the link at its pose (``com`` [m], ``orn`` quaternion), else None."""
        cid = self.client
        geo = _hull_geometry(vertices)
        if geo is None or len(geo[1]) > HULL_MAX_FACES:
            return None
        planes, tri, tri_plane, edges = geo
        if self._hull_probe < 0:
            self._hull_probe = pb.createCollisionShape(pb.GEOM_CAPSULE, radius=radius, height=1e-8,
                                                       physicsClientId=cid)
        rot = _rotation(orn)
        points, hu, near = _check_points(vertices, geo, radius)
        at = np.asarray(com, float)
        closest = []
        for p in points:
            res = pb.getClosestPoints(-1, body, 1.0, -1, link, self._hull_probe, -1, (at + rot @ p).tolist(),
                                      physicsClientId=cid)
            if not res:
                return None
            closest.append(min(res, key=_distance))
        offsets = near - radius - np.array([_distance(c) for c in closest])
        on_link = np.array([rot.T @ (np.asarray(c[6]) - at) for c in closest])  # Bullet's closest points on the link
        inside = hull_distances(hu, 0, on_link)
        # Bullet's distance is never below the true one (HULL_GJK_TOL): the margin is the offsets' top, taken as the
        # median of those near it (Bullet's rounding is some 1e-9 m either way)
        agree = offsets.max() - offsets <= HULL_CHECK_TOL
        margin = float(np.median(offsets[agree]))
        if not (0.0 <= margin < 0.05 and agree.mean() >= 0.5 and (margin - offsets).max() <= HULL_GJK_TOL
                and inside.max() <= margin + HULL_CHECK_TOL):
            return None
        return planes, tri, tri_plane, edges, margin

    def _native_ok(self) -> bool:
        if read_base_states(*self._base_args) != self.n_exact:
            return False
        cid = self.client
        for s, body in enumerate(self.body_ids[:self.n_exact].tolist()):
            pose = pb.getBasePositionAndOrientation(body, physicsClientId=cid)
            vel = pb.getBaseVelocity(body, physicsClientId=cid)
            if self._bases[s].tolist() != [*pose[0], *pose[1], *vel[0], *vel[1]]:
                disabled_warning("ContactSet", "a native base read differs from PyBullet's: unknown layout")
                return False
        return True

    def _native_broad(self, native: int, pairs: list, nb: int, n: int) -> tuple | None:
        """The arguments of :func:`_probe_broad` but the step's (x, reach; filled in by :meth:`_probe`), or None
        when Bullet's answers to its native reads differ from PyBullet's here (an unknown layout)."""
        probe_pairs = [(int(b), int(link)) for b, link in self._probe_rows]
        row_of = np.full((max(b for b, _ in probe_pairs) + 1, max(link for _, link in probe_pairs) + 2), -1, np.int64)
        for (b, link), s in self._probe_rows.items():
            row_of[b, link + 1] = s
        nodes, segs, mid, quat, _ = self._cand
        args = [kernel_api(native), self._cable_box, row_of, self.body_ids.copy(), self.links.copy(), np.zeros((1, 3)),
                0.0, self._probe_out, self._capsule >= 0, np.zeros_like(nodes), np.zeros_like(segs), np.zeros_like(mid),
                np.zeros_like(quat), np.zeros(2, np.int64), np.zeros((4096, 2), np.int32), np.zeros(nb, np.bool_),
                np.zeros((nb, 2, 3)), np.zeros(nb, np.int64)]
        # check: every PROBE row's box, and the overlap of a box round all of them, as PyBullet answers them
        cid = self.client
        try:
            boxes = {s: pb.getAABB(self.rows[s][0], self.rows[s][1], physicsClientId=cid)
                     for s in range(self.n_exact, nb)}
        except pb.error:
            return None
        if not boxes:
            return None
        lo = np.min([b[0] for b in boxes.values()], axis=0) - 1.0
        hi = np.max([b[1] for b in boxes.values()], axis=0) + 1.0
        box = np.array([lo, hi])
        args[1], args[5], args[6] = box, np.zeros((1, 3)), 0.0
        hits = pb.getOverlappingObjects(lo.tolist(), hi.tolist(), physicsClientId=cid) or ()
        rows = sorted({self._probe_rows[h] for h in hits if h in self._probe_rows})
        got = _probe_broad(*args)
        if (got < 0 or np.flatnonzero(args[15]).tolist() != rows
                or any(args[16][s].tolist() != [list(boxes[s][0]), list(boxes[s][1])] for s in rows)):
            disabled_warning("ContactSet", "a native overlap or link box differs from PyBullet's: unknown layout")
            return None
        args[1] = self._cable_box
        return tuple(args)

    def _read_pose(self, s: int, with_velocity: bool) -> None:
        body = self.rows[s][0]
        cid = self.client
        pose = pb.getBasePositionAndOrientation(body, physicsClientId=cid)
        if with_velocity:
            lin, ang = pb.getBaseVelocity(body, physicsClientId=cid)
            self.shapes.lin_vel[s] = lin
            self.shapes.ang_vel[s] = ang
        if pose == self._poses[s]:
            return  # not moved: keep the frame
        self._poses[s] = pose
        self._set_pose(s, *pose)

    def _set_pose(self, s: int, com, orn) -> None:
        """Shape ``s``'s frame from its body's base pose: CoM position [m] (3,), quaternion (4,) (:func:`set_frames`
        for this one shape; a free body's base frame is its inertial frame, principal axes)."""
        state = np.zeros((s + 1, 7))
        state[s, :3], state[s, 3:] = com, orn
        moved = np.zeros(s + 1, np.bool_)
        moved[s] = True
        sh = self.shapes
        set_frames(state, moved, *self._local, self._free_slot, self._inertia_diag, sh.com, sh.pos, sh.rot, sh.inertia)

    def _read_poses(self) -> None:
        """Every shape's body pose (velocity too where it moves by dynamics): static bodies too, as a
        script may move them; one compiled call where native reads are on, else two PyBullet calls each."""
        if self._read_bases is None:
            for s in range(self.n_exact):
                self._read_pose(s, with_velocity=bool(self.dynamic[s]))
            return
        bases = self._bases
        if self._read_bases(*self._base_args):  # some pose changed
            sh = self.shapes
            args = (bases, self._base_args[4], *self._local, self._free_slot, self._inertia_diag, sh.com, sh.pos,
                    sh.rot, sh.inertia)
            if self._frames is None:
                self._frames = bind(set_frames, *args)  # (skips Numba's dispatch)
            self._frames(*args)
        lin, ang = self.shapes.lin_vel, self.shapes.ang_vel
        for s in self._dynamic_exact:  # (row by row: a boolean mask's copies cost 9 us a step for one body)
            lin[s] = bases[s, 7:10]
            ang[s] = bases[s, 10:13]

    def update(self, x: np.ndarray, v: np.ndarray, mass: np.ndarray, h: float, dt: float, stepped: bool,
               shared=(), supported=(), support=None, others=None, others_applied=None) -> int:
        """Read the moving bodies, detect the contacts of positions x [m] (n, 3) for a cable step of h [s]
        within a Bullet step of dt [s]; ``stepped``: Bullet has taken the step the last contacts were
        planned for (their work is then counted with the bodies' velocities read now). ``shared``: free bodies another
        cable's contacts also touched in the last step or this one, {body: cables sharing it}: each moves in this
        cable's step (``others``), or keeps the condensed contact (:func:`_condense_bodies`) this step
        (:func:`~bullet_dlo.bullet.held_bodies.sharing`). ``supported``: free bodies Bullet also held in the
        last step (a contact with the ground or another body); they, and the free bodies a user constraint
        holds, move in the cable's step under the load the rest of the world put on them in the last step
        (:meth:`_measure`), ``support`` {body: Bullet's contact points on it} (:attr:`BulletWorld.support_points
        <bullet_dlo.bullet.world.BulletWorld.support_points>`) changing with the body's motion in the step.
        ``others``: the other cables' reactions on the bodies they share with this one, {body: [(impulse, load_mass,
        ref)]} (:meth:`BulletWorld.other_shares <bullet_dlo.bullet.world.BulletWorld.other_shares>`): a shared body
        moves in the step with its whole mass and those reactions (:func:`~bullet_dlo.bullet.held_bodies.couple`)
        where the cable's step is the Bullet step (h == dt), also where something else holds it, else with its share of
        the mass or, held, by the condensed contact. ``others_applied``: {body: the force and torque [N, N m] the other
        cables applied to it in Bullet's last step} (:meth:`BulletWorld.applied_by_others
        <bullet_dlo.bullet.world.BulletWorld.applied_by_others>`), left out of a held body's measured load."""
        coupling = others is not None and h == dt and held_bodies.COUPLE_SHARED
        if self.free_bodies:
            condensed = held_bodies.sharing(self, shared, supported, support or {}, coupling)
            if condensed != self._condensed:  # (a resting body stays shared or not for many steps: no NumPy work)
                self._condensed = condensed
                self.shapes.slot[:] = self._free_slot
                for b in condensed:
                    self.shapes.slot[self.body_ids == b] = -1
        self._read_poses()
        if self.free_bodies and stepped:
            self._mark_impacts(supported)
        if self.other_cables:
            self._read_others(dt)
        if self._probe_rows:
            self._probe(x, v, h, dt)
        # which free bodies are near: for the held ones' loads, and for the quiet test when nothing touched last step
        quiet_last = self.contacts.count.item(0) == 0 and self.probes.count.item(0) == 0
        near = (self._near_free_bodies(x, v, dt) if self.free_bodies and (supported or self._held or quiet_last)
                else None)
        measured = (self._measure(dt, stepped, supported, support or {}, others_applied or {}, near)
                    if self.free_bodies else ())
        self._inv_dt[0] = 1.0 / dt
        packed = self._set_args
        if (SKIP_QUIET and not self.other_cables and quiet_last
                and (not self.free_bodies or (near is not None and not near.any()))):
            # no contact last step, no probed answer, nobody else's rows: detect() would find nothing and change
            # nothing when quiet() says no shape and no pair of segments is within its margin (the same tests)
            if packed is None:
                kernel, qargs = quiet, (x, v, float(h), self.shapes, self.hulls, self.contacts.reach, self.self_mu,
                                        float(dt))
            else:
                kernel, qargs = quiet_with, (packed, x, v, float(h), float(dt))
            if self._quiet is None:
                self._quiet = bind(kernel, *qargs)
            if self._quiet(*qargs):
                return 0
        k_per_mass = self.alpha / (h * h)
        if packed is None:
            kernel, args = detect, (x, v, mass, self.shapes, self.contacts, self.bodies, self.store, float(h),
                                    k_per_mass, self.zeta, self.self_mu, float(dt), float(dt) if stepped else 0.0,
                                    self.others, self.probes, self._seg_k, self._seg_l, self._seg_b, self._seg_held,
                                    self.hulls, self._probe_out)
        else:
            kernel, args = detect_with, (packed, x, v, mass, float(h), k_per_mass, float(dt),
                                         float(dt) if stepped else 0.0)
        if self._detect is None:
            self._detect = bind(kernel, *args)
        count = self._detect(*args)
        if self.free_bodies:
            self.bodies.hold_count[:] = 0
            self.bodies.held_dv[:] = 0.0
            if self._coupled:
                self.bodies.other_mass[:] = 0.0
                self._coupled = False
            if self._split and not coupling:
                held_bodies.share(self)
        if measured:
            self._hold(measured, dt, mass)
        if self._split and coupling:  # (after the held load: the other cables' reactions join its apparent mass)
            held_bodies.couple(self, others, dt)
        if self._any_dynamic and count:
            self._report_bodies_inside(x, count, dt)
        elif self._inside_since:
            self._inside_since.clear()  # (no row: no body holds the centre line)
        return count

    def _mark_impacts(self, supported) -> None:
        """``shapes.impact``: the free bodies in a Bullet contact (``supported``) in the last step and not in the one
        before, a collision the cable's step could not plan."""
        now = frozenset(supported).intersection(self.free_bodies)
        new = now - self._was_supported
        self._was_supported = now
        impact = self.shapes.impact
        if impact.any():
            impact[:] = False
        for b in new:
            impact[self.body_ids == b] = True

    def _measure(self, dt: float, stepped: bool, supported, support: dict, others_applied: dict,
                 near=None) -> list[int]:
        """See :func:`bullet_dlo.bullet.held_bodies.measure`."""
        return held_bodies.measure(self, dt, stepped, supported, support, others_applied, near)

    def _near_free_bodies(self, x: np.ndarray, v: np.ndarray, dt: float) -> np.ndarray:
        """(S,) bool: the free bodies that may come within the cable's reach (x [m], v [m/s], (n, 3)) in the next two
        Bullet steps of dt [s] (:func:`_near_bodies`). Only these have their held load measured, and with none near
        and no contact, detection is skipped where it provably finds nothing (a box lying on the ground 30 cm from
        the cable cost the cable's step 190 us a Bullet step there)."""
        args = (x, v, float(dt), self.shapes.com, self.shapes.lin_vel, self._slot_row, self._near_bound, self._near)
        if self._near_call is None:
            self._near_call = bind(_near_bodies, *args)  # (skips Numba's dispatch)
        self._near_call(*args)
        return self._near

    def _hold(self, measured: list[int], dt: float, mass: np.ndarray) -> None:
        """See :func:`bullet_dlo.bullet.held_bodies.hold`."""
        held_bodies.hold(self, measured, dt, mass)

    def touched_free_bodies(self) -> list[int]:
        """The free bodies (by body id) some contact of the coming step touches."""
        c, st = self.contacts, self.store
        rows = st.body[:int(c.count[0])]
        slots = self._free_slot[rows[rows >= 0]]
        return [self.free_bodies[s] for s in np.unique(slots[slots >= 0]).tolist()]

    def _report_bodies_inside(self, x: np.ndarray, count: int, dt: float) -> None:
        """Warn, once per body, when a dynamic body holds part of the cable's centre line (x [m]) deeper than
        INSIDE_REPORTED radii, or inside it at all for INSIDE_KEPT seconds on end: it went into the cable instead of
        resting on it (a contact too soft for the body at this step of dt [s]); silently the run would go on with a
        body lying through the cable. (A drop's one-step crossing is neither.)"""
        c, st = self.contacts, self.store
        args = (x, c.count, c.node, c.weight, c.normal, c.point, st.body, self.dynamic, st.keys, st.sink)
        if self._deepest is None:
            self._deepest = bind(_deepest_dynamic, *args)
        # one compiled pass over the rows (this check in NumPy cost 28 us a step with a box on the cable); the
        # rows are looked at again below only when one may be inside (the same test in NumPy decides)
        if not self._deepest(*args) > 0.0:
            self._inside_since.clear()
            return
        sink = st.sink[st.keys[:count]]  # the rows' surface points sit that much inside the body (Store)
        rows = st.body[:count]
        k = np.flatnonzero((rows >= 0) & self.dynamic[np.maximum(rows, 0)])
        if k.size == 0:
            return
        p = c.weight[k, 0:1] * x[c.node[k, 0]] + c.weight[k, 1:2] * x[c.node[k, 1]]
        radius = float(c.radius[0])
        depth = sink[k] - np.einsum("ij,ij->i", c.normal[k], p - c.point[k])  # of the centre line inside the body [m]
        inside: dict[int, float] = {}
        for j in np.flatnonzero(depth > 0.0).tolist():
            body = int(self.body_ids[rows[k[j]]])
            inside[body] = max(inside.get(body, 0.0), float(depth[j]))
        self._inside_since = {body: self._inside_since.get(body, 0) + 1 for body in inside}
        for body, deepest in inside.items():
            if body in self._inside_reported:
                continue
            if deepest <= INSIDE_REPORTED * radius and self._inside_since[body] * dt < INSIDE_KEPT - 1e-9 * dt:
                continue
            self._inside_reported.add(body)
            warnings.warn(f"body {body} holds the cable's centre line {1e3 * deepest:.2f} mm inside "
                          f"it: it went into the cable instead of resting on it (its contacts are too soft for its "
                          f"mass and inertia at dt = {dt:.4g} s; bodies rest on the cable at dt <= 1/240 s, see "
                          "docs/concepts/contact.md, 'Bodies resting on the cable')", RuntimeWarning, stacklevel=2)

    def _read_link(self, s: int) -> None:
        """PROBE row ``s``: its link's centre-of-mass frame and velocity now (the arms move every step)."""
        body, link = self.rows[s][0:2]
        cid, sh = self.client, self.shapes
        if link < 0:
            com, orn = pb.getBasePositionAndOrientation(body, physicsClientId=cid)
            lin, ang = pb.getBaseVelocity(body, physicsClientId=cid)
        else:
            st = pb.getLinkState(body, link, 1, 1, physicsClientId=cid)
            com, orn, lin, ang = st[0], st[1], st[6], st[7]
        sh.com[s] = sh.pos[s] = com
        sh.rot[s] = _rotation(orn)
        if self._free_slot[s] >= 0:
            sh.inertia[s] = (sh.rot[s] * self._inertia_diag[s]) @ sh.rot[s].T
        sh.lin_vel[s] = lin
        sh.ang_vel[s] = ang

    def _probe_sweep(self, dt: float) -> float:
        """Twice the farthest [m] a point of a free body measured by Bullet's narrow phase (its PROBE rows) moves in a
        Bullet step of dt [s], 2 dt (|U| + |Omega| R), R [m] its box's half diagonal plus the box centre's offset from
        the centre of mass (as :func:`_sweep` for the other rows): the largest over those bodies. A duck thrown at the
        cable at 3 m/s (60 Hz: 50 mm a step, 3 mm of margin) was met 3.6 mm inside it."""
        cid, sweep = self.client, 0.0
        for s in np.flatnonzero(self._free_slot[self.n_exact:] >= 0).tolist():
            body = int(self.body_ids[self.n_exact + s])
            lin, ang = pb.getBaseVelocity(body, physicsClientId=cid)
            u, w = math.hypot(*lin), math.hypot(*ang)
            if u == 0.0 and w == 0.0:
                continue
            lo, hi = (np.asarray(b) for b in pb.getAABB(body, -1, physicsClientId=cid))
            com = np.asarray(pb.getBasePositionAndOrientation(body, physicsClientId=cid)[0])
            extent = 0.5 * float(np.linalg.norm(hi - lo)) + float(np.linalg.norm(0.5 * (lo + hi) - com))
            sweep = max(sweep, 2.0 * dt * (u + w * extent))
        return sweep

    def _probe(self, x: np.ndarray, v: np.ndarray, h: float, dt: float) -> None:
        """Bullet's closest points between the cable and the PROBE links within reach, into ``self.probes``.

        Broad phase: one ``getOverlappingObjects`` with the cable's box grown by the reach (nothing else
        while no probed link is near), then each hit link's box against each node's and segment's. Narrow
        phase: ``getClosestPoints`` of a point capsule of the cable radius at each node, and of a capsule of the
        cable radius and rest length along each segment, against the link, within the margin (the same
        as :func:`detect`'s). A node keeps the link's closest point; a segment only where it comes closer
        to the link between its nodes than at them (by SEGMENT_DIP) at an interior point (S_MIN < s <
        1 - S_MIN): elsewhere the nodes carry the contact, as on the primitives' faces. Bullet answers a
        triangle mesh triangle by triangle: besides the closest answer, answers whose normals differ from every
        closer one's by more than 30 degrees and whose points rise above the closest answer's plane are contacts
        of their own (:func:`_distinct`; a node or segment in a concave corner meets each of its faces or edges),
        each with its own friction key (:func:`_probe_key`); a segment also keeps the closest answer facing the same
        way on either side of its closest one (:func:`_beside`: the next ridges of a faceted curve)."""
        pr = self.probes
        pr.count[0] = 0
        cable_box = self._cable_box
        args = (x, v, float(self.contacts.reach[0]), h, cable_box)  # (a flat section reaches further)
        if self._reach is None:
            self._reach = bind(_reach_box, *args)
        margin = self._reach(*args)
        sweep = self._probe_sweep(dt) if self.free_bodies else 0.0
        if sweep > 0.0:  # a free body's motion over the Bullet step widens the margin, as _sweep does for the others
            margin += sweep
            cable_box[0] -= sweep
            cable_box[1] += sweep
        reach = self._radius + margin
        cid = self.client
        rows = None
        broad = self._broad_args
        if broad is not None:  # the rows whose boxes meet no node or segment are left out here
            if PACK_ARGS and hasattr(_probe_broad, "compile"):  # packed once (contact_call.py)
                if self._broad_pack is None:
                    self._broad_pack = make_broad_args(*broad[:5], *broad[7:])
                kernel, args = probe_broad_with, (self._broad_pack, x, reach)
            else:  # (nothing compiled, or the plain call asked for)
                kernel, args = _probe_broad, broad[:5] + (x, reach) + broad[7:]
            if self._broad is None:
                self._broad = bind(kernel, *args)
            nt = self._broad(*args)
            if nt >= 0:
                rows = set(broad[-1][:nt].tolist())
        if rows is None:
            lo, hi = cable_box.tolist()
            hits = pb.getOverlappingObjects(lo, hi, physicsClientId=cid) or ()
            rows = set(map(self._probe_rows.get, hits))  # (a hit that is no PROBE row: None)
            rows.discard(None)
        k_prev = int(self.contacts.count[0])
        prev = self.store.body[:k_prev]
        self._prev_rows = {int(r) for r in np.unique(prev[prev >= self.n_exact])} if k_prev else set()
        rows |= self._prev_rows  # the links touched last step: their velocity now, for the work check
        near = self.hulls.near
        if self._near_set:  # a child link's hull: its pose is read below when it is near
            near[self.n_exact:] = False
            self._near_set = False
        if not rows:
            return
        nodes, segs, mid, quat, dist = self._cand
        closest = pb.getClosestPoints
        sphere, capsule = self._sphere, self._capsule
        box = self._box
        found = []  # (row, node a, node b, weight of b, point, normal, key)
        n = len(x)
        xl = None
        kinds = self.shapes.kind
        for s in sorted(rows):
            body, link = self.rows[s][0:2]
            box[0], box[1] = pb.getAABB(body, link, physicsClientId=cid)
            args = (x, box, reach, self._probe_out[s], capsule >= 0, nodes, segs, mid, quat)
            if self._candidates is None:
                self._candidates = bind(_probe_candidates, *args)
            nn, ns = self._candidates(*args)
            if nn == 0 and ns == 0 and s not in self._prev_rows:
                continue  # only its box was near (a gripper around an excluded end)
            self._read_link(s)
            if kinds[s] == HULL:  # on the exact geometry in detect(), with its pose now
                near[s] = True
                self._near_set = True
                continue
            xl = x.tolist() if xl is None else xl
            shift = self._material_shift(s, x, v, h) if self._free_slot[s] >= 0 else None
            dist[:] = margin
            for i in nodes[:nn].tolist():
                res, at = self._closest_on(body, link, margin, sphere, xl[i], _UNTURNED, shift, (i,))
                if res:
                    answers = _distinct(res)
                    dist[i] = answers[0][8]
                    keys = set()
                    for e, best in enumerate(answers):
                        key = _probe_key(n, i, False, e > 0, best[7])
                        if key not in keys:  # two further answers in one direction: the closer one
                            keys.add(key)
                            found.append((s, i, i, 0.0, best[6], best[7], key))
            for i, m, q in zip(segs[:ns].tolist(), mid[:ns].tolist(), quat[:ns].tolist()):
                res, at = self._closest_on(body, link, margin, capsule, m, q, shift, (i, i + 1))
                if not res:
                    continue
                keys = set()
                xa, xb, r = xl[i], xl[i + 1], self._radius
                answers = _distinct(res)
                answered = [(best, _along(best, at, xa, xb, r), _probe_key(n, i, True, e > 0, best[7]))
                        for e, best in enumerate(answers)]
                s_first = answered[0][1]
                apart = r / max(math.dist(xa, xb), 1e-12)  # a cable radius along the segment
                answered += [(best, sp, _beside_key(n, i, after))
                         for best, sp, after in _beside(res, answers[0], s_first, apart, at, xa, xb, r)]
                for best, sp, key in answered:
                    if best[8] > min(dist[i], dist[i + 1]) - SEGMENT_DIP:
                        continue  # no closer between the nodes than at them: the nodes carry it
                    if S_MIN < sp < 1.0 - S_MIN and key not in keys:
                        keys.add(key)
                        found.append((s, i, i + 1, sp, best[6], best[7], key))
        k = min(len(found), pr.shape.shape[0])
        if k:
            row, a, b, w, point, normal, key = zip(*found[:k])
            pr.shape[:k], pr.node[:k, 0], pr.node[:k, 1], pr.weight[:k] = row, a, b, w
            pr.point[:k], pr.normal[:k], pr.key[:k] = point, normal, key
        pr.count[0] = k

    def _material_shift(self, s: int, x: np.ndarray, v: np.ndarray, h: float) -> np.ndarray | None:
        """How far [m] (n, 3) each node's end after a step of h [s] (x + h v; x [m], v [m/s] (n, 3)) lies from its start
        in PROBE row ``s``'s body's material at the step's start, if the body moves on at its velocity now (None when
        it is at rest): the step moves a row's point linearly, p + h (U + Omega x (p - c)), and this inverts that map
        (I + h [Omega]x) (:meth:`_closest_on`)."""
        sh = self.shapes
        u, w = sh.lin_vel[s], sh.ang_vel[s]
        if not (u.any() or w.any()):
            return None
        a = np.eye(3)
        a[0, 1], a[0, 2], a[1, 2] = -h * w[2], h * w[1], -h * w[0]
        a[1, 0], a[2, 0], a[2, 1] = h * w[2], -h * w[1], h * w[0]
        c = sh.com[s]
        return c + np.linalg.solve(a, (x + h * v - c - h * u).T).T - x

    def _closest_on(self, body: int, link: int, margin: float, shape: int, pos, orn, shift, nodes) -> tuple:
        """Bullet's closest points of the cable's ``shape`` (a node's sphere or a segment's capsule, at ``pos``,
        ``orn``) on the link within ``margin`` [m], and the query's offset [m] (3,) from ``pos``. On a moving free body
        (``shift`` (n, 3), :meth:`_material_shift`) asked again where the body's material will meet the ``nodes``
        at the step's end, less their approach along the first answer's normal: the row's point, moved with the body
        in the step, then ends next to the node however the body turns. (From the start pose, the duck of
        tests/bullet/test_contact_compound.py turning 0.19 rad a step at 60 Hz moved its closest point 5 mm along its
        surface from the node, and the row's plane, which does not turn, let the node end 0.9 mm inside it. The
        approach is left out: a body thrown at the cable 50 mm a step would be asked from deep inside, where the
        nearest face need not be the one that meets the cable.) The linear move's own error is an outward dilation by
        (h |Omega|)^2 / 2 of the arm: the row stops the node a little early."""
        closest, cid = pb.getClosestPoints, self.client
        res = closest(-1, body, margin, -1, link, shape, -1, pos, _ORIGIN, orn, physicsClientId=cid)
        if not res or shift is None:
            return res, _ORIGIN
        d = shift[list(nodes)].mean(axis=0)
        normal = min(res, key=_distance)[7]
        d -= (d @ normal) * np.asarray(normal)
        if not d.any():
            return res, _ORIGIN
        at = d.tolist()
        moved = closest(-1, body, margin, -1, link, shape, -1, [p + q for p, q in zip(pos, at)], _ORIGIN, orn,
                        physicsClientId=cid)
        return (moved, at) if moved else (res, _ORIGIN)

    def _read_others(self, dt: float) -> None:
        """The other cables now: a cable that has planned its coming step already (it stepped before this
        one in the world's phase 7, or outside it) moves over the step as planned (u = (x' - x)/dt);
        one still to step is held where it is (u = 0). See :class:`BulletCable` and docs/concepts/contact.md."""
        o = self.others
        pending = getattr(self.other_cables[0].world, "_pending", ())
        vmax = 0.0
        for idx, cab in enumerate(self.other_cables):
            a0, a1 = o.first[idx], o.first[idx + 1]
            cp = cab._cp
            if cab.name in pending:
                o.x[a0:a1] = cp.x_new
                o.u[a0:a1] = 0.0
                vmax = max(vmax, float(np.abs(cp.v_new).max()))
            else:
                o.x[a0:a1] = cp.x
                np.subtract(cp.x_new, cp.x, out=o.u[a0:a1])
                o.u[a0:a1] /= dt
                vmax = max(vmax, float(np.abs(cp.v).max()), float(np.abs(o.u[a0:a1]).max()))
        o.vmax[0] = vmax

    def per_contact(self, x: np.ndarray) -> dict[str, np.ndarray]:
        """The current contacts (forces of the last step, on the cable [N]): body, link (-1: the base), node (k, 2),
        weight (k, 2), point [m] (k, 3), normal (k, 3), gap [m] (k,) at positions x (negative:
        penetration), normal_force (k,), friction (k, 3), force (k, 3) = normal_force normal +
        friction, sliding (k,) bool."""
        c = self.contacts
        k = int(c.count[0])
        fn = c.f_n[:k].clip(min=0.0)
        idx, w = c.node[:k], c.weight[:k]
        p = w[:, :1] * x[idx[:, 0]] + w[:, 1:] * x[idx[:, 1]]
        gap = np.einsum("kj,kj->k", c.normal[:k], p - c.point[:k]) - c.radius[0]
        shape = self.store.body[:k]
        body = np.where(shape >= 0, self.body_ids[np.maximum(shape, 0)] if len(self.body_ids) else -1,
                        np.where(shape == CABLE, CABLE, -1))
        link = np.where(shape >= 0, self.links[np.maximum(shape, 0)] if len(self.links) else -1, -1)
        return {"body": body, "link": link, "node": c.node[:k].copy(), "gap": gap,
                "weight": c.weight[:k].copy(), "point": c.point[:k].copy(), "normal": c.normal[:k].copy(),
                "normal_force": fn, "friction": c.f_t[:k].copy(),
                "force": fn[:, None] * c.normal[:k] + c.f_t[:k], "sliding": c.state[:k] != STICK}

    def per_body(self, x: np.ndarray) -> dict[int, np.ndarray]:
        """Total force [N] the cable exerts on each touched body, {body id: (3,)}."""
        out: dict[int, np.ndarray] = {}
        pc = self.per_contact(x)
        for b, f in zip(pc["body"].tolist(), pc["force"]):
            if b >= 0:  # -1: the cable on itself
                out[b] = out.get(b, np.zeros(3)) - f
        return out

    def apply_to_bodies(self) -> None:
        """Apply the reaction of every contact to its dynamic body (force at the centre of mass plus
        the torque of the forces about it), for the coming Bullet step."""
        c = self.contacts
        if self.free_bodies:
            self._applied[:] = 0.0
        if int(c.count[0]) == 0 or not self._dynamic_rows:
            return
        if self._loads is None:
            nb = len(self.rows)
            self._loads = (c.count, c.f_n, c.f_t, c.normal, c.point, self.bodies.slot, self.store.body, self.dynamic,
                           self.shapes.com, self.bodies.impulse, self._inv_dt, np.zeros((nb, 3)), np.zeros((nb, 3)),
                           np.zeros(nb, np.int64))
            self._body_loads = bind(_body_loads, *self._loads)  # skips Numba's dispatch (10 us on a Contacts)
        force, torque, touched = self._loads[-3:]
        count = self._body_loads(*self._loads)
        cid = self.client
        apply, twist, frame = pb.applyExternalForce, pb.applyExternalTorque, pb.WORLD_FRAME
        for s in touched[:count].tolist():
            body, link = int(self.body_ids[s]), int(self.links[s])
            apply(body, link, force[s].tolist(), self.shapes.com[s].tolist(), frame, cid)
            twist(body, link, torque[s].tolist(), frame, cid)
            o = self._free_slot[s]
            if o >= 0:  # what this cable applied to a free body (see _measure)
                self._applied[o, :3] += force[s]
                self._applied[o, 3:] += torque[s]


@njit(cache=True, error_model="numpy")
def _deepest_dynamic(x, count, node, weight, normal, point, body, dynamic, keys, sink):
    """The largest depth [m] of the cable's centre line (x [m], (n, 3)) inside a dynamic body over the first
    count[0] contact rows (node, weight, normal, point of the Contacts; body: their Shapes rows, -1 for none;
    dynamic: per Shapes row; keys, sink: the Store's, the rows' surface points sit sink[keys[k]] [m] inside the
    body); -inf without such a row."""
    deepest = -np.inf
    for k in range(count[0]):
        s = body[k]
        if s < 0 or not dynamic[s]:
            continue
        a, b = node[k, 0], node[k, 1]
        d = sink[keys[k]]
        for j in range(3):
            d -= normal[k, j] * (weight[k, 0] * x[a, j] + weight[k, 1] * x[b, j] - point[k, j])
        deepest = max(deepest, d)
    return deepest


@njit(cache=True, error_model="numpy")
def _body_loads(count, f_n, f_t, normal, point, slot, body, dynamic, com, impulse, inv_dt, force, torque, touched):
    """The contacts' reactions summed per dynamic Shapes row: force (B, 3) [N] and torque about its centre of mass
    com (B, 3) [N m]; touched <- the rows touched, in increasing order; returns their count. The first count[0]
    contact rows: the Contacts' f_n, f_t, normal, point and the Bodies' slot (only these arrays: a whole Contacts
    is 37 arrays to unbox at every call). A free body (its rows' slot >= 0) gets the mean of the reactions its
    step solved with over the Bullet step, the Bodies' impulse times inv_dt[0] [1/s] (the damper may pull): a
    step taken again as sub-steps has a force per sub-step, and the last one's alone left a leaning 30 g box
    40 mN short for a whole step (docs/concepts/contact.md). (One compiled pass: NumPy's per-call cost on these
    few rows was 50 us a step.) A body of several Shapes rows (the mesh-clip part: three boxes) has one slot:
    its mean goes to the first of its rows touched, the others get none of it (handed to each, the part on the
    cord got 3 times its reaction whenever bar and legs touched: carried at 0.395 of its weight)."""
    nb = force.shape[0]
    used = np.zeros(nb, np.bool_)
    given = np.zeros(impulse.shape[0], np.bool_)
    for k in range(count[0]):
        s = body[k]
        if s < 0 or not dynamic[s]:
            continue
        o = slot[k]
        if not used[s]:
            used[s] = True
            for j in range(3):
                force[s, j] = 0.0
                torque[s, j] = 0.0
        if o >= 0:  # a free body: its mean reaction, once
            if not given[o]:
                given[o] = True
                for j in range(3):
                    force[s, j] += impulse[o, j] * inv_dt[0]
                    torque[s, j] += impulse[o, 3 + j] * inv_dt[0]
            continue
        fn = max(f_n[k], 0.0)
        a0, a1, a2 = point[k, 0] - com[s, 0], point[k, 1] - com[s, 1], point[k, 2] - com[s, 2]
        f0 = -(fn * normal[k, 0] + f_t[k, 0])
        f1 = -(fn * normal[k, 1] + f_t[k, 1])
        f2 = -(fn * normal[k, 2] + f_t[k, 2])
        force[s, 0] += f0
        force[s, 1] += f1
        force[s, 2] += f2
        torque[s, 0] += a1 * f2 - a2 * f1
        torque[s, 1] += a2 * f0 - a0 * f2
        torque[s, 2] += a0 * f1 - a1 * f0
    count = 0
    for s in range(nb):
        if used[s]:
            touched[count] = s
            count += 1
    return count


# ----- detection kernel --------------------------------------------------------------------------
@njit(cache=True, error_model="numpy", inline="always")
def _normal_from(q, c, out_n):
    """Unit vector from surface point ``c`` to the outside point ``q`` into ``out_n``; returns |q - c| [m]."""
    d2 = 0.0
    for j in range(3):
        out_n[j] = q[j] - c[j]
        d2 += out_n[j] ** 2
    dl = math.sqrt(d2)
    for j in range(3):
        out_n[j] /= dl
    return dl


@njit(cache=True, error_model="numpy")
def _node_closest(kind, size, q, out_c, out_n):
    """Closest surface point out_c and outward normal out_n (shape frame) to point q; returns the
    signed distance [m] (negative inside)."""
    if kind == BOX:
        inside = True
        for j in range(3):
            out_c[j] = min(max(q[j], -size[j]), size[j])
            if q[j] < -size[j] or q[j] > size[j]:
                inside = False
        if inside:  # nearest face
            best = 1e300
            for j in range(3):
                for sg in (-1.0, 1.0):
                    dist = size[j] - sg * q[j]
                    if dist < best:
                        best = dist
                        out_n[:] = 0.0
                        out_n[j] = sg
            for j in range(3):
                out_c[j] = q[j] + best * out_n[j]
            return -best
        return _normal_from(q, out_c, out_n)
    R = size[0]
    if kind == SPHERE or kind == CAPSULE:
        t = 0.0 if kind == SPHERE else min(max(q[2], -size[1]), size[1])
        d0, d1, d2 = q[0], q[1], q[2] - t
        dl = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if dl == 0.0:
            return 1e300
        out_n[0], out_n[1], out_n[2] = d0 / dl, d1 / dl, d2 / dl
        for j in range(3):
            out_c[j] = R * out_n[j]
        out_c[2] += t
        return dl - R
    # cylinder, axis z, half length size[1]
    hl = size[1]
    rho = math.sqrt(q[0] * q[0] + q[1] * q[1])
    sz = 1.0 if q[2] >= 0.0 else -1.0
    side = rho - R
    cap = abs(q[2]) - hl
    if side <= 0.0 and cap <= 0.0:  # inside: the nearer of side and cap
        if side >= cap and rho > 0.0:
            out_n[0], out_n[1], out_n[2] = q[0] / rho, q[1] / rho, 0.0
            out_c[0], out_c[1], out_c[2] = R * out_n[0], R * out_n[1], q[2]
            return side
        out_n[0], out_n[1], out_n[2] = 0.0, 0.0, sz
        out_c[0], out_c[1], out_c[2] = q[0], q[1], sz * hl
        return cap
    if cap <= 0.0:  # beside the mantle
        out_n[0], out_n[1], out_n[2] = q[0] / rho, q[1] / rho, 0.0
        out_c[0], out_c[1], out_c[2] = R * out_n[0], R * out_n[1], q[2]
        return side
    if side <= 0.0:  # above a flat end
        out_n[0], out_n[1], out_n[2] = 0.0, 0.0, sz
        out_c[0], out_c[1], out_c[2] = q[0], q[1], sz * hl
        return cap
    out_c[0], out_c[1], out_c[2] = R * q[0] / rho, R * q[1] / rho, sz * hl  # the rim
    return _normal_from(q, out_c, out_n)


@njit(cache=True, error_model="numpy")
def _segment_axis(qa, qb, P, A, hl, R, out_c, out_n):
    """Segment qa-qb against a capped line P + t A (|t| <= hl) of radius R (shape frame): the interior
    parameter s of the closest point (or -1 if not interior / out of range); fills surface point and normal;
    the distance goes to out_c[3]."""
    e0, e1, e2 = qb[0] - qa[0], qb[1] - qa[1], qb[2] - qa[2]
    w0, w1, w2 = qa[0] - P[0], qa[1] - P[1], qa[2] - P[2]
    a = e0 * e0 + e1 * e1 + e2 * e2
    b = e0 * A[0] + e1 * A[1] + e2 * A[2]
    d = e0 * w0 + e1 * w1 + e2 * w2
    ee = A[0] * w0 + A[1] * w1 + A[2] * w2
    den = a - b * b
    if den <= 1e-12 * a:
        return -1.0
    s = (b * ee - d) / den
    t = (w0 + s * e0) * A[0] + (w1 + s * e1) * A[1] + (w2 + s * e2) * A[2]
    if abs(t) > hl:  # beyond the end: closest point of the segment to the end point
        t = hl if t > 0.0 else -hl
        s = ((P[0] + t * A[0] - qa[0]) * e0 + (P[1] + t * A[1] - qa[1]) * e1 + (P[2] + t * A[2] - qa[2]) * e2) / a
    if s <= S_MIN or s >= 1.0 - S_MIN:
        return -1.0
    r2 = 0.0
    for j in range(3):
        out_n[j] = qa[j] + s * (qb[j] - qa[j]) - (P[j] + t * A[j])
        r2 += out_n[j] ** 2
    rl = math.sqrt(r2)
    if rl == 0.0:
        return -1.0
    for j in range(3):
        out_n[j] /= rl
        out_c[j] = P[j] + t * A[j] + R * out_n[j]
    out_c[3] = rl - R
    return s


@njit(cache=True, error_model="numpy")
def _cylinder_side(qa, qb, s, R, hl) -> int:
    """Which face of an upright cylinder (axis z, radius R [m], half length hl [m], shape frame) segment qa-qb
    presses, given :func:`_segment_axis`'s interior parameter s (-1: none): 0, the mantle, where the segment's point s
    lies beside it or inside nearer to it; else the flat end it is near, +1 (top) or -1 (bottom), whose rows are
    :func:`_rim_row`'s. (Everything inside was the mantle's before: a cylinder standing on a cable had the segment
    under its flat end pushed sideways by up to R, a 3 kg one shoved 9 mm and tipped, a 10 kg one stopped as energy
    growth, a puck between two nodes of a coarse cable pushed through it.)"""
    if s > 0.0:
        p0, p1, p2 = qa[0] + s * (qb[0] - qa[0]), qa[1] + s * (qb[1] - qa[1]), qa[2] + s * (qb[2] - qa[2])
        rho = math.sqrt(p0 * p0 + p1 * p1)
        cap = abs(p2) - hl  # [m] beyond the flat end (> 0) or inside (< 0)
        if cap < 0.0 and (rho >= R or R - rho <= -cap):
            return 0
        return 1 if p2 >= 0.0 else -1
    return 1 if qa[2] + qb[2] >= 0.0 else -1


@njit(cache=True, error_model="numpy")
def _rim_row(qa, qb, R, hl, sz, end, out_c, out_n):
    """The flat end sz (+1 top, -1 bottom) of an upright cylinder (as :func:`_cylinder_side`) against segment qa-qb
    where the segment's chord over the end's disk meets the rim: its entry (end 0) or exit (end 1). Fills the row's
    surface point (above the segment's point, on the end face) and normal (+-z) and its distance beyond the face into
    out_c[3]; returns the segment's parameter there, or -1 where that chord end is a node (over the disk: its own row
    carries it, as nodes on a box's face) or the segment misses the disk. The rim takes the segment as a box's edge
    does: a level segment under a level end rests on both chord ends, a tilted end digs in at one."""
    d0, d1 = qb[0] - qa[0], qb[1] - qa[1]
    a = d0 * d0 + d1 * d1
    b = qa[0] * d0 + qa[1] * d1
    disc = b * b - a * (qa[0] * qa[0] + qa[1] * qa[1] - R * R)
    if a <= 0.0 or disc <= 0.0:
        return -1.0  # along the axis, or off the disk
    root = math.sqrt(disc)
    t = (-b - root) / a if end == 0 else (-b + root) / a
    if t <= S_MIN or t >= 1.0 - S_MIN:
        return -1.0
    q2 = qa[2] + t * (qb[2] - qa[2])
    out_n[0], out_n[1], out_n[2] = 0.0, 0.0, float(sz)
    out_c[0], out_c[1], out_c[2], out_c[3] = qa[0] + t * d0, qa[1] + t * d1, sz * hl, sz * q2 - hl
    return t


@njit(cache=True, error_model="numpy", inline="always")  # (~45 arrays: 2 us a row called, under Numba's own pipeline)
def _add(c, st, key, shape, ia, ib, wa, wb, cl, nl, sh, k_per_mass, zeta, mass, x):
    """Append a contact (surface point cl, normal nl in the shape frame) unless the arrays are full."""
    k = c.count[0]
    if k < c.node.shape[0]:  # (not an early return: the tuples' last uses must follow every branch)
        for j in range(3):
            c.point[k, j] = (sh.pos[shape, j] + sh.rot[shape, j, 0] * cl[0] + sh.rot[shape, j, 1] * cl[1]
                             + sh.rot[shape, j, 2] * cl[2])
            c.normal[k, j] = sh.rot[shape, j, 0] * nl[0] + sh.rot[shape, j, 1] * nl[1] + sh.rot[shape, j, 2] * nl[2]
        _add_row(c, st, key, shape, ia, ib, wa, wb, sh, k_per_mass, zeta, mass, x)
    _last_use = c, st, sh, mass, x, cl, nl  # (a last use after the branches: tests/llvm_loops.py)


@njit(cache=True, error_model="numpy", inline="always")  # (~45 arrays: 2 us a row called, under Numba's own pipeline)
def _add_row(c, st, key, shape, ia, ib, wa, wb, sh, k_per_mass, zeta, mass, x):
    """The rest of row count[0] once its world point and normal are set: the body's velocity there, the law."""
    k = c.count[0]
    # scalars, not array temporaries: each costs an allocation and reference counts per contact
    a0, a1, a2 = c.point[k, 0] - sh.com[shape, 0], c.point[k, 1] - sh.com[shape, 1], c.point[k, 2] - sh.com[shape, 2]
    w0, w1, w2 = sh.ang_vel[shape, 0], sh.ang_vel[shape, 1], sh.ang_vel[shape, 2]
    c.body_vel[k, 0] = sh.lin_vel[shape, 0] + w1 * a2 - w2 * a1
    c.body_vel[k, 1] = sh.lin_vel[shape, 1] + w2 * a0 - w0 * a2
    c.body_vel[k, 2] = sh.lin_vel[shape, 2] + w0 * a1 - w1 * a0
    c.internal[k] = False
    mk = wa * mass[ia] + wb * mass[ib]  # stiffness by the mass at the contact point
    _fill(c, st, key, shape, ia, ib, wa, wb, sh.static_friction[shape], sh.dynamic_friction[shape], k_per_mass * mk, zeta, mk, x)
    if sh.impact[shape]:
        _sink_unplanned(c, st, key, k, x)
    _last_use = c, st, sh, mass, x  # (a last use after the branches: tests/llvm_loops.py)


@njit(cache=True, error_model="numpy", inline="always")
def _sink_unplanned(c, st, key, k, x):
    """Row k (``key``) of a body in a collision in Bullet's last step (Shapes.impact): what it starts inside the cable
    beyond the depth the last step planned for it (Store.depth; 0 for a new row) goes into the sink, the row's surface
    point that much further inside the body (let out over SINK_TIME, as :func:`detect`'s sink). The detector's sink
    estimates the unplanned move from the row's last point and normal; a 3 kg box whose corner Bullet bounced off the
    ground turned 1.3 mm into the cable at a row planned 9.6 mm outside, which that misses, and the penalty handed the
    box 0.11 J (stopped as energy growth at 0.13 s)."""
    g = _gap(c, k, x)
    extra = -g - st.depth[key]
    if extra > 0.0:
        _to_sink(c, st, k, extra)
        g += extra
        c.cap[k] = c.static_friction[k] * c.k_n[k] * (-g) if g < 0.0 else 0.0
    _last_use = c, st, x  # (a last use after the branches: tests/llvm_loops.py)


@njit(cache=True, error_model="numpy", inline="always")  # (~45 arrays: 2 us a row called, under Numba's own pipeline)
def _fill(c, st, key, shape, ia, ib, wa, wb, mu_s, mu_d, k_n, zeta, mk, x):
    """The rest of row count[0] (point, normal, body velocity set): nodes, stiffness k_n [N/m] (damping
    ratio zeta for the mass mk [kg]), friction, friction state."""
    k = c.count[0]
    c.kind[k] = PENALTY
    c.node[k, 0], c.node[k, 1] = ia, ib
    c.weight[k, 0], c.weight[k, 1] = wa, wb
    c.k_n[k] = k_n
    c.k_t[k] = k_n
    c.c_n[k] = 2.0 * zeta * math.sqrt(c.k_n[k] * mk)
    c.static_friction[k] = mu_s
    c.dynamic_friction[k] = mu_d
    if st.active[key]:
        for j in range(4):
            c.anchor[k, j] = st.anchor[key, j]
        c.state[k] = st.state[key]
    else:
        for j in range(3):
            c.anchor[k, j] = wa * x[ia, j] + wb * x[ib, j]
        c.anchor[k, 3] = wb
        c.state[k] = STICK
        for j in range(3):
            st.drift[key, j] = 0.0
        st.sink[key] = 0.0
        st.depth[key] = 0.0
    o = st.sink[key]
    if o > 0.0:  # the surface point that much inside the body: the penetration its unplanned moves made, let out slowly
        for j in range(3):
            c.point[k, j] -= o * c.normal[k, j]
    g = 0.0
    for j in range(3):
        g += c.normal[k, j] * (wa * x[ia, j] + wb * x[ib, j] - c.point[k, j])
    g -= c.radius[0]
    c.cap[k] = c.static_friction[k] * c.k_n[k] * (-g) if g < 0.0 else 0.0
    c.f_n[k] = 0.0
    c.f_t[k, 0], c.f_t[k, 1], c.f_t[k, 2] = 0.0, 0.0, 0.0
    st.keys[k] = key
    st.body[k] = shape
    c.count[0] = k + 1


@njit(cache=True, error_model="numpy", inline="always")
def _taut(x, i, ks, l0, kb):
    """Whether segment i's tension T [N] bends the cable at an edge within the segment: its bend length
    sqrt(EI / T) below the segment's length l0, T l0 > k_b (k_b = EI / l0, the larger of its nodes'). Then
    the chain cannot bend round the edge itself and the segment wraps it; a slack or short segment keeps the
    chain's own bends (a cable's overhang over a box edge stands on them)."""
    d = 0.0
    for j in range(3):
        d += (x[i + 1, j] - x[i, j]) ** 2
    return ks * (math.sqrt(d) - l0) * l0 > max(kb[i], kb[i + 1]) and kb[i] + kb[i + 1] > 0.0


@njit(cache=True, error_model="numpy")
def _make_wrap(c, k, axis, side, ks, l0, kb_a, kb_b, edge_r, fresh, x):
    """Turn row k (a segment's capsule contact with a sharp edge, its edge-line point c.point[k] already) into a
    WRAP row: the edge's direction ``axis`` and the unit bisector ``side`` of its two faces' outward normals
    (world frame), the segment's spring, the edge's radius edge_r [m] (0 for a box, a hull's collision margin);
    a new wrap's anchor splits the segment at equal tension."""
    for j in range(3):
        c.axis[k, j] = axis[j]
        c.side[k, j] = side[j]
    c.seg[k, 0], c.seg[k, 1], c.seg[k, 2], c.seg[k, 3], c.seg[k, 4] = ks, l0, kb_a, kb_b, edge_r
    c.seg[k, 5] = 0.0  # set by mark_wrap_neighbours once all rows are made
    c.kind[k] = WRAP
    c.cap[k] = 0.0
    if fresh:
        wrap_start(c, k, x)
        # a wrap that starts with its path already round the edge (a chord cutting the corner, a taut capsule
        # contact) starts with the energy of the path against the chord's: the model's switch, not work of the
        # cable's forces, so the energy check counts it as done on the cable (no false alarm)
        c.body_work[0] += wrap_energy(c, k, x)
    c.cap[k] = _wrap_cap(c, k, x)


@njit(cache=True, error_model="numpy", inline="always")
def _parallel(qa, qb, A, sin2) -> bool:
    """Segment qa-qb within an angle of parallel to the unit direction A (one frame): sin2 the angle's sine squared."""
    e2 = 0.0
    ea = 0.0
    for j in range(3):
        e2 += (qb[j] - qa[j]) ** 2
        ea += (qb[j] - qa[j]) * A[j]
    return ea * ea > e2 * (1.0 - sin2)


@njit(cache=True, error_model="numpy", inline="always")
def _row_near(c, first, i, s, ds) -> bool:
    """A row (from row ``first`` on) on segment i (nodes i, i + 1) within ds of its parameter s [-]."""
    for k in range(first, c.count[0]):
        if c.node[k, 0] == i and c.node[k, 1] == i + 1 and abs(c.weight[k, 1] - s) < ds:
            return True
    return False


@njit(cache=True, error_model="numpy", inline="always")
def _edge_point(qn, P, A, hl, out_c, out_n):
    """Node qn against the capped line P + t A (|t| <= hl) (shape frame): its closest point to the node in out_c, the
    unit normal from it to the node in out_n; returns the distance [m] (out_c[3]; 1e300 on the line)."""
    t = (qn[0] - P[0]) * A[0] + (qn[1] - P[1]) * A[1] + (qn[2] - P[2]) * A[2]
    t = min(max(t, -hl), hl)
    r2 = 0.0
    for j in range(3):
        out_c[j] = P[j] + t * A[j]
        out_n[j] = qn[j] - out_c[j]
        r2 += out_n[j] ** 2
    d = math.sqrt(r2)
    if d == 0.0:
        out_c[3] = 1e300
        return 1e300
    for j in range(3):
        out_n[j] /= d
    out_c[3] = d
    return d


@njit(cache=True, error_model="numpy")
def _box_wrap(c, k, rot, A, P, o1, o2, ks, l0, kb_a, kb_b, fresh, x):
    """:func:`_make_wrap` for the box edge through P along A (shape frame; rot: world from shape), on the
    bisector of its faces o1 and o2."""
    b1 = math.copysign(1.0, P[o1]) / math.sqrt(2.0)
    b2 = math.copysign(1.0, P[o2]) / math.sqrt(2.0)
    axis = np.empty(3)
    side = np.empty(3)
    for j in range(3):
        axis[j] = rot[j, 0] * A[0] + rot[j, 1] * A[1] + rot[j, 2] * A[2]
        side[j] = rot[j, o1] * b1 + rot[j, o2] * b2
    _make_wrap(c, k, axis, side, ks, l0, kb_a, kb_b, 0.0, fresh, x)


PAST_NODE, PAST_ARC = 2, 1  # _off_edge_end: a node past the edge's end behind both its faces; the arc past the end


@njit(cache=True, error_model="numpy")
def _off_edge_end(c, k, x, za, zb, hl, behind_a, behind_b) -> int:
    """Whether wrap row k lies off an end of its edge at x: PAST_NODE where a node past the end lies behind both of the
    edge's faces (behind_a, behind_b: across the edge it is inside the body's wedge, so the segment goes down a third
    face and the path round the line would take it round the body from inside); else PAST_ARC where the arc lies past
    the end (the edge spans |z| <= hl [m] along its line; za, zb [m] are the segment's nodes' coordinates along it from
    its middle, :func:`wrap_arc_share`); else 0. The wrap's geometry is the whole line: kept past the end, a cable
    sliding along the edge off it hung on the line beyond it, and a node reaching the line there (its distance from it
    0) blew the row up (Routing-v0's clip, 2026-12-06); at a table's corner a segment round the vertical edge wrapped the
    end face's top edge as well, and that wrap (the larger arc) held the cable on the corner."""
    if (behind_a and abs(za) > hl) or (behind_b and abs(zb) > hl):
        return PAST_NODE
    s = wrap_arc_share(c, k, x)
    return PAST_ARC if s >= 0.0 and abs(za + s * (zb - za)) > hl else 0


@njit(cache=True, error_model="numpy", inline="always")
def _behind(qn, E, n1, n2) -> bool:
    """Whether point qn lies behind both planes through E with the outward normals n1 and n2 (one frame)."""
    d1 = (qn[0] - E[0]) * n1[0] + (qn[1] - E[1]) * n1[1] + (qn[2] - E[2]) * n1[2]
    d2 = (qn[0] - E[0]) * n2[0] + (qn[1] - E[1]) * n2[1] + (qn[2] - E[2]) * n2[2]
    return d1 < 0.0 and d2 < 0.0


@njit(cache=True, error_model="numpy", inline="always")
def _behind_box_edge(qn, P, o1, o2) -> bool:
    """Whether point qn (box frame) lies behind both faces of the box edge through P whose faces are normal to axes o1
    and o2 (the signs of P[o1], P[o2] give their outward normals)."""
    return (qn[o1] - P[o1]) * P[o1] < 0.0 and (qn[o2] - P[o2]) * P[o2] < 0.0


@njit(cache=True, error_model="numpy")
def _unwrap(c, st, k, x):
    """Turn WRAP row k back into the segment's capsule contact with the edge (its point and normal those of the
    row as added), with a fresh friction anchor at its material point. The wrap's energy against the chord's goes
    as the model's switch, as a new wrap's comes (:func:`_make_wrap`): counted as work on the cable.

    The path went round the edge's rounding where the chord cuts inside it (by up to r (1 - cos(alpha / 2))): the
    capsule starts with that depth in the sink (Store.sink; its surface point that much inside the body, let out
    over SINK_TIME, the energy booked as the body's work, :func:`_pay_release`), not as a penalty. Without it, a wrap
    ending at a table's corner started a capsule 0.9 mm deep (the penalty is stiff for microns: 4 N on a 0.1 g
    node), and the cable's end was thrown up at 3.6 m/s (n 80, 1 kHz)."""
    c.body_work[0] -= wrap_energy(c, k, x)
    c.kind[k] = PENALTY
    a, b = c.node[k, 0], c.node[k, 1]
    wa, wb = c.weight[k, 0], c.weight[k, 1]
    g = 0.0
    for j in range(3):
        c.anchor[k, j] = wa * x[a, j] + wb * x[b, j]
        g += c.normal[k, j] * (c.anchor[k, j] - c.point[k, j])
    c.anchor[k, 3] = wb
    c.state[k] = STICK
    g -= c.radius[0]
    if g < 0.0:
        _to_sink(c, st, k, -g)
    c.cap[k] = 0.0


@njit(cache=True, error_model="numpy")
def _sink_unwrapped(c, st, sh, first, x, wrapped_before):
    """The capsule rows (from row ``first`` on) on static bodies of each segment wrapped last step (wrapped_before,
    by first node) and not now start with their depth in the sink, as :func:`_unwrap`'s row does: while the segment
    wrapped, its chord cut inside the edge's rounding and its other rows with that body pushed nothing
    (:func:`_one_wrap_per_segment`). A wrap ending at a table's corner left the chord 0.9 mm inside the vertex, whose
    three edges' capsules then threw the cable's end up at 3 m/s (n 80, 1 kHz)."""
    now = np.zeros(wrapped_before.shape[0], np.bool_)
    for k in range(first, c.count[0]):
        if c.kind[k] == WRAP:
            now[c.node[k, 0]] = True
    for k in range(first, c.count[0]):
        i = c.node[k, 0]
        s = st.body[k]
        if (c.kind[k] == WRAP or c.node[k, 1] != i + 1 or not wrapped_before[i] or now[i] or s < 0
                or sh.inv_mass[s] > 0.0):
            continue
        g = _gap(c, k, x)
        if g < 0.0:
            _to_sink(c, st, k, -g)
            c.cap[k] = 0.0


@njit(cache=True, error_model="numpy", inline="always")
def _to_sink(c, st, k, depth):
    """Row k's surface point ``depth`` [m] further inside its body, kept in the sink (Store.sink) and let out over
    SINK_TIME (:func:`detect`)."""
    st.sink[st.keys[k]] += depth
    for j in range(3):
        c.point[k, j] -= depth * c.normal[k, j]


@njit(cache=True, error_model="numpy", inline="always")
def _clear_sink(c, st, k):
    """Row k, about to wrap its edge again, drops what is left of an unwrapped capsule's sink (:func:`_unwrap`): its
    point goes back to the edge line, which the wrap's geometry is."""
    key = st.keys[k]
    o = st.sink[key]
    if o > 0.0:
        for j in range(3):
            c.point[k, j] += o * c.normal[k, j]
        st.sink[key] = 0.0


@njit(cache=True, error_model="numpy")
def _one_wrap_per_segment(c, st, first, n, x):
    """A segment with more than one WRAP row (across two edges, of one box or two: near a corner) keeps the wrap whose
    path turns the most (the largest arc alpha at x) and capsule contacts with the others (:func:`_unwrap`): the
    wraps' potentials each replace the segment's whole spring and do not add. Until 2026-12-06 all of them went back
    to capsules: a chord cutting the corner of the edge it wrapped then met that edge as a capsule whose normal, from
    the edge to the chord, pointed into the body and pulled the segment in (a cable slid off a table's corner).

    A wrapped segment's other rows with the same body push nothing (their stiffness, damping and friction cap are
    zeroed; the rows stay for their keys): the cable there is the wrap's path, not the chord, and the chord's
    contacts with the body's other edges pointed into it or along a face (the chord of a segment wrapped round a
    table's edge, beside the vertical edge at its corner, was pushed back along the side face at 14 N)."""
    keep = np.full(n, -1, np.int64)
    most = np.full(n, -np.inf)
    for k in range(first, c.count[0]):
        if c.kind[k] == WRAP:
            alpha = _arc_middle(c, k, x)[1]
            i = c.node[k, 0]
            if alpha > most[i]:
                most[i] = alpha
                keep[i] = k
    for k in range(first, c.count[0]):
        i = c.node[k, 0]
        if c.node[k, 1] != i + 1 or keep[i] < 0 or keep[i] == k:
            continue
        if c.kind[k] == WRAP:
            _unwrap(c, st, k, x)
        if st.body[k] == st.body[keep[i]]:
            c.k_n[k], c.k_t[k], c.c_n[k], c.cap[k] = 0.0, 0.0, 0.0, 0.0


@njit(cache=True, error_model="numpy")
def _near_bodies(x, v, dt, com, lin_vel, slot_row, bound, near):
    """near (S,) <- whether free body s (its centre of mass com[slot_row[s]] [m], velocity lin_vel[slot_row[s]]
    [m/s], Shapes rows) lies within bound[s] [m] plus the distance both can move in 2 dt [s] of the box of the nodes x
    [m] (n, 3) moving at v [m/s]; returns whether any does."""
    lo, hi = np.empty(3), np.empty(3)
    vmax = _nodes_box(x, v, lo, hi)
    anyone = False
    for s in range(near.shape[0]):
        r = slot_row[s]
        gap2, speed = 0.0, 0.0
        for j in range(3):
            d = max(lo[j] - com[r, j], com[r, j] - hi[j], 0.0)
            gap2 += d * d
            speed = max(speed, abs(lin_vel[r, j]))
        reach = bound[s] + 2.0 * dt * (speed + vmax)
        near[s] = gap2 < reach * reach
        anyone |= near[s]
    return anyone


@njit(cache=True, error_model="numpy")
def _reach_box(x, v, radius, h, out):
    """The contact margin [m] of positions x (n, 3) [m] moving at v [m/s] over a step of h [s], as in
    :func:`detect`, and the nodes' bounding box grown by the reach (radius + margin) into ``out`` (2, 3)."""
    vmax = _nodes_box(x, v, out[0], out[1])
    margin = radius + 2.0 * vmax * h + 1e-3
    for j in range(3):
        out[0, j] = out[0, j] - radius - margin
        out[1, j] = out[1, j] + radius + margin
    return margin


@njit(cache=True, error_model="numpy", inline="always")
def _nodes_box(x, v, lo, hi):
    """The nodes' bounding box: lo, hi (3,) [m] <- the smallest and largest coordinates of x (n, 3) [m]; returns the
    largest speed component |v[i, j]| [m/s] of v (n, 3) (:func:`_largest_speed`)."""
    for j in range(3):
        lo[j], hi[j] = x[0, j], x[0, j]
        for i in range(1, x.shape[0]):
            lo[j] = min(lo[j], x[i, j])
            hi[j] = max(hi[j], x[i, j])
    return _largest_speed(v)


@njit(cache=True, error_model="numpy", inline="always")
def _largest_speed(v):
    """The largest speed component |v[i, j]| [m/s] of v (n, 3): the cable's part of the contact margin."""
    vmax = 0.0
    for i in range(v.shape[0]):
        for j in range(3):
            vmax = max(vmax, abs(v[i, j]))
    return vmax


@njit(cache=True, error_model="numpy")
def _probe_candidates(x, box, reach, out, segments, nodes, segs, mid, quat):
    """The nodes and segments of x (n, 3) [m] whose boxes come within ``reach`` [m] of ``box`` (2, 3) (a
    link's lower and upper corners), skipping the ``out`` nodes (and their segments): node indices into ``nodes``, segment starts
    into ``segs`` with each segment's midpoint ``mid`` and the quaternion [x, y, z, w] turning z onto it
    (a capsule's axis) into ``quat`` (only if ``segments``). Returns (node count, segment count)."""
    n = x.shape[0]
    lo, hi = box[0], box[1]
    nn = 0
    ns = 0
    for i in range(n):
        near = True
        for j in range(3):
            if x[i, j] < lo[j] - reach or x[i, j] > hi[j] + reach:
                near = False
        if near and not out[i]:
            nodes[nn] = i
            nn += 1
        if not segments or i == n - 1 or out[i] or out[i + 1]:
            continue
        near = True
        for j in range(3):
            if min(x[i, j], x[i + 1, j]) > hi[j] + reach or max(x[i, j], x[i + 1, j]) < lo[j] - reach:
                near = False
        if not near:
            continue
        e0, e1, e2 = x[i + 1, 0] - x[i, 0], x[i + 1, 1] - x[i, 1], x[i + 1, 2] - x[i, 2]
        el = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        if el == 0.0:
            continue
        e0, e1, e2 = e0 / el, e1 / el, e2 / el
        segs[ns] = i
        for j in range(3):
            mid[ns, j] = 0.5 * (x[i, j] + x[i + 1, j])
        if e2 < -1.0 + 1e-12:  # pointing down z: half a turn about x
            quat[ns, 0], quat[ns, 1], quat[ns, 2], quat[ns, 3] = 1.0, 0.0, 0.0, 0.0
        else:  # half-way between z and e: (z x e, 1 + z.e), normalised
            ql = math.sqrt(e1 * e1 + e0 * e0 + (1.0 + e2) ** 2)
            quat[ns, 0], quat[ns, 1], quat[ns, 2], quat[ns, 3] = -e1 / ql, e0 / ql, 0.0, (1.0 + e2) / ql
        ns += 1
    return nn, ns


@njit(cache=True)
def _probe_broad(api, cable_box, row_of, row_body, row_link, x, reach, out, segments, nodes, segs, mid, quat,
                 data, pairs, hit, boxes, todo):
    """:meth:`ContactSet._probe`'s broad phase in one call: the PROBE rows whose links' broad-phase boxes overlap
    ``cable_box`` (``getOverlappingObjects``; ``row_of[body, link + 1]``: the row of a (body, link) pair, -1: none)
    into ``hit`` (rows,), each one's link box (``getAABB``, one collision-info request per body) into ``boxes``
    (rows, 2, 3), and into ``todo`` the rows, in order, where :func:`_probe_candidates` finds a node or a segment
    near the box (its buffers are scratch here). Returns how many (-1: a native read failed)."""
    count = overlapping(api, cable_box, data, pairs)
    if count < 0:
        return -1
    hit[:] = False
    for k in range(count):
        b, link = pairs[k, 0], pairs[k, 1]
        if 0 <= b < row_of.shape[0] and -1 <= link < row_of.shape[1] - 1:
            s = row_of[b, link + 1]
            if s >= 0:
                hit[s] = True
    nt = 0
    body = -1
    status = np.uint64(0)
    for s in range(hit.shape[0]):
        if not hit[s]:
            continue
        if row_body[s] != body:  # one request answers every link of the body (the rows of a body are adjacent)
            body = row_body[s]
            status = submit(api, api[HANDLE], collision_info_init(api, api[HANDLE], body))
        box = boxes[s]
        if status_aabb(api, status, row_link[s], box.ctypes.data, box.ctypes.data + 24) == 0:
            return -1
        nn, ns = _probe_candidates(x, box, reach, out[s], segments, nodes, segs, mid, quat)
        if nn > 0 or ns > 0:
            todo[nt] = s
            nt += 1
    return nt


@njit(cache=True)
def probe_broad_with(b, x, reach):
    """:func:`_probe_broad` on a set's packed arrays ``b`` (:class:`~bullet_dlo.bullet.contact_call.BroadArgs`)."""
    return _probe_broad(b.api, b.cable_box, b.row_of, b.row_body, b.row_link, x, reach, b.out, b.segments, b.nodes,
                        b.segs, b.mid, b.quat, b.data, b.pairs, b.hit, b.boxes, b.todo)


@njit(cache=True, error_model="numpy", inline="always")
def _tri_closest(q, t, out_c):
    """Closest point out_c (3,) [m] of triangle t (3, 3) to q; returns the squared distance [m^2] (the
    Voronoi regions of vertices, edges and face in turn: Ericson, Real-Time Collision Detection, 5.1.5)."""
    return _tri_closest_region(q, t, out_c)[0]


@njit(cache=True, error_model="numpy", inline="always")
def _tri_closest_region(q, t, out_c):
    """:func:`_tri_closest`, and whether the closest point is the projection of q onto the triangle's plane (its
    face region: inside the triangle, on none of its edges or vertices)."""
    face = False
    ab0, ab1, ab2 = t[1, 0] - t[0, 0], t[1, 1] - t[0, 1], t[1, 2] - t[0, 2]
    ac0, ac1, ac2 = t[2, 0] - t[0, 0], t[2, 1] - t[0, 1], t[2, 2] - t[0, 2]
    ap0, ap1, ap2 = q[0] - t[0, 0], q[1] - t[0, 1], q[2] - t[0, 2]
    d1 = ab0 * ap0 + ab1 * ap1 + ab2 * ap2
    d2 = ac0 * ap0 + ac1 * ap1 + ac2 * ap2
    u, v = 0.0, 0.0  # out_c = a + u ab + v ac
    if d1 <= 0.0 and d2 <= 0.0:
        pass
    else:
        bp0, bp1, bp2 = q[0] - t[1, 0], q[1] - t[1, 1], q[2] - t[1, 2]
        d3 = ab0 * bp0 + ab1 * bp1 + ab2 * bp2
        d4 = ac0 * bp0 + ac1 * bp1 + ac2 * bp2
        cp0, cp1, cp2 = q[0] - t[2, 0], q[1] - t[2, 1], q[2] - t[2, 2]
        d5 = ab0 * cp0 + ab1 * cp1 + ab2 * cp2
        d6 = ac0 * cp0 + ac1 * cp1 + ac2 * cp2
        vc = d1 * d4 - d3 * d2
        vb = d5 * d2 - d1 * d6
        va = d3 * d6 - d5 * d4
        if d3 >= 0.0 and d4 <= d3:
            u = 1.0
        elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
            u = d1 / (d1 - d3)
        elif d6 >= 0.0 and d5 <= d6:
            v = 1.0
        elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
            v = d2 / (d2 - d6)
        elif va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
            w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
            u, v = 1.0 - w, w
        else:
            den = 1.0 / (va + vb + vc)
            u, v = vb * den, vc * den
            face = True
    out_c[0] = t[0, 0] + u * ab0 + v * ac0
    out_c[1] = t[0, 1] + u * ab1 + v * ac1
    out_c[2] = t[0, 2] + u * ab2 + v * ac2
    return (q[0] - out_c[0]) ** 2 + (q[1] - out_c[1]) ** 2 + (q[2] - out_c[2]) ** 2, face


@njit(cache=True, error_model="numpy")
def _hull_distance(plane, tri, tri_plane, p0, q, pd, out_c, out_n):
    """Signed distance [m] of point q from a convex polytope (faces ``plane`` (F, 4), triangles ``tri`` with
    their planes ``tri_plane`` - p0), without the collision margin; closest surface point out_c and outward unit
    normal out_n. Inside: the nearest face (as a box's). Outside: the closest point on the triangles of the faces
    q lies beyond (a closest point's normal cone holds one of them). pd (F,): scratch."""
    sd = -1e300
    fb = 0
    for f in range(plane.shape[0]):
        d = plane[f, 0] * q[0] + plane[f, 1] * q[1] + plane[f, 2] * q[2] - plane[f, 3]
        pd[f] = d
        if d > sd:
            sd = d
            fb = f
    if sd <= 0.0:
        for j in range(3):
            out_n[j] = plane[fb, j]
            out_c[j] = q[j] - sd * out_n[j]
        return sd
    best = 1e300
    cl = np.empty(3)
    for t in range(tri.shape[0]):
        if pd[tri_plane[t] - p0] <= 0.0:
            continue
        d2 = _tri_closest(q, tri[t], cl)
        if d2 < best:
            best = d2
            out_c[0], out_c[1], out_c[2] = cl[0], cl[1], cl[2]
    return _normal_from(q, out_c, out_n)


@njit(cache=True, error_model="numpy")
def _closest_triangle(hu, h, q, out_c, cl, stack, limit2=1e300):
    """The triangle of hull h (:class:`Hulls`, its tree) nearest to q [m] (link frame) within sqrt(limit2) [m]: its
    global index, with its closest point in out_c and the squared distance [m^2] (-1, limit2: none, or no tree). A
    subtree is skipped only when its box is farther than the best triangle so far, so the result is the nearest of
    all (ties: the lower index). cl (3,): scratch; stack (bvh.STACK,) int: scratch."""
    best = limit2
    tb = -1
    root = hu.tri_root[h]
    if root < 0:
        return tb, best
    t0 = hu.tri_first[h]
    top = 0
    stack[0] = root
    while top >= 0:
        k = stack[top]
        top -= 1
        if bvh.box_distance2(hu.tree_lo[k], hu.tree_hi[k], q) > best:
            continue
        r = hu.tree_right[k]
        if r < 0:
            for a in range(hu.tree_first[k], hu.tree_first[k] + hu.tree_count[k]):
                t = t0 + hu.tree_item[a]
                d2 = _tri_closest(q, hu.tri[t], cl)
                if d2 < best or (d2 == best and t < tb):
                    best, tb = d2, t
                    out_c[0], out_c[1], out_c[2] = cl[0], cl[1], cl[2]
            continue
        dl = bvh.box_distance2(hu.tree_lo[k + 1], hu.tree_hi[k + 1], q)
        dr = bvh.box_distance2(hu.tree_lo[r], hu.tree_hi[r], q)
        near, far, d_far = (k + 1, r, dr) if dl <= dr else (r, k + 1, dl)
        if d_far <= best:  # the farther child below the nearer one: popped after it, pruned by then if it can be
            top += 1
            stack[top] = far
        top += 1
        stack[top] = near
    return tb, best


@njit(cache=True, error_model="numpy", inline="always")
def _in_outside_cell(hu, h, q) -> bool:
    """Whether q [m] (in hull h's box) lies in a cube of its grid that is wholly outside the polytope."""
    k = 0
    stride = 1
    for j in range(3):
        i = int((q[j] - hu.lo[h, j]) / hu.grid_cell[h])
        i = min(max(i, 0), hu.grid_dims[h, j] - 1)
        k += i * stride
        stride *= hu.grid_dims[h, j]
    return hu.grid_out[hu.grid_first[h] + k]


@njit(cache=True, error_model="numpy")
def _hull_distance_at(hu, h, plane, tri, tri_plane, p0, q, pd, out_c, out_n, stack, cutoff=1e300, node=-1):
    """:func:`_hull_distance` of hull h of ``hu`` (its faces ``plane``, ``tri``, ``tri_plane`` sliced out, p0 its first
    plane) at q [m], through its triangles' tree where it has one: the nearest triangle, and where q lies in front
    of that triangle's plane (so outside the polytope) its closest point is the polytope's; otherwise (inside, or
    nearest at an edge of a face q is behind) every face is tested as without a tree. With a tree, a point farther
    than ``cutoff`` [m] from every triangle, outside the hull's box or in a cube of its grid that lies outside the
    polytope, returns ``cutoff`` (a lower bound; out_c, out_n not written). pd (F,), stack: scratch.

    ``node`` >= 0: q is that node's, whose nearest triangle when last measured (``hu.hint``) is tried first. The
    face's plane supports the polytope, so nothing of it is nearer than the plane: q at least ``cutoff`` in front
    of it returns ``cutoff`` (the bound above); q in front of it that projects inside the triangle has that
    projection as the polytope's closest point, on the nearest triangle the tree finds (ties aside: a point on two
    triangles is on their edge, not inside either). A resting or slowly sliding node keeps its triangle for many
    steps and skips the tree's ~60 boxes and ~16 triangles a query."""
    root = hu.tri_root[h]
    if root >= 0:
        limit2 = cutoff * cutoff if cutoff < 1e150 else 1e300
        hinted = 0 <= node < hu.hint.shape[1]
        if hinted and hu.hint[h, node] >= 0:
            t = hu.hint[h, node]
            f = hu.tri_plane[t]
            ahead = hu.plane[f, 0] * q[0] + hu.plane[f, 1] * q[1] + hu.plane[f, 2] * q[2] - hu.plane[f, 3]
            if ahead >= cutoff:  # that far in front of one face's plane: outside, and at least that far
                return cutoff
            d2, face = _tri_closest_region(q, hu.tri[t], out_c)
            if face and d2 < limit2 and ahead > 0.0:
                return _normal_from(q, out_c, out_n)
        cl = np.empty(3)
        t, _ = _closest_triangle(hu, h, q, out_c, cl, stack, limit2)
        if t < 0:
            if bvh.box_distance2(hu.tree_lo[root], hu.tree_hi[root], q) > 0.0 or _in_outside_cell(hu, h, q):
                if hinted:  # its nearest triangle, whose plane bounds the next steps' distance
                    hu.hint[h, node], _ = _closest_triangle(hu, h, q, out_c, cl, stack)
                return cutoff
            t, _ = _closest_triangle(hu, h, q, out_c, cl, stack)  # inside the box: perhaps deep inside the hull
        if hinted:
            hu.hint[h, node] = t
        f = hu.tri_plane[t]
        if hu.plane[f, 0] * q[0] + hu.plane[f, 1] * q[1] + hu.plane[f, 2] * q[2] - hu.plane[f, 3] > 0.0:
            return _normal_from(q, out_c, out_n)
    return _hull_distance(plane, tri, tri_plane, p0, q, pd, out_c, out_n)


@njit(cache=True, error_model="numpy")
def hull_distance(hu, h, q, out_c, out_n):
    """:func:`_hull_distance` of hull h of ``hu`` (:class:`Hulls`) at q [m] (its link frame), margin included:
    the distance from the surface Bullet's bodies meet."""
    p0, p1 = hu.plane_first[h], hu.plane_first[h + 1]
    t0, t1 = hu.tri_first[h], hu.tri_first[h + 1]
    pd = np.empty(p1 - p0)
    stack = np.empty(bvh.STACK, np.int64)
    d = _hull_distance_at(hu, h, hu.plane[p0:p1], hu.tri[t0:t1], hu.tri_plane[t0:t1], p0, q, pd, out_c, out_n, stack)
    for j in range(3):
        out_c[j] += hu.margin[h] * out_n[j]
    return d - hu.margin[h]


@njit(cache=True, error_model="numpy")
def hull_distances(hu, h, points):
    """:func:`hull_distance` of hull h of ``hu`` at each of ``points`` (k, 3) [m] (its link frame), one call: (k,)
    [m], each the same as a call of its own."""
    out = np.empty(points.shape[0])
    out_c, out_n = np.zeros(3), np.zeros(3)
    for k in range(points.shape[0]):
        out[k] = hull_distance(hu, h, points[k], out_c, out_n)
    return out


@njit(cache=True, inline="always")
def _edge_cos(hu, e) -> float:
    """The cosine of the turn between the two faces of hull edge e (1: flat; a sharp edge's is at most
    cos WRAP_EDGE_MIN)."""
    n1, n2 = hu.edge_n[e, 0], hu.edge_n[e, 1]
    return n1[0] * n2[0] + n1[1] * n2[1] + n1[2] * n2[2]


@njit(cache=True, error_model="numpy", inline="always")
def _ahead_of_a_face(hu, h, a, b, i, reach):
    """Whether nodes i and i + 1 (a, b [m], the hull's frame) both lie more than ``reach`` [m] in front of the plane of
    either node's last nearest triangle (``hu.hint``). Every face's plane supports the convex hull, so its edges lie
    on or behind it, and the segment between the nodes is nowhere nearer the plane than its nearer end: no edge is
    within reach of the segment, and :func:`_hull_contacts` makes it no row (its edge search is skipped: on the
    duck at n = 20 about 7 of the 11 segments in the hull's box, each testing ~37 edges)."""
    if i + 1 >= hu.hint.shape[1]:
        return False
    for node in (i, i + 1):
        t = hu.hint[h, node]
        if t < 0:
            continue
        f = hu.tri_plane[t]
        da = hu.plane[f, 0] * a[0] + hu.plane[f, 1] * a[1] + hu.plane[f, 2] * a[2] - hu.plane[f, 3]
        db = hu.plane[f, 0] * b[0] + hu.plane[f, 1] * b[1] + hu.plane[f, 2] * b[2] - hu.plane[f, 3]
        if min(da, db) > reach + TREE_SLACK:
            return True
    return False


@njit(cache=True, error_model="numpy")
def _edge_rows(hu, close, n_close, e0, e1, wrapped, qa, qb, reach, rows, kept):
    """The hull edges the segment qa-qb tests: those of ``close[:n_close]`` whose box grown by ``reach`` [m] meets the
    segment's (a wrapped segment: every edge e0 .. e1 - 1) into ``kept`` and the columns of ``rows`` (9, >= count):
    midpoint (3) [m], unit direction (3), half length [m] (rows 7 and 8 for :func:`_segment_edges`); returns their
    count."""
    count = 0
    for k in range(e1 - e0 if wrapped else n_close):
        e = e0 + k if wrapped else close[k]
        P, A, hl = hu.edge_p[e], hu.edge_a[e], hu.edge_hl[e]
        skip = False
        for j in range(3):
            ext = abs(A[j]) * hl + reach
            if min(qa[j], qb[j]) > P[j] + ext or max(qa[j], qb[j]) < P[j] - ext:
                skip = True
        if skip and not wrapped:
            continue
        kept[count] = e
        for j in range(3):
            rows[j, count] = P[j]
            rows[3 + j, count] = A[j]
        rows[6, count] = hl
        count += 1
    return count


@njit(cache=True, error_model="numpy")
def _segment_edges(qa, qb, rows, count):
    """:func:`_segment_axis` of the segment qa-qb against the ``count`` edges of ``rows`` (:func:`_edge_rows`): the
    parameter s of the closest point along the segment (-1: none interior) into ``rows[7]`` and its squared distance
    from the edge [m^2] into ``rows[8]`` (:func:`_segment_axis`'s distance is its root less the edge's radius). The
    same operations in the same order, so the same bits, written without branches over unit-stride columns so that
    the compiler takes several edges at a time (the duck's ~40 edges a segment: about 7 instead of 30 ns an edge)."""
    qa0, qa1, qa2, qb0, qb1, qb2 = qa[0], qa[1], qa[2], qb[0], qb[1], qb[2]
    e0, e1, e2 = qb0 - qa0, qb1 - qa1, qb2 - qa2
    a = e0 * e0 + e1 * e1 + e2 * e2
    p0, p1, p2, a0, a1, a2, hls = rows[0], rows[1], rows[2], rows[3], rows[4], rows[5], rows[6]
    out_s, out_r2 = rows[7], rows[8]
    for k in range(count):
        P0, P1, P2, A0, A1, A2, hl = p0[k], p1[k], p2[k], a0[k], a1[k], a2[k], hls[k]
        w0, w1, w2 = qa0 - P0, qa1 - P1, qa2 - P2
        b = e0 * A0 + e1 * A1 + e2 * A2
        d = e0 * w0 + e1 * w1 + e2 * w2
        ee = A0 * w0 + A1 * w1 + A2 * w2
        den = a - b * b
        s = (b * ee - d) / den
        t = (w0 + s * e0) * A0 + (w1 + s * e1) * A1 + (w2 + s * e2) * A2
        beyond = abs(t) > hl  # beyond the edge's end: the segment's point closest to the end point
        tc = hl if t > 0.0 else -hl
        s_end = ((P0 + tc * A0 - qa0) * e0 + (P1 + tc * A1 - qa1) * e1 + (P2 + tc * A2 - qa2) * e2) / a
        s = s_end if beyond else s
        t = tc if beyond else t
        n0 = qa0 + s * (qb0 - qa0) - (P0 + t * A0)
        n1 = qa1 + s * (qb1 - qa1) - (P1 + t * A1)
        n2 = qa2 + s * (qb2 - qa2) - (P2 + t * A2)
        r2 = 0.0
        r2 += n0 * n0
        r2 += n1 * n1
        r2 += n2 * n2
        out_s[k] = s if (den > 1e-12 * a) & (s > S_MIN) & (s < 1.0 - S_MIN) & (r2 != 0.0) else -1.0
        out_r2[k] = r2


@njit(cache=True, error_model="numpy")
def _hull_contacts(c, st, s, hu, q, x, mass, base, margin, out, sh, k_per_mass, zeta, seg_k, seg_l, seg_b, seg_held):
    """Contacts of the nodes (local positions q (n, 3) [m]) and segments with hull row s (:class:`Hulls`): a
    node meets the polytope grown by the margin m (closest point, :func:`_hull_distance`), a segment the
    closest edge as a capsule of radius m (as a box's edges, with R = m: with the nodes exact for a convex
    polytope, whose distance along a segment is smallest at a node or at an edge). An edge whose faces turn by
    WRAP_EDGE_MIN or more is sharp: a static hull's wraps a taut segment like a box edge (radius r + m); a blunter
    one (a faceted curve) meets the segment only where it comes closer between the nodes than at them (by
    SEGMENT_DIP), as Bullet's narrow phase was asked, so a node near it is not met twice. A segment whose point
    nearest the edge lies inside the polytope (the edge through it between two nodes outside) is not met on the
    edge but leaves by the nearest face, as a node inside does, where it is deeper than both nodes."""
    n = x.shape[0]
    radius = c.radius[0]
    h = hu.row[s]
    m = hu.margin[h]
    reach = radius + margin + m
    q_lo = np.empty(3)  # the nodes' box grown by the reach [m]
    q_hi = np.empty(3)
    for j in range(3):
        lo, hi = q[0, j], q[0, j]
        for i in range(1, n):
            lo = min(lo, q[i, j])
            hi = max(hi, q[i, j])
        if lo - reach > hu.hi[h, j] or hi + reach < hu.lo[h, j]:
            return
        q_lo[j], q_hi[j] = lo - reach, hi + reach
    p0, p1 = hu.plane_first[h], hu.plane_first[h + 1]
    t0, t1 = hu.tri_first[h], hu.tri_first[h + 1]
    plane, tri, tri_plane = hu.plane[p0:p1], hu.tri[t0:t1], hu.tri_plane[t0:t1]
    pd = np.empty(p1 - p0)
    tree = hu.tri_root[h] >= 0
    stack = np.empty(bvh.STACK if tree else 1, np.int64)
    cl = np.empty(4)
    nl = np.empty(3)
    # a node farther than this from a hull with a tree keeps the bound as its distance: it makes no row, and where a
    # segment's row compares its depth or its distance with the nodes' (SEGMENT_DIP) the bound decides as the
    # distance would (a segment's row is within radius + margin of the surface)
    far = radius + margin + m + 10.0 * SEGMENT_DIP
    near = np.zeros(n, np.bool_)
    dist = np.full(n, 1e300)  # the nodes' distances from the polytope [m]
    for i in range(n):
        if out[i]:
            continue
        inside = True
        for j in range(3):
            if q[i, j] < hu.lo[h, j] - reach or q[i, j] > hu.hi[h, j] + reach:
                inside = False
        if not inside:
            continue
        near[i] = True
        if tree:
            d = _hull_distance_at(hu, h, plane, tri, tri_plane, p0, q[i], pd, cl, nl, stack, far, i)
        else:  # (a small hull: every face, without the call in between)
            d = _hull_distance(plane, tri, tri_plane, p0, q[i], pd, cl, nl)
        dist[i] = d
        if d - m - radius < margin:
            for j in range(3):
                cl[j] += m * nl[j]
            _add(c, st, base + i, s, i, i, 1.0, 0.0, cl, nl, sh, k_per_mass, zeta, mass, x)
    wraps = seg_k.shape[0] == n - 1 and sh.inv_mass[s] == 0.0
    e0, e1 = hu.edge_first[h], hu.edge_first[h + 1]
    best_c = np.empty(4)
    best_n = np.empty(3)
    qs = np.empty(3)
    rows = np.empty((9, e1 - e0))  # a segment's edges and their distances (_edge_rows, _segment_edges)
    cand_e = np.empty(e1 - e0, np.int64)  # a segment's edges with an interior closest point, their s and distance [m]
    cand_s = np.empty(e1 - e0)
    cand_d = np.empty(e1 - e0)
    picks = np.empty(3, np.int64)
    # the edges whose boxes meet the nodes' (grown by the reach), once: the only ones a segment's box can meet (a
    # finely faceted hull's 1605 edges were tested by every segment; the cable across it meets a few of them); with
    # the edges' tree, each segment's own (its box grown by the reach, and a little more so that the test below,
    # which rounds otherwise, decides: the same edges in the same order as from the full list)
    close = np.empty(e1 - e0, np.int64)
    n_close = 0
    edge_tree = hu.edge_root[h] >= 0
    seg_lo = np.empty(3 if edge_tree else 0)
    seg_hi = np.empty(3 if edge_tree else 0)
    for e in range(e0, e1):
        if edge_tree:
            break
        P, A, hl = hu.edge_p[e], hu.edge_a[e], hu.edge_hl[e]
        keep = True
        for j in range(3):
            ext = abs(A[j]) * hl
            if q_lo[j] > P[j] + ext or q_hi[j] < P[j] - ext:
                keep = False
        if keep:
            close[n_close] = e
            n_close += 1
    for i in range(n - 1):
        if out[i] or out[i + 1]:
            continue
        key = base + n + i
        wraps_i = wraps and not (seg_held.shape[0] == n and (seg_held[i] or seg_held[i + 1]))
        wrapped = wraps_i and st.active[key] and st.wrap[key]
        if not (near[i] or near[i + 1] or wrapped):
            # both nodes off the hull's box: the segment between them may still cross a corner (a long segment
            # round a small body); skipped only when its own box misses the hull's
            miss = False
            for j in range(3):
                if (min(q[i, j], q[i + 1, j]) - reach > hu.hi[h, j]
                        or max(q[i, j], q[i + 1, j]) + reach < hu.lo[h, j]):
                    miss = True
            if miss:
                continue
        if not wrapped and _ahead_of_a_face(hu, h, q[i], q[i + 1], i, reach):
            continue
        best = 1e300
        eb = -1
        sb = 0.0
        nc = 0
        if edge_tree and not wrapped:
            for j in range(3):
                grow = reach + TREE_SLACK
                seg_lo[j] = min(q[i, j], q[i + 1, j]) - grow
                seg_hi[j] = max(q[i, j], q[i + 1, j]) + grow
            n_close = bvh.overlapping(hu.tree_lo, hu.tree_hi, hu.tree_right, hu.tree_first, hu.tree_count,
                                      hu.tree_item, hu.edge_root[h], e0, seg_lo, seg_hi, close, stack)
        count = _edge_rows(hu, close, n_close, e0, e1, wrapped, q[i], q[i + 1], reach, rows, cand_e)
        _segment_edges(q[i], q[i + 1], rows, count)
        for k in range(count):  # (the candidates packed into cand_* in place: nc <= k)
            sp = rows[7, k]
            if sp > 0.0:
                e = cand_e[k]
                d = math.sqrt(rows[8, k]) - m
                cand_e[nc], cand_s[nc], cand_d[nc] = e, sp, d
                nc += 1
                if d < best:
                    best, eb, sb = d, e, sp
        if eb < 0:
            continue
        # the closest edge's point and normal (its row's, pick 0 below)
        _segment_axis(q[i], q[i + 1], hu.edge_p[eb], hu.edge_a[eb], hu.edge_hl[eb], m, best_c, best_n)
        # the closest edge, and the closest blunt one within reach on either side of it along the segment (at least
        # a radius away): a segment across a faceted curve tilts onto the next ridge, which must already be a row
        # (with the closest edge's row alone, the row jumped between two ridges 2.4 mm apart on the duck, each time
        # to the one the solve had just lifted the segment off, and the cable never came to rest)
        picks[0], picks[1], picks[2] = eb, -1, -1
        apart = radius / max(math.sqrt((q[i + 1, 0] - q[i, 0]) ** 2 + (q[i + 1, 1] - q[i, 1]) ** 2
                                       + (q[i + 1, 2] - q[i, 2]) ** 2), 1e-12)
        d_left, d_right = 1e300, 1e300
        for k in range(nc):
            e = cand_e[k]
            if cand_d[k] - radius >= margin or _edge_cos(hu, e) <= math.cos(WRAP_EDGE_MIN):
                continue
            if cand_s[k] < sb - apart and cand_d[k] < d_left:
                d_left, picks[1] = cand_d[k], e
            elif cand_s[k] > sb + apart and cand_d[k] < d_right:
                d_right, picks[2] = cand_d[k], e
        used = 0  # the features taken by this segment's rows (a bit each)
        for pick in range(3):
            eb = picks[pick]
            if eb < 0:
                continue
            spot = n + 3 * i + pick  # (its hint: the segments' three points after the nodes)
            if pick > 0:  # (the closest edge's point and normal are best_c, best_n from the edge loop)
                sb = _segment_axis(q[i], q[i + 1], hu.edge_p[eb], hu.edge_a[eb], hu.edge_hl[eb], m, best_c, best_n)
            best = best_c[3]
            # a sharp edge's row is the segment's own (feature 0: its wrap state); a blunt one's is keyed by its edge (a
            # feature of 1-12 by its index, the next free one if taken), so a row keeps its friction anchor while the
            # same ridge carries it whichever of the segment's rows is closest
            row_key = key
            if _edge_cos(hu, eb) > math.cos(WRAP_EDGE_MIN):
                f = eb % N_EDGES
                while used & (1 << f):
                    f = (f + 1) % N_EDGES
                used |= 1 << f
                row_key = base + n + (1 + f) * (n - 1) + i
            n1, n2 = hu.edge_n[eb, 0], hu.edge_n[eb, 1]
            edge_sharp = _edge_cos(hu, eb) <= math.cos(WRAP_EDGE_MIN)
            sharp = wraps_i and edge_sharp
            # a chord cutting the corner through the hull (its closest point inside both faces)
            behind = (best_n[0] * n1[0] + best_n[1] * n1[1] + best_n[2] * n1[2] < 0.0
                      and best_n[0] * n2[0] + best_n[1] * n2[1] + best_n[2] * n2[2] < 0.0)
            cuts = sharp and behind
            # outside, the edge is the nearest feature only where the direction from it lies between its two faces'
            # normals (best_n = a n1 + b n2 (+ along the edge) with a, b >= 0); elsewhere (beside a face) the face is
            c12 = n1[0] * n2[0] + n1[1] * n2[1] + n1[2] * n2[2]
            d1 = best_n[0] * n1[0] + best_n[1] * n1[1] + best_n[2] * n1[2]
            d2 = best_n[0] * n2[0] + best_n[1] * n2[1] + best_n[2] * n2[2]
            beside = not behind and (d1 - c12 * d2 < 0.0 or d2 - c12 * d1 < 0.0)
            if behind and not sharp:  # (in front of either face's plane the point is outside: no polytope distance)
                # the segment's point inside the polytope: it leaves by the nearest face (as in detect's boxes)
                for j in range(3):
                    qs[j] = best_c[j] + best_c[3] * best_n[j]
                if tree:
                    d = _hull_distance_at(hu, h, plane, tri, tri_plane, p0, qs, pd, cl, nl, stack, 1e300, spot)
                else:
                    d = _hull_distance(plane, tri, tri_plane, p0, qs, pd, cl, nl)
                if d < 0.0:
                    if d > min(dist[i], dist[i + 1]) - SEGMENT_DIP:
                        continue  # the nodes are as deep: they carry it
                    for j in range(3):
                        best_c[j] = cl[j] + m * nl[j]
                        best_n[j] = nl[j]
                    best = best_c[3] = d - m
            elif beside and not sharp:
                # the direction from the edge runs along the face into the polytope (as detect's box edges before
                # 2026-12-03: a segment entering a hull next to an edge was pushed into it along the face): the row is
                # the face's, which is the edge's where the two meet, while the edge is within reach and only for one of
                # the edge's own faces (another face's row belongs to that face's edges and nodes)
                if best - radius >= margin:
                    continue
                for j in range(3):
                    qs[j] = best_c[j] + best_c[3] * best_n[j]
                if tree:
                    d = _hull_distance_at(hu, h, plane, tri, tri_plane, p0, qs, pd, cl, nl, stack, 1e300, spot)
                else:
                    d = _hull_distance(plane, tri, tri_plane, p0, qs, pd, cl, nl)
                own1 = nl[0] * n1[0] + nl[1] * n1[1] + nl[2] * n1[2]
                own2 = nl[0] * n2[0] + nl[1] * n2[1] + nl[2] * n2[2]
                if max(own1, own2) < 1.0 - 1e-9:
                    continue
                for j in range(3):
                    best_c[j] = cl[j] + m * nl[j]
                    best_n[j] = nl[j]
                best = best_c[3] = d - m
            held = sharp and wrapped
            if not (best - radius < margin or held or cuts):
                continue
            if not edge_sharp and best + m > min(dist[i], dist[i + 1]) - SEGMENT_DIP:
                continue  # a blunt edge (a faceted curve) no closer between the nodes than at them: the nodes carry it
            fresh = not (st.active[key] and st.wrap[key])
            _add(c, st, row_key, s, i, i + 1, 1.0 - sb, sb, best_c, best_n, sh, k_per_mass, zeta, mass, x)
            k = c.count[0] - 1
            # the segment before a wrapped one wraps too while its own path goes round the edge: its row then bends the
            # node between them (the turn over the edge is the edge's), continuously (mark_wrap_neighbours)
            before = i + 2 < n and st.active[key + 1] and st.wrap[key + 1]
            along = _parallel(q[i], q[i + 1], hu.edge_a[eb], WRAP_ALONG_SIN2)  # (no wrap: see detect's boxes)
            if k < 0 or not (sharp and st.keys[k] == key
                             and (held or ((cuts or before or _taut(x, i, seg_k[i], seg_l[i], seg_b))
                                           and not along))):
                continue
            rot, pos = sh.rot[s], sh.pos[s]
            axis = np.empty(3)
            side = np.empty(3)
            bl = 0.0
            for j in range(3):
                bl += (n1[j] + n2[j]) ** 2
            bl = math.sqrt(bl)
            A = hu.edge_a[eb]
            for j in range(3):
                e_j = 0.0
                for o in range(3):
                    e_j += rot[j, o] * (best_c[o] - m * best_n[o])  # the edge line's point, off the rounding
                c.point[k, j] = pos[j] + e_j
                axis[j] = rot[j, 0] * A[0] + rot[j, 1] * A[1] + rot[j, 2] * A[2]
                side[j] = (rot[j, 0] * (n1[0] + n2[0]) + rot[j, 1] * (n1[1] + n2[1]) + rot[j, 2] * (n1[2] + n2[2])) / bl
            st.sink[st.keys[k]] = 0.0  # (:func:`_clear_sink`; the line's point is set above)
            cp0, cp1, cp2 = c.point[k, 0], c.point[k, 1], c.point[k, 2]  # (the rounding's point: a capsule row's)
            _make_wrap(c, k, axis, side, seg_k[i], seg_l[i], seg_b[i], seg_b[i + 1], m, fresh, x)
            if best - radius >= margin and not wrap_active(c, k, x):
                c.count[0] = k  # the chord has left the edge: the wrap is over
            else:
                za, zb = 0.0, 0.0
                for j in range(3):
                    za += (q[i, j] - hu.edge_p[eb, j]) * A[j]
                    zb += (q[i + 1, j] - hu.edge_p[eb, j]) * A[j]
                # (a chord through the hull keeps its wrap unless a node has gone round the corner; one past the
                # edge's end along it is not through it)
                through = cuts and abs(za + sb * (zb - za)) < hu.edge_hl[eb]
                off = _off_edge_end(c, k, x, za, zb, hu.edge_hl[eb], _behind(q[i], hu.edge_p[eb], n1, n2),
                                    _behind(q[i + 1], hu.edge_p[eb], n1, n2))
                if along or off == PAST_NODE or (off == PAST_ARC and not through):
                    c.point[k, 0], c.point[k, 1], c.point[k, 2] = cp0, cp1, cp2
                    _unwrap(c, st, k, x)  # the cable has slid off the edge's end, or lies along it
                    if best - radius >= margin or through:  # (through: the capsule's normal points into the hull)
                        c.count[0] = k


@njit(cache=True, error_model="numpy")
def detect(x, v, mass, sh, c, bd, st, h, k_per_mass, zeta, self_mu, h_body, h_done, oc, pr, seg_k, seg_l, seg_b,
           seg_held, hu, out_nodes):
    """Store the friction state of the last step's contacts by key, then fill ``c`` with the contacts
    of positions x [m] (n, 3) (velocities v [m/s]) whose gap is below the margin (cable radius + twice
    the distance the fastest node moves in a step of h [s] + 1 mm; with a shape, + twice the farthest its body
    moves in a Bullet step of h_body, :func:`_sweep`); self-contacts too unless
    self_mu[0] < 0 (self_mu: static and dynamic friction cable on cable). Returns the count.

    Dynamic bodies: the last step's work of each one on the cable, counted by the contact step with
    its velocity before the step, is corrected to its velocity now (after Bullet's step of h_done [s];
    0: no step was taken); the new contacts' stiffness and damping carry the body's inertia over a
    Bullet step of h_body [s] (:func:`_condense_bodies`).

    Other cables (``oc``, :class:`Others`): their segments against this cable's (:func:`_cable_contacts`);
    the last step's contacts with them are corrected for where the other cable actually went.

    Probed links (``pr``, :class:`Probes`): Bullet's closest points become contacts of the same law.

    Free bodies (``bd``, :class:`~bullet_dlo.core.kernels.contact.Bodies`, slots for the world's free bodies):
    their mass, inertia and velocity, and each row's slot and arm (:func:`_load_free_bodies`).

    Convex hulls (``hu``, :class:`Hulls`): the rows of kind HULL near the cable, on their exact geometry
    (:func:`_hull_contacts`), without the nodes ``out_nodes`` (B, n) bool of their row (and the segments next to
    them).

    Edges of static boxes: a segment whose axis comes within the margin of one edge (of one box) is wrapped
    round it (a WRAP row: its stretch measured along the path over the edge, capstan friction; see
    :func:`~bullet_dlo.core.kernels.contact._wrap_eval`) when ``seg_k``, ``seg_l`` (the segments' stretch
    stiffness [N/m] and rest length [m]) and ``seg_b`` (the nodes' bending constants [N m/rad^2]) are given; a segment near two edges keeps capsule contacts with
    both (one wrap per segment); ``seg_held`` (n,) bool, when given, keeps segments next to a held node from
    wrapping."""
    vmax = _largest_speed(v)
    margin = c.reach[0] + 2.0 * vmax * h + 1e-3  # (reach: a flat section's half diagonal, else the radius)
    previous = st.keys[:c.count[0]].copy()  # the keys in contact last step (their rows get overwritten)
    had_wrap = np.zeros(sh.kind.shape[0], np.bool_)  # shapes with a wrapped segment last step
    seg_wrapped = np.zeros(x.shape[0], np.bool_)  # segments (by first node) wrapped last step
    credit_max = np.zeros(0)  # (previous rows) the penalty energy a body's unplanned move may have stored, [J]
    credit_paid = np.zeros(0)  # and what of the row's energy is accounted for already [J]
    released = np.zeros(0)  # (previous rows) the sink let out this step [m]
    c.body_work[0] -= c.body_work[1]  # the last step's stored energy of unplanned moves: now released or gone
    c.body_work[1] = 0.0
    for k in range(previous.shape[0]):  # persist what the last step left
        key = previous[k]
        for j in range(4):
            st.anchor[key, j] = c.anchor[k, j]
        st.state[key] = c.state[k]
        st.wrap[key] = c.kind[k] == WRAP
        st.load[key] = max(0.0, c.f_n[k])
        st.stiffness[key] = c.k_n[k]
        s = st.body[k]
        if c.kind[k] == WRAP and s >= 0:
            had_wrap[s] = True
            seg_wrapped[c.node[k, 0]] = True
        if h_done > 0.0 and (s < 0 or sh.inv_mass[s] == 0.0) and st.sink[key] > 0.0:
            # a static row's sink (an unwrapped capsule's start, :func:`_unwrap`) is let out as a free body's is
            held = st.sink[key]
            st.sink[key] = max(0.0, 1.0 - h_done / SINK_TIME) * held
            if released.shape[0] == 0:
                released = np.zeros(previous.shape[0])
            released[k] = held - st.sink[key]
        if h_done > 0.0 and s >= 0 and sh.inv_mass[s] > 0.0:
            # Bullet moved the body by h v' (semi-implicit Euler), v' its velocity now, not by the h u
            # the cable's step assumed: energy a body took from a too stiff contact counts as made
            w = sh.ang_vel[s]
            a0, a1, a2 = c.point[k, 0] - sh.com[s, 0], c.point[k, 1] - sh.com[s, 1], c.point[k, 2] - sh.com[s, 2]
            d0 = sh.lin_vel[s, 0] + w[1] * a2 - w[2] * a1 - c.body_vel[k, 0]
            d1 = sh.lin_vel[s, 1] + w[2] * a0 - w[0] * a2 - c.body_vel[k, 1]
            d2 = sh.lin_vel[s, 2] + w[0] * a1 - w[1] * a0 - c.body_vel[k, 2]
            fn = c.f_n[k]
            c.body_work[0] += h_done * ((fn * c.normal[k, 0] + c.f_t[k, 0]) * d0
                                        + (fn * c.normal[k, 1] + c.f_t[k, 1]) * d1
                                        + (fn * c.normal[k, 2] + c.f_t[k, 2]) * d2)
            if c.kind[k] != WRAP and c.state[k] == STICK:
                # a stuck anchor is a point of the body: it moves with what Bullet did, not only with the plan (a
                # plank resting across the cable and the ground crept along the cable while its anchors lagged the
                # ground's push, which the cable's step takes a step late). Followed at once, a body rocking
                # between the ground and the cable (a duck at 240 Hz) was kept rocking: each follow stretches
                # the friction spring by a move the body made without its force, energy the next step hands back.
                # So the anchor follows the low-passed unplanned motion: a steady drift exactly, a rocking of
                # period well below FOLLOW_TIME hardly. In the tangent plane only: the normal part is the penalty's
                dn = c.normal[k, 0] * d0 + c.normal[k, 1] * d1 + c.normal[k, 2] * d2
                a = min(1.0, h_done / FOLLOW_TIME)
                st.drift[key, 0] += a * (d0 - dn * c.normal[k, 0] - st.drift[key, 0])
                st.drift[key, 1] += a * (d1 - dn * c.normal[k, 1] - st.drift[key, 1])
                st.drift[key, 2] += a * (d2 - dn * c.normal[k, 2] - st.drift[key, 2])
                for j in range(3):
                    st.anchor[key, j] += h_done * st.drift[key, j]
            else:
                for j in range(3):
                    st.drift[key, j] = 0.0
            if c.kind[k] != WRAP:
                # f_n times the move is the work at the planned end's force. A body Bullet moved further into the
                # cable than planned (a step's lag of its support: a duck rocking on the ground and the cable,
                # 1.2 mm at 60 Hz) leaves the penalty holding up to 1/2 k_n delta^2 more (delta: the move towards
                # the cable) that no force paid for, and the coming implicit step mostly dissipates it (k_n h^2 /
                # m_c = 1e4): counted, it stopped such runs as "energy growth". It is left out of the balance of
                # this step (body_work[1], taken back at the next detection), as far as the row, detected again,
                # holds it: what of it the next step turns into motion of the cable or the body is counted there
                g_plan = _gap(c, k, x)
                delta = h_done * (c.normal[k, 0] * d0 + c.normal[k, 1] * d1 + c.normal[k, 2] * d2)
                e_plan = min(0.0, g_plan)
                st.depth[key] = -e_plan
                e_new = min(0.0, g_plan - delta)
                extra = 0.5 * c.k_n[k] * (e_new * e_new - e_plan * e_plan) + c.k_n[k] * e_plan * delta
                # The extra penetration itself is not the penalty's to push back: released by the stiff spring
                # (k_n = 1e4 m_c / h^2, stiff for the cable's node mass) into a light body it launched it (a 1 g box
                # tipping off the cable, its corner hitting the ground in Bullet's step, turned 2-4 mm into the
                # cable and left at 3-20 m/s). The row's surface point moves into the body by it (Store.sink, in
                # _fill) and comes back over SINK_TIME, a position correction without the spring's energy (as
                # Bullet's split impulse); a move out of the cable takes back what it can
                # Only a collision's (sh.impact): a body held in the step (a duck rocking on the ground and the
                # cable) or misjudged (a mass changed after the set read it) keeps the penalty's push, or it sinks
                keep = max(0.0, 1.0 - h_done / SINK_TIME)
                pressed = e_plan - e_new if sh.impact[s] else min(0.0, e_plan - e_new)
                held = max(0.0, st.sink[key] + pressed)
                st.sink[key] = max(0.0, keep * st.sink[key] + pressed)
                if st.sink[key] < held:  # what is let out this step: the surface point's move pays the penalty's
                    if released.shape[0] == 0:  # energy (below), as a body's move into the cable would
                        released = np.zeros(previous.shape[0])
                    released[k] = held - st.sink[key]
                if extra > 0.0:
                    if credit_max.shape[0] == 0:
                        credit_max = np.zeros(previous.shape[0])
                        credit_paid = np.zeros(previous.shape[0])
                    credit_max[k] = extra
                    # the energy the row held at the planned end, and the linear part of the move's work booked
                    credit_paid[k] = 0.5 * c.k_n[k] * e_plan * e_plan - c.k_n[k] * e_plan * delta
    if h_done > 0.0:
        _cable_moved(c, st, oc, previous.shape[0], h_done)
    n = x.shape[0]
    per_shape = n + (N_EDGES + 3) * (n - 1) + 6  # keys_per_shape(n)
    radius = c.radius[0]
    c.count[0] = 0
    q = np.empty((n, 3))
    cl = np.empty(4)
    nl = np.empty(3)
    qs = np.empty(4)  # scratch: a segment's point, a node's closest point
    nl2 = np.empty(3)
    P = np.empty(3)
    A = np.empty(3)
    q_lo = np.empty(3)
    q_hi = np.empty(3)
    first_edge = c.count[0]
    for k in range(pr.count[0]):  # Bullet's closest points on the probed links (world frame already)
        s = pr.shape[k]
        ia, ib = pr.node[k, 0], pr.node[k, 1]
        m = c.count[0]
        if m >= c.node.shape[0]:
            break
        for j in range(3):
            c.point[m, j] = pr.point[k, j]
            c.normal[m, j] = pr.normal[k, j]
        key = s * per_shape + pr.key[k]
        _add_row(c, st, key, s, ia, ib, 1.0 - pr.weight[k], pr.weight[k], sh, k_per_mass, zeta, mass, x)
    for s in range(sh.kind.shape[0]):
        kind = sh.kind[s]
        if kind == PROBE or (kind == HULL and not hu.near[s]):
            continue
        size = sh.size[s]
        rot, pos = sh.rot[s], sh.pos[s]
        for i in range(n):  # nodes in the shape frame
            for j in range(3):
                q[i, j] = (rot[0, j] * (x[i, 0] - pos[0]) + rot[1, j] * (x[i, 1] - pos[1])
                           + rot[2, j] * (x[i, 2] - pos[2]))
        margin_s = margin + _sweep(sh, s, hu, h_body)  # the cable's margin and the body's own motion in a step
        if kind == HULL:
            _hull_contacts(c, st, s, hu, q, x, mass, s * per_shape, margin_s, out_nodes[s], sh, k_per_mass, zeta,
                           seg_k, seg_l, seg_b, seg_held)
            continue
        if _out_of_reach(q, kind, size, radius + margin_s):
            continue  # the cable's bounding box misses the shape's: nothing of it can touch
        base = s * per_shape
        first = c.count[0]  # this shape's first row
        for i in range(n):
            d = _node_closest(kind, size, q[i], cl, nl)
            if d - radius < margin_s:
                _add(c, st, base + i, s, i, i, 1.0, 0.0, cl, nl, sh, k_per_mass, zeta, mass, x)
        if kind == BOX:  # segments against the 12 edges
            wraps = seg_k.shape[0] == n - 1 and sh.inv_mass[s] == 0.0
            for j in range(3):  # the nodes' bounding box (shape frame), grown by the reach
                q_lo[j], q_hi[j] = q[0, j], q[0, j]
                for i in range(1, n):
                    q_lo[j] = min(q_lo[j], q[i, j])
                    q_hi[j] = max(q_hi[j], q[i, j])
                q_lo[j] -= radius + margin_s
                q_hi[j] += radius + margin_s
            for ax in range(3):
                o1 = (ax + 1) % 3
                o2 = (ax + 2) % 3
                A[:] = 0.0
                A[ax] = 1.0
                for e in range(4):
                    P[ax] = 0.0
                    P[o1] = size[o1] if e % 2 == 0 else -size[o1]
                    P[o2] = size[o2] if e // 2 == 0 else -size[o2]
                    if (not had_wrap[s] and (q_lo[ax] > size[ax] or q_hi[ax] < -size[ax] or q_lo[o1] > P[o1]
                                             or q_hi[o1] < P[o1] or q_lo[o2] > P[o2] or q_hi[o2] < P[o2])):
                        # the whole cable misses the edge as each segment would (_may_reach_edge), and no
                        # segment wrapped round this box last step: nothing of it meets this edge (the ground's
                        # edges under a cable lying on it: 12 (n - 1) tests a step)
                        continue
                    feat = 1 + 4 * ax + e
                    for i in range(n - 1):
                        key = base + n + (n - 1) * feat + i
                        wraps_i = wraps and not (seg_held.shape[0] == n and (seg_held[i] or seg_held[i + 1]))
                        wrapped = wraps_i and st.active[key] and st.wrap[key]
                        if not wrapped and not _may_reach_edge(q[i], q[i + 1], P, ax, size[ax], radius + margin_s):
                            continue
                        sp = _segment_axis(q[i], q[i + 1], P, A, size[ax], 0.0, cl, nl)
                        # a wrapped segment, or the one before a wrapped one (key + 1: the next segment at this edge),
                        # whose closest point to the edge is a node (on the edge's cylinder, turning round it): a row
                        # all the same, kept only while its path goes round the edge. Without it the bend at a node
                        # rounding the edge was measured against the chord of the segment before, which stays on the
                        # face while the node turns: a spring of k_b / r^2 (94 N/m on a 4 mm soft cable) held the node
                        # at the top of the corner
                        reaching = False
                        if sp <= 0.0 and wraps_i and (wrapped or (i + 2 < n and st.active[key + 1]
                                                                  and st.wrap[key + 1])):
                            near = i if _edge_point(q[i], P, A, size[ax], cl, nl) < _edge_point(
                                q[i + 1], P, A, size[ax], cl, nl) else i + 1
                            reaching = _edge_point(q[near], P, A, size[ax], cl, nl) - radius < margin_s
                            if reaching:  # (a place inside the segment, at the node's end)
                                sp = 2.0 * S_MIN if near == i else 1.0 - 2.0 * S_MIN
                        # a chord cutting the corner through the box (a coarse segment draped round the edge)
                        inside = (sp > 0.0 and abs(cl[o1] + cl[3] * nl[o1]) < size[o1]
                                  and abs(cl[o2] + cl[3] * nl[o2]) < size[o2])
                        cuts = wraps_i and inside
                        # (turned out only when the point is inside along the edge too: one below a vertical
                        # edge's end, under the bottom face, is outside the box)
                        inside = inside and abs(cl[ax] + cl[3] * nl[ax]) < size[ax]
                        # outside, the edge is the segment's nearest feature only where the direction from it lies
                        # between its two faces' normals; elsewhere (beside a face) the face is, with its normal
                        beside = sp > 0.0 and not inside and (nl[o1] * P[o1] < 0.0 or nl[o2] * P[o2] < 0.0)
                        if beside and not wraps_i and _parallel(q[i], q[i + 1], A, ALONG_EDGE ** 2):
                            continue  # (its closest point to the edge lies anywhere along it: the nodes carry it)
                        if (inside or beside) and not wraps_i:
                            # the direction from the edge to the segment's point then points into the box, and
                            # the distance is no depth: left so, the penalty pulled the segment through the edge,
                            # deeper in (a 0.3 kg box tipped off the cable, its edge through a segment between two
                            # nodes just outside it, squeezed the cable at 30-56 N between that row and the nodes'
                            # and was stopped as energy growth). The point leaves by the nearest face, as a node
                            # inside does, where it is deeper than both nodes (else they carry it). Beside a face,
                            # the direction from the edge ran along the face into the box (a segment entering a
                            # tipping 1 g box next to its bottom edge was pushed up into it while its node was pushed
                            # out through the bottom, and the box, squeezed between the two rows, was thrown): the
                            # row is the face's, which is the edge's where the two meet (found while the edge is
                            # within reach, as before, and only for one of the edge's own faces: the point beneath a
                            # plank is beside its bottom face for each top edge too, whose rows doubled the bottom's)
                            reach = cl[3]
                            for j in range(3):
                                qs[j] = cl[j] + cl[3] * nl[j]
                            cl[3] = _node_closest(kind, size, qs, cl, nl)
                            if inside and cl[3] > min(_node_closest(kind, size, q[i], qs, nl2),
                                                      _node_closest(kind, size, q[i + 1], qs, nl2)) - SEGMENT_DIP:
                                continue
                            if beside and (reach - radius >= margin_s
                                           or nl[o1] * P[o1] < 0.0 or nl[o2] * P[o2] < 0.0):
                                continue
                            # the face's contact there is already a row (an edge the segment crosses, found first)
                            if beside and _row_near(c, first, i, sp, radius / math.sqrt(
                                    (q[i + 1, 0] - q[i, 0]) ** 2 + (q[i + 1, 1] - q[i, 1]) ** 2
                                    + (q[i + 1, 2] - q[i, 2]) ** 2)):
                                continue
                        # a wrap is kept while the path wraps, even with the chord deep in the box
                        if sp > 0.0 and (cl[3] - radius < margin_s or wrapped or cuts):
                            fresh = not (st.active[key] and st.wrap[key])  # a new wrap (or a capsule contact turning into one)
                            _add(c, st, key, s, i, i + 1, 1.0 - sp, sp, cl, nl, sh, k_per_mass, zeta, mass, x)
                            # the segment before a wrapped one (key + 1: the next segment at this edge) wraps
                            # too: its row bends the node between them (mark_wrap_neighbours)
                            before = i + 2 < n and st.active[key + 1] and st.wrap[key + 1]
                            # a segment lying along the edge does not wrap it: its nodes sit on the edge's
                            # cylinder, where the path's tangents vanish and their curvature 1/t diverges (a cable
                            # slid off a table's corner onto the end face's edge stalled Newton at 1e5 times gravity's
                            # impulse); its nodes' rows carry it, as they do a cable lying on a face
                            along = _parallel(q[i], q[i + 1], A, WRAP_ALONG_SIN2)
                            if (wraps_i and c.count[0] > 0 and st.keys[c.count[0] - 1] == key
                                    and (wrapped or ((cuts or before or _taut(x, i, seg_k[i], seg_l[i], seg_b))
                                                     and not along))):
                                k = c.count[0] - 1
                                _clear_sink(c, st, k)
                                _box_wrap(c, k, rot, A, P, o1, o2, seg_k[i], seg_l[i], seg_b[i], seg_b[i + 1], fresh, x)
                                gone = cl[3] - radius >= margin_s or reaching  # (or a node's row would be doubled)
                                if gone and not wrap_active(c, k, x):
                                    c.count[0] = k  # the chord has left the edge
                                else:
                                    off = _off_edge_end(c, k, x, q[i, ax], q[i + 1, ax], size[ax],
                                                        _behind_box_edge(q[i], P, o1, o2),
                                                        _behind_box_edge(q[i + 1], P, o1, o2))
                                    # a chord through the box keeps its wrap, unless a node has gone round the
                                    # corner past the edge's end (the segment wraps the edge there, not this one);
                                    # then the capsule's normal, from this edge to the chord, points into the box
                                    if along or off == PAST_NODE or (off == PAST_ARC and not inside):
                                        _unwrap(c, st, k, x)  # the cable has slid off the edge's end, or lies along it
                                        if gone or inside:
                                            c.count[0] = k
        elif kind == SPHERE:
            P[:] = 0.0
            for i in range(n - 1):
                e2 = 0.0
                dot = 0.0
                for j in range(3):
                    ej = q[i + 1, j] - q[i, j]
                    e2 += ej * ej
                    dot -= q[i, j] * ej
                sp = dot / e2
                if sp <= S_MIN or sp >= 1.0 - S_MIN:
                    continue
                r2 = 0.0
                for j in range(3):
                    nl[j] = q[i, j] + sp * (q[i + 1, j] - q[i, j])
                    r2 += nl[j] ** 2
                rl = math.sqrt(r2)
                if rl > 0.0 and rl - size[0] - radius < margin_s:
                    for j in range(3):
                        nl[j] /= rl
                        cl[j] = size[0] * nl[j]
                    key = base + n + i
                    _add(c, st, key, s, i, i + 1, 1.0 - sp, sp, cl, nl, sh, k_per_mass, zeta, mass, x)
        else:  # cylinder mantle / capsule core: segments against the axis
            P[:] = 0.0
            A[0], A[1], A[2] = 0.0, 0.0, 1.0
            for i in range(n - 1):
                sp = _segment_axis(q[i], q[i + 1], P, A, size[1], size[0], cl, nl)
                side = _cylinder_side(q[i], q[i + 1], sp, size[0], size[1]) if kind == CYLINDER else 0
                if side == 0 and sp > 0.0 and cl[3] - radius < margin_s:
                    key = base + n + i
                    _add(c, st, key, s, i, i + 1, 1.0 - sp, sp, cl, nl, sh, k_per_mass, zeta, mass, x)
                for end in range(2 if side != 0 else 0):  # a flat end's rim, as a box's edges (their keys)
                    sr = _rim_row(q[i], q[i + 1], size[0], size[1], side, end, cl, nl)
                    if sr > 0.0 and cl[3] - radius < margin_s:
                        key = base + n + (n - 1) * (1 + end) + i
                        _add(c, st, key, s, i, i + 1, 1.0 - sr, sr, cl, nl, sh, k_per_mass, zeta, mass, x)
    _one_wrap_per_segment(c, st, first_edge, n, x)
    _sink_unwrapped(c, st, sh, first_edge, x, seg_wrapped)
    mark_wrap_neighbours(c, first_edge)  # after the last change of a row's kind
    if self_mu[0] >= 0.0:
        _self_contacts(x, v, h, mass, c, st, sh.kind.shape[0] * per_shape, self_mu, margin, k_per_mass, zeta)
    if oc.x.shape[0] > 0:
        _cable_contacts(x, mass, c, st, oc, sh.kind.shape[0] * per_shape + 2 * (n - 1) * (2 * n - 1),  # self_keys(n)
                        margin + 2.0 * oc.vmax[0] * h_body, k_per_mass, zeta)
    if bd.mass.shape[0] > 0:  # free bodies in the world: the rows they press follow their load
        _follow_loads(c, st, sh, x)
    _condense_bodies(c, st, sh, x, v, h_body)
    if bd.mass.shape[0] > 0:  # free bodies in the world (a pass of its own: nothing to pay without them)
        _load_free_bodies(c, bd, st, sh)
    if credit_max.shape[0] > 0:  # the stored energy of the body's move, as far as the rows detected now hold it
        for k in range(c.count[0]):
            key = st.keys[k]
            for j in range(previous.shape[0]):
                if previous[j] == key and credit_max[j] > 0.0:
                    e_now = min(0.0, _gap(c, k, x))
                    unpaid = min(credit_max[j], max(0.0, 0.5 * c.k_n[k] * e_now * e_now - credit_paid[j]))
                    c.body_work[0] += unpaid
                    c.body_work[1] += unpaid
                    credit_max[j] = 0.0
    if released.shape[0] > 0:
        _pay_release(c, st, x, previous, released)
    for k in range(previous.shape[0]):  # active: in contact this step (what the next step continues)
        st.active[previous[k]] = False
    for k in range(c.count[0]):
        st.active[st.keys[k]] = True
    return c.count[0]


@njit(cache=True, error_model="numpy")
def detect_with(a, x, v, mass, h, k_per_mass, h_body, h_done):
    """:func:`detect` on a set's packed arrays ``a`` (:class:`~bullet_dlo.bullet.contact_call.SetArgs`)."""
    return detect(x, v, mass, a.shapes, a.contacts, a.bodies, a.store, h, k_per_mass, a.zeta, a.self_mu, h_body, h_done,
                  a.others, a.probes, a.seg_k, a.seg_l, a.seg_b, a.seg_held, a.hulls, a.probe_out)


@njit(cache=True, error_model="numpy")
def _follow_loads(c, st, sh, x):
    """Stiffen the rows under a heavy body to their load. A row's stiffness alpha m_c / h^2 holds the cable's own
    weight microns deep, but not a body's: a 2 kg cube on a 0.2 g node at 60 Hz rested 1.33 mm into a 1.25 mm radius,
    and a 10 kg box pressed a node's centre half a radius under the table top. A PENALTY row on a free body (one
    solved in the cable's step, Shapes.slot >= 0) that carried f [N] at the end of the last step is at least
    f / (LOAD_DEPTH r) stiff, and a static row (the table) as far as free bodies' rows press within NEAR_NODES nodes
    of its own, so no body's weight presses a row deeper than LOAD_DEPTH r (at most LOAD_STIFFNESS_MAX times its own
    stiffness). Where a row is stiffer than in the last step,
    the part of its depth the new stiffness would push back at once goes into the sink (Store.sink, let out over
    SINK_TIME and paid as the body's work): it starts with the last step's force, not with a kick.

    Only these rows, and a static row only as far as free bodies press its nodes: the load of a body's weight is a
    force, and a stiffer row carries the same force less deep. A squeeze between a driven link (an arm) or two static
    bodies is a displacement: there each stiffer step would press harder, and the next stiffen more (a geometric
    growth to the cap), so those rows keep alpha m_c / h^2. (Stiffened to its whole load wherever a free body touched
    its node, a static row let a fixture's squeeze beside a 10 g box on the cable grow from 37 to 165 N.)"""
    n = x.shape[0]
    pressing = np.zeros(n)  # [N] the load free bodies' rows put on each node at the end of the last step
    found = False
    for k in range(c.count[0]):
        s = st.body[k]
        key = st.keys[k]
        if c.kind[k] == PENALTY and s >= 0 and sh.slot[s] >= 0 and st.active[key] and st.load[key] > 0.0:
            pressing[c.node[k, 0]] += c.weight[k, 0] * st.load[key]
            pressing[c.node[k, 1]] += c.weight[k, 1] * st.load[key]
            found = True
    if not found:
        return
    # the cable's bending carries a body's load to the nodes beside those it presses: a static row may take what free
    # bodies press within NEAR_NODES of its nodes (unspread, the table rows beside a 3 kg box stayed 8 % too deep)
    near = np.zeros(n)
    for i in range(n):
        for j in range(max(0, i - NEAR_NODES), min(n, i + NEAR_NODES + 1)):
            near[i] += pressing[j]
    floor = LOAD_DEPTH * c.radius[0]
    for k in range(c.count[0]):
        s = st.body[k]
        if c.kind[k] != PENALTY or s < 0 or c.k_n[k] <= 0.0 or not st.active[st.keys[k]]:
            continue  # (a wrap, self or other-cable row; a row that pushes nothing; a new row: no load yet)
        key = st.keys[k]
        if sh.slot[s] >= 0:
            load = st.load[key]
        elif sh.inv_mass[s] == 0.0:  # a static row: only as far as free bodies press its nodes (not a squeeze's load)
            load = min(st.load[key], c.weight[k, 0] * near[c.node[k, 0]] + c.weight[k, 1] * near[c.node[k, 1]])
        else:
            continue
        base = c.k_n[k]
        k_new = min(LOAD_STIFFNESS_MAX * base, max(base, load / floor))
        if k_new <= base:
            continue
        g = _gap(c, k, x)
        if g < 0.0 and k_new > st.stiffness[key]:
            deeper = -g * (1.0 - st.stiffness[key] / k_new)
            for j in range(3):
                c.point[k, j] -= deeper * c.normal[k, j]
            st.sink[key] += deeper
            g += deeper
        scale = k_new / base
        c.k_n[k] = k_new
        c.k_t[k] *= scale
        c.c_n[k] *= math.sqrt(scale)
        c.cap[k] = c.static_friction[k] * k_new * (-g) if g < 0.0 else 0.0


@njit(cache=True, error_model="numpy")
def _pay_release(c, st, x, previous, released):
    """The work [J] of letting out the sink (:class:`Store`): each row detected now whose key (previous[j]) let out
    released[j] [m] this step has its surface point that much closer to the cable, and the penalty holds
    1/2 k_n (min(0, g)^2 - min(0, g + released)^2) more at x [m]: work the body did on the cable, added to
    c.body_work[0]. Unbooked, a 3 kg box dropped off-centre on the cable at 120 Hz, its corner hitting the ground,
    had the 0.08 J of lifting itself out of its 2.8 mm sink counted as energy made, and was stopped."""
    for k in range(c.count[0]):
        key = st.keys[k]
        if c.kind[k] == WRAP:
            continue  # (a row wrapped again: its sink is gone, :func:`_clear_sink`)
        for j in range(previous.shape[0]):
            if previous[j] == key and released[j] > 0.0:
                g = _gap(c, k, x)
                e, e_held = min(0.0, g), min(0.0, g + released[j])
                c.body_work[0] += 0.5 * c.k_n[k] * (e * e - e_held * e_held)


@njit(cache=True, error_model="numpy", inline="always")
def _sweep(sh, s, hu, h):
    """Twice the farthest [m] a point of shape row s (:class:`Shapes`) moves in a step of h [s] by its body's velocity:
    2 h (|U| + |Omega| R), R [m] the shape's reach from the body's centre of mass (its bounding sphere about its
    frame, a hull's box corner, plus the frame's offset). Zero for a body at rest and for a PROBE row (not counted).

    The cable's margin counts the cable's motion only; a body moving into the cable faster than that margin per step
    was met only once it was inside it (a 0.3 kg box tipping off a cable at 13 rad/s at 60 Hz: 9 mm in, then
    stopped as energy growth)."""
    w = math.sqrt(sh.ang_vel[s, 0] ** 2 + sh.ang_vel[s, 1] ** 2 + sh.ang_vel[s, 2] ** 2)
    u = math.sqrt(sh.lin_vel[s, 0] ** 2 + sh.lin_vel[s, 1] ** 2 + sh.lin_vel[s, 2] ** 2)
    if w == 0.0 and u == 0.0:
        return 0.0
    kind, size = sh.kind[s], sh.size[s]
    if kind == BOX:
        extent = math.sqrt(size[0] ** 2 + size[1] ** 2 + size[2] ** 2)
    elif kind == SPHERE:
        extent = size[0]
    elif kind == CYLINDER:
        extent = math.sqrt(size[0] ** 2 + size[1] ** 2)
    elif kind == CAPSULE:
        extent = size[0] + size[1]
    elif kind == HULL:
        r, r2 = hu.row[s], 0.0
        for j in range(3):
            r2 += max(abs(hu.lo[r, j]), abs(hu.hi[r, j])) ** 2
        extent = math.sqrt(r2) + hu.margin[r]
    else:
        return 0.0
    off = math.sqrt((sh.pos[s, 0] - sh.com[s, 0]) ** 2 + (sh.pos[s, 1] - sh.com[s, 1]) ** 2
                    + (sh.pos[s, 2] - sh.com[s, 2]) ** 2)
    return 2.0 * h * (u + w * (extent + off))


@njit(cache=True, error_model="numpy")
def quiet(x, v, h, sh, hu, radius, self_mu, h_body):
    """Whether :func:`detect` of positions x [m] (n, 3), velocities v [m/s], a cable step of h [s] in a Bullet step
    of h_body [s] would find no contact, by its own tests: every :class:`Shapes` row out of reach by its cull
    (:func:`_out_of_reach` with the row's margin; PROBE rows are skipped there, a HULL row near (``hu``) is not
    culled) and, unless self_mu[0] < 0, no pair of segments within the margin (:func:`_self_touches`). With no
    contact in the last step, no probed answer, no other cable and no free body, such a detect() changes nothing but
    the count (0): the caller skips it (``ContactSet.update``)."""
    vmax = _largest_speed(v)
    r = radius[0]
    margin = r + 2.0 * vmax * h + 1e-3
    n = x.shape[0]
    q = np.empty((n, 3))
    kind = sh.kind
    for s in range(kind.shape[0]):
        if kind[s] == PROBE:
            continue
        if kind[s] == HULL:
            if hu.near[s]:
                return False
            continue
        R, P = sh.rot[s], sh.pos[s]
        for i in range(n):  # nodes in the shape frame, as detect() computes them
            for j in range(3):
                q[i, j] = (R[0, j] * (x[i, 0] - P[0]) + R[1, j] * (x[i, 1] - P[1]) + R[2, j] * (x[i, 2] - P[2]))
        if not _out_of_reach(q, kind[s], sh.size[s], r + margin + _sweep(sh, s, hu, h_body)):
            return False
    return not (self_mu[0] >= 0.0 and _self_touches(x, r, margin))


@njit(cache=True, error_model="numpy")
def quiet_with(a, x, v, h, h_body):
    """:func:`quiet` on a set's packed arrays ``a`` (:class:`~bullet_dlo.bullet.contact_call.SetArgs`)."""
    return quiet(x, v, h, a.shapes, a.hulls, a.contacts.reach, a.self_mu, h_body)


@njit(cache=True, error_model="numpy")
def _load_free_bodies(c, bd, st, sh):
    """The free bodies' mass, world inertia and velocity now into the contact step's Bodies ``bd``, and each
    row's slot (-1: not on a free body, or on a shared one) and arm [m] from the body's centre of mass."""
    for k in range(c.count[0]):
        s = st.body[k]
        bd.slot[k] = sh.slot[s] if s >= 0 and c.kind[k] == PENALTY else -1
        if bd.slot[k] >= 0:
            for j in range(3):
                bd.arm[k, j] = c.point[k, j] - sh.com[s, j]
    for s in range(sh.kind.shape[0]):
        o = sh.slot[s]
        if o < 0:
            continue
        bd.mass[o] = 1.0 / sh.inv_mass[s]
        for j in range(3):
            bd.vel[o, j] = sh.lin_vel[s, j]
            bd.vel[o, 3 + j] = sh.ang_vel[s, j]
            for q in range(3):
                bd.inertia[o, j, q] = sh.inertia[s, j, q]


@njit(cache=True, error_model="numpy")
def _condense_bodies(c, st, sh, x, v, h):
    """Put each dynamic body's inertia into its contacts (see :class:`ContactSet`).

    K [N/m, N, N m] (6, 6): the stiffness the body meets through its contacts that may carry load in
    the step (predicted gap g + h n.(v_p - u_b) below a quarter of the cable radius), each as k I
    on its point's motion v + w x r (k = k_n + c_n / h: k_t = k_n, and the damper over one step;
    isotropic, an upper bound); lambda [1/s^2]: the largest eigenvalue of K scaled by the body's
    inertia (1/M on translation, 1/I_min on rotation: again an upper bound), its fastest
    contact mode squared. Every contact on the body gets k_n, k_t, c_n and its friction cap scaled
    by 1 / (1 + h^2 lambda), h [s] the Bullet step in which the body answers: the body then meets at
    most lambda h^2 / (1 + lambda h^2) < 1 per step, inside the explicit limit, and for a body
    resting on N equal contacts this is the penalty in series with the body's inertia, k / (1 +
    N k h^2 / M). Static bodies are left alone.
    """
    count = c.count[0]
    nb = sh.kind.shape[0]
    any_dynamic = False
    for k in range(count):
        s = st.body[k]
        if s >= 0 and sh.inv_mass[s] > 0.0 and sh.slot[s] < 0:
            any_dynamic = True
            break
    if not any_dynamic:
        return
    K = np.zeros((nb, 6, 6))
    used = np.zeros(nb, np.bool_)
    r = np.empty(3)
    for k in range(count):
        s = st.body[k]
        if s < 0 or sh.inv_mass[s] <= 0.0 or sh.slot[s] >= 0:  # free bodies: in the step's solve instead
            continue
        a, b = c.node[k, 0], c.node[k, 1]
        wa, wb = c.weight[k, 0], c.weight[k, 1]
        g = -c.radius[0]
        q = 0.0
        for j in range(3):
            g += c.normal[k, j] * (wa * x[a, j] + wb * x[b, j] - c.point[k, j])
            q += c.normal[k, j] * (wa * v[a, j] + wb * v[b, j] - c.body_vel[k, j])
        if g + h * q > 0.25 * c.radius[0]:
            continue  # stays open through the step: carries nothing
        o = sh.owner[s]
        used[o] = True
        kk = c.k_n[k] + c.c_n[k] / h
        r2 = 0.0
        for j in range(3):
            r[j] = c.point[k, j] - sh.com[s, j]
            r2 += r[j] * r[j]
        # J = [I, -[r]x]: J^T J = [[I, -[r]x], [[r]x, |r|^2 I - r r^T]]
        Kb = K[o]
        for j in range(3):
            Kb[j, j] += kk
            for q2 in range(3):
                Kb[3 + j, 3 + q2] += kk * ((r2 if j == q2 else 0.0) - r[j] * r[q2])
        for (j, q2, sg) in ((1, 2, 1.0), (2, 1, -1.0), (2, 0, 1.0), (0, 2, -1.0), (0, 1, 1.0), (1, 0, -1.0)):
            # [r]x[j, q2]: [[0, -r2, r1], [r2, 0, -r0], [-r1, r0, 0]]; the entry is sg r[3 - j - q2]
            e = -sg * r[3 - j - q2]  # ([r]x)[j, q2]
            Kb[j, 3 + q2] -= kk * e
            Kb[3 + j, q2] += kk * e
    lam = np.zeros(nb)
    w = np.empty(6)
    y = np.empty(6)
    for o in range(nb):
        if not used[o]:
            continue
        sm = math.sqrt(sh.inv_mass[o])
        si = math.sqrt(sh.inv_inertia[o])
        scl = (sm, sm, sm, si, si, si)
        A = K[o]
        for j in range(6):
            for q2 in range(6):
                A[j, q2] *= scl[j] * scl[q2]
        # power iteration on the 6 x 6 positive semi-definite A; start off every axis
        for j in range(6):
            w[j] = 1.0 + 0.1 * j
        est = 0.0
        for _ in range(60):
            nrm = 0.0
            for j in range(6):
                acc = 0.0
                for q2 in range(6):
                    acc += A[j, q2] * w[q2]
                y[j] = acc
                nrm += acc * acc
            nrm = math.sqrt(nrm)
            if nrm == 0.0:
                break
            wn = 0.0
            for j in range(6):
                wn += w[j] * w[j]
            est = nrm / math.sqrt(wn)
            for j in range(6):
                w[j] = y[j] / nrm
        lam[o] = est
    for k in range(count):
        s = st.body[k]
        if s >= 0 and sh.inv_mass[s] > 0.0 and sh.slot[s] < 0:
            scale = 1.0 / (1.0 + h * h * lam[sh.owner[s]])
            c.k_n[k] *= scale
            c.k_t[k] *= scale
            c.c_n[k] *= scale
            c.cap[k] *= scale


@njit(cache=True, error_model="numpy")
def _out_of_reach(q, kind, size, reach):
    """True when the bounding box of the nodes q (n, 3) (shape frame) is farther than ``reach`` [m] from
    the shape's bounding box in some coordinate (an exact reject: every distance is at least that)."""
    for j in range(3):
        if kind == BOX:
            half = size[j]
        elif kind == SPHERE or j < 2:
            half = size[0]
        else:  # along a cylinder's or capsule's axis
            half = size[1] + (size[0] if kind == CAPSULE else 0.0)
        lo, hi = q[0, j], q[0, j]
        for i in range(1, q.shape[0]):
            lo = min(lo, q[i, j])
            hi = max(hi, q[i, j])
        if lo - reach > half or hi + reach < -half:
            return True
    return False


@njit(cache=True, error_model="numpy", inline="always")
def _may_reach_edge(qa, qb, P, ax, hl, reach):
    """False when segment qa-qb (shape frame) is farther than ``reach`` [m] from the box edge through P
    along axis ``ax`` (|t| <= hl) in some coordinate: then it cannot touch it (a cheap exact reject)."""
    near = True
    for j in range(3):
        lo, hi = min(qa[j], qb[j]) - reach, max(qa[j], qb[j]) + reach
        p = P[j]  # (read before the branches: see _gap in core/kernels/contact.py)
        if j == ax:
            near = near and not (lo > hl or hi < -hl)
        else:
            near = near and not (lo > p or hi < p)
    _last_use = qa, qb, P  # (a last use after the branches: tests/llvm_loops.py)
    return near


@njit(cache=True, error_model="numpy")
def _segments_closest(a0, a1, b0, b1):
    """Parameters (s, t) in [0, 1] of the closest points of segments a0-a1 and b0-b1."""
    d1 = a1 - a0
    d2 = b1 - b0
    r = a0 - b0
    aa = d1 @ d1
    ee = d2 @ d2
    ff = d2 @ r
    cc = d1 @ r
    bb = d1 @ d2
    den = aa * ee - bb * bb
    s = min(max((bb * ff - cc * ee) / den, 0.0), 1.0) if den > 1e-14 * aa * ee else 0.0
    t = (bb * s + ff) / ee
    if t < 0.0:
        t = 0.0
        s = min(max(-cc / aa, 0.0), 1.0)
    elif t > 1.0:
        t = 1.0
        s = min(max((bb - cc) / aa, 0.0), 1.0)
    return s, t


@njit(cache=True, error_model="numpy")
def _self_pairs_brute(x, skip, reach):
    """Segment pairs (i, j), j > i + skip, whose first nodes are within ``reach`` [m], as codes i n + j in
    increasing order: every pair tried, O(n^2) (the reference of :func:`_self_pairs`)."""
    n = x.shape[0]
    reach2 = reach * reach
    out = np.empty(16, np.int64)
    k = 0
    for i in range(n - 1):
        for j in range(i + 1 + skip, n - 1):
            d2 = (x[i, 0] - x[j, 0]) ** 2 + (x[i, 1] - x[j, 1]) ** 2 + (x[i, 2] - x[j, 2]) ** 2
            if d2 > reach2:
                continue
            if k == out.shape[0]:
                out = np.concatenate((out, np.empty(k, np.int64)))
            out[k] = i * n + j
            k += 1
    return out[:k]


@njit(cache=True, error_model="numpy")
def _self_pairs(x, skip, reach):
    """The pairs of :func:`_self_pairs_brute` (same set, same order): from the grid (:func:`_grid_pairs`)
    above SMALL_N nodes, by trying every pair below (faster there)."""
    if x.shape[0] <= SMALL_N:
        return _self_pairs_brute(x, skip, reach)
    return _grid_pairs(x, skip, reach)


@njit(cache=True, error_model="numpy")
def _grid_pairs(x, skip, reach):
    """The pairs of :func:`_self_pairs_brute` (same set, same order) from a uniform grid of cells of side
    >= ``reach`` [m] over the first nodes of the segments: a pair within reach lies in neighbouring cells,
    so each node looks at the 27 cells around its own, O(n log n) (one sort of the cells).
    Non-finite positions: the brute search."""
    n = x.shape[0]
    m = n - 1  # segments, each placed at its first node
    if m < 1:
        return np.empty(0, np.int64)
    lo = np.empty(3)
    hi = np.empty(3)
    for j in range(3):
        lo[j] = x[0, j]
        hi[j] = x[0, j]
    for i in range(m):
        for j in range(3):
            if not math.isfinite(x[i, j]):
                return _self_pairs_brute(x, skip, reach)
            lo[j] = min(lo[j], x[i, j])
            hi[j] = max(hi[j], x[i, j])
    # cells of side >= reach, at most 2^20 per axis (bigger cells only add candidates, never lose one)
    side = max(reach, 1e-12)
    for j in range(3):
        side = max(side, (hi[j] - lo[j]) / 1048575.0)
    dims = np.empty(3, np.int64)
    for j in range(3):
        dims[j] = int((hi[j] - lo[j]) / side) + 1
    cell = np.empty((m, 3), np.int64)
    key = np.empty(m, np.int64)
    for i in range(m):
        for j in range(3):
            cell[i, j] = min(int((x[i, j] - lo[j]) / side), dims[j] - 1)
        key[i] = (cell[i, 0] * dims[1] + cell[i, 1]) * dims[2] + cell[i, 2]
    order = np.argsort(key, kind="mergesort")
    sorted_key = key[order]
    reach2 = reach * reach
    out = np.empty(16, np.int64)
    k = 0
    row = np.empty(16, np.int64)  # the partners j of segment i, sorted before they are appended (no global sort)
    for i in range(m):
        c_i = 0
        for a in range(max(cell[i, 0] - 1, 0), min(cell[i, 0] + 2, dims[0])):
            for b in range(max(cell[i, 1] - 1, 0), min(cell[i, 1] + 2, dims[1])):
                for c in range(max(cell[i, 2] - 1, 0), min(cell[i, 2] + 2, dims[2])):
                    kc = (a * dims[1] + b) * dims[2] + c
                    first = np.searchsorted(sorted_key, kc)
                    for q in range(first, m):
                        if sorted_key[q] != kc:
                            break
                        j = order[q]
                        if j <= i + skip:
                            continue  # close along the cable, or found from j's side
                        d2 = (x[i, 0] - x[j, 0]) ** 2 + (x[i, 1] - x[j, 1]) ** 2 + (x[i, 2] - x[j, 2]) ** 2
                        if d2 > reach2:
                            continue
                        if c_i == row.shape[0]:
                            row = np.concatenate((row, np.empty(c_i, np.int64)))
                        p = c_i  # insertion sort: the rows are short
                        while p > 0 and row[p - 1] > j:
                            row[p] = row[p - 1]
                            p -= 1
                        row[p] = j
                        c_i += 1
        while k + c_i > out.shape[0]:
            out = np.concatenate((out, np.empty(out.shape[0], np.int64)))
        for p in range(c_i):
            out[k + p] = i * n + row[p]
        k += c_i
    return out[:k]


@njit(cache=True, error_model="numpy", inline="always")
def _self_candidates(x, radius, margin):
    """The candidate pairs of segments of :func:`_self_contacts` (codes i n + j, :func:`_self_pairs`)."""
    l0 = 0.0
    for j in range(3):
        l0 += (x[1, j] - x[0, j]) ** 2
    # segments closer along the cable than pi r (a loop tighter than the cable is thick) never touch, and
    # those within 2 r + margin would be near each other on a straight cable: both are left out
    skip = 1 + int(math.ceil(max(math.pi * radius, 2.0 * radius + margin) / max(math.sqrt(l0), 1e-12)))
    reach = 2.5 * math.sqrt(l0) + 2.0 * radius + margin  # first nodes farther apart: the segments cannot touch
    return _self_pairs(x, skip, reach)


@njit(cache=True, error_model="numpy")
def _self_touches(x, radius, margin):
    """Whether :func:`_self_contacts` may add a row: a candidate pair of segments of x closer than 2 radius + margin
    [m] (every row of a pair is at least that far apart)."""
    n = x.shape[0]
    for code in _self_candidates(x, radius, margin):
        i, j = code // n, code % n
        s, t = _segments_closest(x[i], x[i + 1], x[j], x[j + 1])
        d2 = 0.0
        for q in range(3):
            d2 += ((1.0 - s) * x[i, q] + s * x[i + 1, q] - (1.0 - t) * x[j, q] - t * x[j + 1, q]) ** 2
        if d2 < (2.0 * radius + margin) ** 2:
            return True
    return False


@njit(cache=True, error_model="numpy")
def _self_contacts(x, v, h, mass, c, st, key0, self_mu, margin, k_per_mass, zeta):
    """Contacts between segments of the cable that are not close along it (a cable lying across or along itself).

    Per candidate pair of segments i < j (from a grid, :func:`_self_pairs`, in the order of a loop over i then j),
    the rows of their closest features, by the rules of :func:`_cable_contacts` with the cable as the other cable:
    the two edges where they cross at an angle that defines them (:func:`_crossing`), and each node either segment
    owns (the segment that starts at it; the last node with the last segment) where the other segment holds its
    closest point on the centre line near it (:func:`_node_on`). A cable folded or coiled along itself then touches
    at every node of both strands (one closest pair per segment pair left nodes without a row: they sank into the
    other strand and the Newton steps stopped converging; the lower strand of a fold felt up to 57 times the upper
    one's weight). Each contact is two rows (:func:`_self_row`).
    """
    n = x.shape[0]
    m = n - 1
    r2 = 2.0 * c.radius[0]
    for code in _self_candidates(x, c.radius[0], margin):
        i, j = code // n, code % n  # i < j - 1: segment i never owns the last node
        s, t = _segments_closest(x[i], x[i + 1], x[j], x[j + 1])
        if SNAP < s < 1.0 - SNAP and SNAP < t < 1.0 - SNAP and _crossing(x[i], x[i + 1], x[j], x[j + 1], r2):
            if not _self_row(x, v, h, mass, c, st, key0 + 2 * (i * m + j), i, s, j, t, self_mu, margin,
                             k_per_mass, zeta):
                return
        t = _node_on(x[i], x, j, 0, n)  # node i on segment j
        if t >= 0.0 and not _self_row(x, v, h, mass, c, st, key0 + 2 * (m * m + i * m + j), i, 0.0, j, t,
                                      self_mu, margin, k_per_mass, zeta):
            return
        for b in range(j, j + 1 + (1 if j == n - 2 else 0)):  # segment j's nodes on segment i
            s = _node_on(x[b], x, i, 0, n)
            if s >= 0.0 and not _self_row(x, v, h, mass, c, st, key0 + 2 * (m * m + b * m + i), i, s, b, 0.0,
                                          self_mu, margin, k_per_mass, zeta):
                return


@njit(cache=True, error_model="numpy")
def _self_row(x, v, h, mass, c, st, key, i, s, j, t, self_mu, margin, k_per_mass, zeta):
    """The two rows (keys ``key`` and key + 1) between the cable's point at s on segment i and its point at t on
    segment j (a node index j = n - 1 with t 0 is the last node), when their capsules are within ``margin`` [m].

    Each side's row is against the plane through the midpoint of the two centre-line points, normal to the line
    between them, held over the step (lagged: the Newton matrix stays banded; extrapolating the other side at its
    velocity pushed a falling segment through the one it lands on), with the stiffness of the pair's mean mass:
    each side takes up half the penetration, equal and opposite forces at rest. (Against the other side's capsule
    held where it was, each side took up all of it while the other did too: the pair left at twice the speed that
    undoes the penetration, and a coil settling on itself felt 10-25 times its weight in net self-contact force.)

    Friction acts on the slip of one side over the other: the two sides' stick offsets (material point minus anchor)
    are made equal and opposite at each detection, so the anchors move with the pair's midpoint, and over the step
    with the pair's mean velocity v [m/s] (h [s]: the step); each side takes up half the slip. (Anchored in the
    world, a coil settling as a whole was braked by slip it did not make; a side that slid while the other stuck
    left offsets in the same direction, a net self force of 5 % of the weight that stayed once both stuck.) The
    stick spring is SELF_STICK of the penalty stiffness: at the penalty's (k h^2 / m = 1e4) the lagged sticking of
    the two sides pumped a soft coil at 240 Hz to a stop in 30 steps; at 1 % a stuck row gives 100 mu times the
    penetration of slip before it slides. Returns False when the rows are full."""
    n = x.shape[0]
    if j == n - 1:
        j, t = n - 2, 1.0
    radius = c.radius[0]
    d2 = 0.0
    for q in range(3):
        d2 += ((1.0 - s) * x[i, q] + s * x[i + 1, q] - (1.0 - t) * x[j, q] - t * x[j + 1, q]) ** 2
    d = math.sqrt(d2)
    if d == 0.0 or d - 2.0 * radius >= margin:
        return True
    m_pair = 0.5 * ((1.0 - s) * mass[i] + s * mass[i + 1] + (1.0 - t) * mass[j] + t * mass[j + 1])
    k0 = c.count[0]
    if k0 + 1 >= c.node.shape[0]:
        return False
    for side in range(2):
        k = k0 + side
        a, u, b, w = (i, s, j, t) if side == 0 else (j, t, i, s)
        for q in range(3):
            nq = ((1.0 - s) * x[i, q] + s * x[i + 1, q] - (1.0 - t) * x[j, q] - t * x[j + 1, q]) / d
            c.normal[k, q] = nq if side == 0 else -nq
            c.point[k, q] = 0.5 * ((1.0 - u) * x[a, q] + u * x[a + 1, q] + (1.0 - w) * x[b, q] + w * x[b + 1, q])
            c.body_vel[k, q] = 0.0  # the plane held where it is
        c.internal[k] = True
        _fill(c, st, key + side, -1, a, a + 1, 1.0 - u, u, self_mu[0], self_mu[1], k_per_mass * m_pair, zeta,
              m_pair, x)
        c.k_t[k] = SELF_STICK * c.k_n[k]
    # the anchors: the two sides' stick offsets made equal and opposite (half their difference each), so that they
    # move with the midpoint of the material points the slips are measured at; then over the step at its velocity
    a0, s0, a1, s1 = c.node[k0, 0], c.anchor[k0, 3], c.node[k0 + 1, 0], c.anchor[k0 + 1, 3]
    for q in range(3):
        p0 = (1.0 - s0) * x[a0, q] + s0 * x[a0 + 1, q]
        p1 = (1.0 - s1) * x[a1, q] + s1 * x[a1 + 1, q]
        v_mid = 0.5 * ((1.0 - s0) * v[a0, q] + s0 * v[a0 + 1, q] + (1.0 - s1) * v[a1, q] + s1 * v[a1 + 1, q])
        half = 0.5 * ((p0 - c.anchor[k0, q]) - (p1 - c.anchor[k0 + 1, q]))
        c.anchor[k0, q] = p0 - half + h * v_mid
        c.anchor[k0 + 1, q] = p1 + half + h * v_mid
    return True


@njit(cache=True, error_model="numpy")
def _cable_moved(c, st, oc, count, h_done):
    """The last step's contacts with other cables (rows < count, their friction state persisted by key):
    the other cable's point moved by d = (where it is now) - (where it was + h_done u), u what this
    cable's step assumed (0: held). Its work on this cable, f . d, is counted, and the friction anchor
    moves with it (it is tied to the other cable's surface)."""
    for k in range(count):
        if st.body[k] != CABLE:
            continue
        i0, i1 = oc.row_node[k, 0], oc.row_node[k, 1]
        w0, w1 = oc.row_w[k, 0], oc.row_w[k, 1]
        key = st.keys[k]
        fn = max(c.f_n[k], 0.0)
        for j in range(3):
            d = w0 * oc.x[i0, j] + w1 * oc.x[i1, j] - oc.row_p0[k, j] - h_done * c.body_vel[k, j]
            c.body_work[0] += (fn * c.normal[k, j] + c.f_t[k, j]) * d
            st.anchor[key, j] += d


SELF_STICK = 0.01  # [-] a self-contact row's stick stiffness over its penalty stiffness (see _self_row)
SNAP = 1e-9  # [-] an edge-edge closest point this near a segment's end is the end's node (a node row's)
CROSSING = 0.1  # [-] two segments cross (an edge-edge row) when sin(angle) x the shorter exceeds this x r1 + r2


@njit(cache=True, error_model="numpy")
def _cable_contacts(x, mass, c, st, oc, key0, margin, k_per_mass, zeta):
    """Contacts of this cable's segments with the other cables' segments (capsules of each cable's radius).

    Per pair of segments within reach, the rows of their closest features (the point-edge and edge-edge
    distances of rod contact): (1) the two edges, where their closest points lie inside both and the segments
    cross at an angle that defines them (:func:`_crossing`); (2) each node of this cable against the other
    segment, where that segment holds the node's closest point on the other centre line near it (:func:`_node_on`:
    one row where the line bends, or where the node lies over one of its nodes); (3) each node of the other cable
    against this segment, by the same rule. Each node is taken once, with the segment that starts at it (the last
    node with the last segment). Cables lying along each other then touch at every node of both (two parallel
    segments have no single closest point pair: taken as one, the last node of a cable lying on another had no
    row and sank into it, and rounding at shared nodes doubled rows, so that the two cables' steps held different
    forces). The rules are the same with the two cables swapped, so the other cable's contact set holds the same
    rows, with the same stiffness (the pair's mean mass at the point): equal and opposite forces at rest. The
    other cable's capsule is a body whose surface moves at oc.u over the step (the other cable's planned step, or
    held), with the combined friction. Broad phase: each other cable's bounding box, then node distances
    (segments whose first nodes are farther apart than both segments' lengths plus the reach cannot touch)."""
    n = x.shape[0]
    radius = c.radius[0]
    N = oc.x.shape[0]
    lo = np.empty(3)
    hi = np.empty(3)
    for j in range(3):
        lo[j] = x[0, j]
        hi[j] = x[0, j]
    l_own = 0.0
    for i in range(n):
        for j in range(3):
            lo[j] = min(lo[j], x[i, j])
            hi[j] = max(hi[j], x[i, j])
        if i < n - 1:
            l_own = max(l_own, math.sqrt((x[i + 1, 0] - x[i, 0]) ** 2 + (x[i + 1, 1] - x[i, 1]) ** 2
                                         + (x[i + 1, 2] - x[i, 2]) ** 2))
    for cc in range(oc.first.shape[0] - 1):
        a0, a1 = oc.first[cc], oc.first[cc + 1]
        rb = oc.radius[a0]
        reach = radius + rb + margin
        out = False
        for j in range(3):
            olo, ohi = oc.x[a0, j], oc.x[a0, j]
            for q in range(a0 + 1, a1):
                olo = min(olo, oc.x[q, j])
                ohi = max(ohi, oc.x[q, j])
            if olo - reach > hi[j] or ohi + reach < lo[j]:
                out = True
        if out:
            continue  # the bounding boxes are farther apart than the reach
        l_oth = 0.0
        for q in range(a0, a1 - 1):
            l_oth = max(l_oth, math.sqrt((oc.x[q + 1, 0] - oc.x[q, 0]) ** 2 + (oc.x[q + 1, 1] - oc.x[q, 1]) ** 2
                                         + (oc.x[q + 1, 2] - oc.x[q, 2]) ** 2))
        pair_reach = l_own + l_oth + reach
        pair_reach2 = pair_reach * pair_reach
        for i in range(n - 1):
            for q in range(a0, a1 - 1):
                d2 = (x[i, 0] - oc.x[q, 0]) ** 2 + (x[i, 1] - oc.x[q, 1]) ** 2 + (x[i, 2] - oc.x[q, 2]) ** 2
                if d2 > pair_reach2:
                    continue
                # (1) the edges, crossing at an angle their closest points are well defined at
                s, t = _segments_closest(x[i], x[i + 1], oc.x[q], oc.x[q + 1])
                if (SNAP < s < 1.0 - SNAP and SNAP < t < 1.0 - SNAP
                        and _crossing(x[i], x[i + 1], oc.x[q], oc.x[q + 1], radius + rb)):
                    if not _cable_row(x, mass, c, st, oc, key0 + i * N + q, i, s, q, t, rb, margin, k_per_mass,
                                      zeta):
                        return
                # (2) this cable's nodes the segment owns (each node once) where the other segment is closest
                for a in range(i, i + 1 + (1 if i == n - 2 else 0)):
                    t = _node_on(x[a], oc.x, q, a0, a1)
                    if t >= 0.0 and not _cable_row(x, mass, c, st, oc, key0 + (n - 1 + a) * N + q, a, 0.0, q, t,
                                                   rb, margin, k_per_mass, zeta):
                        return
                # (3) the other cable's nodes its segment owns where this segment is closest (the same rule)
                for b in range(q, q + 1 + (1 if q == a1 - 2 else 0)):
                    s = _node_on(oc.x[b], x, i, 0, n)
                    if s >= 0.0 and not _cable_row(x, mass, c, st, oc, key0 + (2 * n - 1 + i) * N + b, i, s, q,
                                                   float(b - q), rb, margin, k_per_mass, zeta):
                        return


@njit(cache=True, error_model="numpy")
def _crossing(a0, a1, b0, b1, reach):
    """Whether segments a0-a1 and b0-b1 cross at an angle theta whose edge-edge row the node rows cannot stand for:
    sin(theta) times the shorter length above CROSSING of the centre lines' contact distance ``reach`` [m] (below,
    the node rows leave at most (CROSSING reach / 2)^2 / (2 reach) = reach / 800 of penetration between them, and
    the closest points of two nearly parallel segments are ill defined: the two cables' sets took them
    differently, rows on one side only)."""
    aa = 0.0
    ee = 0.0
    ab = 0.0
    for j in range(3):
        da = a1[j] - a0[j]
        db = b1[j] - b0[j]
        aa += da * da
        ee += db * db
        ab += da * db
    if aa <= 0.0 or ee <= 0.0:
        return False
    sin2 = max(0.0, 1.0 - ab * ab / (aa * ee))
    return sin2 * min(aa, ee) > (CROSSING * reach) ** 2


@njit(cache=True, error_model="numpy")
def _projection(p, a, b):
    """The parameter in [0, 1] of the point of segment a-b closest to p."""
    num = 0.0
    den = 0.0
    for j in range(3):
        d = b[j] - a[j]
        num += (p[j] - a[j]) * d
        den += d * d
    if den <= 0.0:
        return 0.0
    return min(max(num / den, 0.0), 1.0)


@njit(cache=True, error_model="numpy")
def _node_on(p, ox, q, a0, a1):
    """Where node p meets segment q of a centre line ox (its nodes a0 .. a1 - 1): the parameter in [0, 1] of the
    point of segment q closest to p when that is a closest point of the whole line near there (p nearer to segment q
    than to the one before it, and no nearer to the one after it: one row where the line bends about the point
    next to p, or where p lies over a node of it), else -1."""
    t = _projection(p, ox[q], ox[q + 1])
    d = _distance2(p, ox[q], ox[q + 1], t)
    if q > a0 and not d < _distance2(p, ox[q - 1], ox[q], _projection(p, ox[q - 1], ox[q])):
        return -1.0
    if q < a1 - 2 and not d <= _distance2(p, ox[q + 1], ox[q + 2], _projection(p, ox[q + 1], ox[q + 2])):
        return -1.0
    return t


@njit(cache=True, error_model="numpy")
def _distance2(p, a, b, t):
    """Squared distance [m^2] from p to the point at t of segment a-b."""
    d2 = 0.0
    for j in range(3):
        d2 += (p[j] - ((1.0 - t) * a[j] + t * b[j])) ** 2
    return d2


@njit(cache=True, error_model="numpy")
def _cable_row(x, mass, c, st, oc, key, i, s, q, t, rb, margin, k_per_mass, zeta):
    """A row between this cable's point at s on segment i (its last node: i n - 1, s 0) and the other cable's
    point at t on its segment q, when their capsules are within ``margin``. Returns False when the rows are
    full."""
    n = x.shape[0]
    if i == n - 1:
        i, s = n - 2, 1.0
    d2 = 0.0
    nl = np.empty(3)
    for j in range(3):
        nl[j] = ((1.0 - s) * x[i, j] + s * x[i + 1, j]) - ((1.0 - t) * oc.x[q, j] + t * oc.x[q + 1, j])
        d2 += nl[j] ** 2
    d = math.sqrt(d2)
    if d == 0.0 or d - c.radius[0] - rb >= margin:
        return True
    k = c.count[0]
    if k >= c.node.shape[0]:
        return False
    for j in range(3):
        nl[j] /= d
        p0 = (1.0 - t) * oc.x[q, j] + t * oc.x[q + 1, j]
        oc.row_p0[k, j] = p0
        c.normal[k, j] = nl[j]
        c.point[k, j] = p0 + rb * nl[j]
        c.body_vel[k, j] = (1.0 - t) * oc.u[q, j] + t * oc.u[q + 1, j]
    oc.row_node[k, 0], oc.row_node[k, 1] = q, q + 1
    oc.row_w[k, 0], oc.row_w[k, 1] = 1.0 - t, t
    c.internal[k] = False
    m_pair = 0.5 * ((1.0 - s) * mass[i] + s * mass[i + 1] + (1.0 - t) * oc.mass[q] + t * oc.mass[q + 1])
    _fill(c, st, key, CABLE, i, i + 1, 1.0 - s, s, oc.static_friction[q], oc.dynamic_friction[q],
          k_per_mass * m_pair, zeta, m_pair, x)
    return True
