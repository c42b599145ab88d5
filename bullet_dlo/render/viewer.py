"""A browser viewer of a recorded run: one self-contained HTML file, or a live page on the loopback.

:func:`write_viewer` turns a :class:`Run` (a recorded cable, and when there are arms their joint
angles, grasp poses and wrist wrenches; obstacles; see :func:`bullet_dlo.data.runs.load_run` for
the files it reads) into a single ``.html`` file that opens in a browser from disk (``file://``),
with no Python process, no server and no network. :func:`serve` shows the same scene live at
``http://127.0.0.1:PORT`` with a frame slider. What it draws, per recorded row:

* the cable as a tube of its diameter (a cylinder per segment) with a thin centre line that keeps it
  visible from afar, and the masses as discs of the cable's diameter;
* both arms from their URDFs (the composed arm + gripper PyBullet loads,
  :func:`bullet_dlo.robots.compose.robot_urdf`) at the recorded joint angles; PyBullet's forward
  kinematics in a DIRECT client gives every link's pose and its visual meshes. Each base is placed
  where the recorded grasp pose says it is (base = grasp pose x FK(q)^-1 at the first row);
* the ground, the table of a dual-arm scene and the scene's obstacles: boxes, cylinders and URDF
  bodies (every link's visual shapes, joints at zero; :func:`urdf_geometry`);
* each wrist's force (tared, world frame) as an arrow at its grasp point, and a time plot of both
  wrists (sensor solid, model dashed, :func:`bullet_dlo.render.plots.plot_wrenches`) standing
  behind the scene with a cursor at the shown time;
* contacts: masses whose sphere (the cable's radius) is within 1 mm of the ground, table or an
  obstacle, as points, and with an arrow of the estimated contact force where the cable model is
  known: m a - f_model(x, v) at that mass (a from the recorded velocities; the contact solver's
  own forces are not recorded), its component along the surface normal;
* a timeline (play, pause, scrub, speed) at the bottom of the page.

Why viser rather than rerun (both are pip packages; their installed sources were read for this):
viser's scene serializer (``ViserServer.get_scene_serializer().as_html()``) writes the whole
viewer, a three.js client of about 0.8 MB, with the recording inlined as base64 into one HTML
file that plays back with a timeline from ``file://``; it renders with WebGL, which headless
Chromium provides in software (SwiftShader), so the browser test checks real pixels. Rerun's
``.rrd`` is a recording, not a viewer: opening it needs the native viewer (a 290 MB binary in the
wheel) or its WebAssembly web viewer served over HTTP (``rerun --web-viewer``, a running
process) or fetched from app.rerun.io (the network, and the same version). Rerun has better
time plots (any series, zoomable); here the plot is a picture in the scene, and the live
``--serve`` page adds the numbers of the shown row. viser is an optional dependency
(``pip install 'bullet-dlo[view]'``); without it :func:`require_viser` says so in one line.
"""
from __future__ import annotations

import dataclasses
import io
import socket
import time
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from bullet_dlo.core.validate import ParameterError

MAX_FRAMES = 400
"""Most rows a viewer file holds by default (longer runs are subsampled evenly; ``max_frames``)."""
CABLE_RGB = (230, 30, 30)
NODE_RGB = (250, 200, 0)
ARM_RGB = (70, 110, 190)
"""Colour of a link whose URDF gives none (or plain white): the arms' blue in the page."""
CONTACT_RGB = (20, 200, 60)
OBSTACLE_RGB = (150, 150, 160)
TUBE_SIDES = 12  # facets around the cable's tube
FORCE_RGB = ((255, 140, 0), (160, 0, 200))
CONTACT_MARGIN = 1e-3  # [m] gap below which a mass counts as touching


@dataclasses.dataclass
class Run:
    """What the viewer shows (SI units; k rows, n masses, j arm joints).

    t (k,) [s]; cable_x (k, n, 3) [m]; radius: the cable's [m]; robot: arm name (None: no arms);
    joint_q (k, 2, j) [rad], ee_pos (k, 2, 3) [m], ee_quat (k, 2, 4) (x, y, z, w): per arm,
    left = the cable's first end; wrench_world (k, 2, 6) [N, N m]; end_forces (k, 2, 3) [N];
    cable_v (k, n, 3) [m/s] (None: from positions); cable: a :class:`~bullet_dlo.core.spec.CableSpec`
    (contact forces are estimated with it); ground_height [m] (None: no ground); table: (half
    extents, centre) of the table box [m]; obstacles: scene ``bullet.obstacles`` entries; source:
    what was read, for the title.
    """

    t: np.ndarray
    cable_x: np.ndarray
    radius: float = 0.002
    robot: str | None = None
    joint_q: np.ndarray | None = None
    ee_pos: np.ndarray | None = None
    ee_quat: np.ndarray | None = None
    wrench_world: np.ndarray | None = None
    end_forces: np.ndarray | None = None
    cable_v: np.ndarray | None = None
    cable: Any = None
    ground_height: float | None = 0.0
    table: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    obstacles: tuple[dict, ...] = ()
    source: str = "run"

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, dtype=float).reshape(-1)
        self.cable_x = np.asarray(self.cable_x, dtype=float)
        k = len(self.t)
        if k == 0 or self.cable_x.ndim != 3 or self.cable_x.shape[0] != k or self.cable_x.shape[2] != 3:
            raise ParameterError(f"{self.source}: cable positions must be (k, n, 3) with k = {k} rows of t, "
                                 f"got {self.cable_x.shape}")
        if not np.all(np.isfinite(self.cable_x)) or not np.all(np.isfinite(self.t)):
            raise ParameterError(f"{self.source}: cable positions or times are not finite")
        for name, width in (("joint_q", None), ("ee_pos", 3), ("ee_quat", 4), ("wrench_world", 6),
                            ("end_forces", 3)):
            value = getattr(self, name)
            if value is None:
                continue
            value = np.asarray(value, dtype=float)
            if value.ndim != 3 or value.shape[:2] != (k, 2) or (width and value.shape[2] != width):
                raise ParameterError(f"{self.source}: {name} must be (k, 2, {width or 'j'}) with k = {k}, "
                                     f"got {value.shape}")
            setattr(self, name, value)
        if self.robot is not None and (self.joint_q is None or self.ee_pos is None or self.ee_quat is None):
            raise ParameterError(f"{self.source}: arms need joint_q, ee_pos and ee_quat")

    @property
    def frames(self) -> int:
        return len(self.t)


def require_viser():
    """The viser module, or ParameterError in one line saying how to install it."""
    try:
        import viser
    except ModuleNotFoundError:
        raise ParameterError("the viewer needs viser: pip install 'bullet-dlo[view]' (or pip install viser)") from None
    return viser


# ----- arms: link poses and meshes from the URDF PyBullet loads -----------------------------------
@dataclasses.dataclass
class ArmGeometry:
    """One arm's visual shapes and their world poses per row: meshes[i] = (link, trimesh, rgb,
    local position, local wxyz); poses (k, links, 7): each link's URDF frame (x y z, w x y z)."""

    meshes: list
    link_ids: list[int]
    poses: np.ndarray


def _wxyz(q_xyzw: Sequence[float]) -> tuple[float, float, float, float]:
    return (float(q_xyzw[3]), float(q_xyzw[0]), float(q_xyzw[1]), float(q_xyzw[2]))


def visual_meshes(client: int, body: int, default_rgb: tuple[int, int, int]) -> list:
    """A loaded body's visual shapes as (link, trimesh, rgb, local position, local wxyz), local to each
    link's URDF frame (:func:`_link_pose`); ``default_rgb`` where the URDF gives no colour
    (or plain white)."""
    import pybullet as pb
    import trimesh

    cache: dict[str, Any] = {}
    meshes = []
    for shape in pb.getVisualShapeData(body, physicsClientId=client):
        link, geom, dims, fname, lpos, lorn, rgba = shape[1], shape[2], shape[3], shape[4], shape[5], shape[6], shape[7]
        if geom == pb.GEOM_MESH:
            fname = fname.decode() if isinstance(fname, bytes) else fname
            if fname not in cache:
                cache[fname] = trimesh.load(fname, force="mesh", process=False)
            mesh = cache[fname].copy()
            mesh.apply_scale(np.asarray(dims, dtype=float))
        elif geom == pb.GEOM_BOX:
            mesh = trimesh.creation.box(extents=np.asarray(dims, dtype=float))
        elif geom == pb.GEOM_CYLINDER:
            mesh = trimesh.creation.cylinder(radius=dims[1], height=dims[0])
        elif geom == pb.GEOM_SPHERE:
            mesh = trimesh.creation.icosphere(radius=dims[0], subdivisions=2)
        elif geom == pb.GEOM_CAPSULE:
            mesh = trimesh.creation.capsule(radius=dims[1], height=dims[0])
        else:
            continue
        rgb = tuple(int(255 * c) for c in rgba[:3])
        if min(rgb) >= 250 or rgba[3] == 0:
            rgb = default_rgb
        meshes.append((link, mesh, rgb, tuple(lpos), _wxyz(lorn)))
    return meshes


def _link_pose(client: int, body: int, link: int) -> tuple:
    """World pose (position, quaternion x y z w) of a link's URDF frame, the frame its visual shapes are
    given in (measured: ``getVisualShapeData``'s local frames are the URDF's ``<visual><origin>``); the
    link's centre of mass, which ``getBasePositionAndOrientation`` and ``getLinkState``'s first pair
    return, sits at its ``<inertial><origin>`` from it."""
    import pybullet as pb

    if link == -1:
        com = pb.getBasePositionAndOrientation(body, physicsClientId=client)
        inertial = pb.getDynamicsInfo(body, -1, physicsClientId=client)[3:5]
        return pb.multiplyTransforms(com[0], com[1], *pb.invertTransform(*inertial))
    st = pb.getLinkState(body, link, computeForwardKinematics=True, physicsClientId=client)
    return st[4], st[5]


def urdf_geometry(obstacles: Sequence[dict]) -> list[tuple[list, np.ndarray]]:
    """The scene's ``urdf`` obstacles as drawn: per obstacle, its visual meshes (see
    :func:`visual_meshes`) and each mesh's link pose (m, 7) (x y z, w x y z) at the obstacle's pose
    with its joints at zero. A file that does not load is skipped (the run was made with it)."""
    import pybullet as pb

    from bullet_dlo.bullet.world import resolve_asset

    out = []
    urdfs = [ob for ob in obstacles if ob.get("type") == "urdf"]
    if not urdfs:
        return out
    client = pb.connect(pb.DIRECT)
    try:
        for ob in urdfs:
            try:
                body = pb.loadURDF(str(resolve_asset(ob["path"])), list(ob.get("position", (0, 0, 0))),
                                   list(ob.get("orientation", (0, 0, 0, 1))), useFixedBase=True,
                                   flags=pb.URDF_USE_IMPLICIT_CYLINDER, physicsClientId=client)
            except (pb.error, ParameterError):
                continue
            meshes = visual_meshes(client, body, OBSTACLE_RGB)
            poses = np.zeros((len(meshes), 7))
            for i, (link, *_rest) in enumerate(meshes):
                p, o = _link_pose(client, body, link)
                poses[i, :3], poses[i, 3:] = p, _wxyz(o)
            out.append((meshes, poses))
    finally:
        pb.disconnect(client)
    return out


def arm_geometry(robot: str, joint_q: np.ndarray, ee_pos: np.ndarray, ee_quat: np.ndarray) -> list[ArmGeometry]:
    """Both arms' visual meshes and link poses at the recorded joint angles (k, 2, j)."""
    import pybullet as pb

    from bullet_dlo.config.robot import load_robot_spec
    from bullet_dlo.robots.compose import robot_urdf

    spec = load_robot_spec(robot)
    path = str(robot_urdf(spec))
    client = pb.connect(pb.DIRECT)
    try:
        body = pb.loadURDF(path, useFixedBase=True, physicsClientId=client)
        movable = [j for j in range(pb.getNumJoints(body, physicsClientId=client))
                   if pb.getJointInfo(body, j, physicsClientId=client)[2] != pb.JOINT_FIXED]
        if joint_q.shape[2] != len(movable):
            raise ParameterError(f"robot {robot!r} has {len(movable)} joints, the run recorded {joint_q.shape[2]}")
        grasp = next(j for j in range(pb.getNumJoints(body, physicsClientId=client))
                     if pb.getJointInfo(body, j, physicsClientId=client)[12].decode() == spec.grasp_link)
        meshes = visual_meshes(client, body, ARM_RGB)
        links = {m[0] for m in meshes}
        link_ids = sorted(links)
        out = []
        for arm in range(2):
            poses = np.zeros((len(joint_q), len(link_ids), 7))
            base = None
            for r, q in enumerate(joint_q[:, arm]):
                for j, value in zip(movable, q):
                    pb.resetJointState(body, j, float(value), physicsClientId=client)
                if base is None:  # world from base: the recorded grasp pose times the grasp pose in the base frame
                    gs = pb.getLinkState(body, grasp, computeForwardKinematics=True, physicsClientId=client)
                    inv = pb.invertTransform(gs[4], gs[5])
                    base = pb.multiplyTransforms(ee_pos[r, arm].tolist(), ee_quat[r, arm].tolist(), *inv)
                for c, link in enumerate(link_ids):
                    p, o = _link_pose(client, body, link)
                    wp, wo = pb.multiplyTransforms(base[0], base[1], p, o)
                    poses[r, c, :3] = wp
                    poses[r, c, 3:] = _wxyz(wo)
            out.append(ArmGeometry(meshes, link_ids, poses))
        return out
    finally:
        pb.disconnect(client)


# ----- contacts ----------------------------------------------------------------------------------
def _surfaces(run: Run) -> list[tuple[str, Any]]:
    out: list[tuple[str, Any]] = []
    if run.ground_height is not None:
        out.append(("plane", float(run.ground_height)))
    if run.table is not None:
        out.append(("box", (np.asarray(run.table[0]), np.asarray(run.table[1]), np.eye(3))))
    for ob in run.obstacles:
        rot = _rotation(ob.get("orientation", (0, 0, 0, 1)))
        if ob.get("type") == "box":
            out.append(("box", (np.asarray(ob["half_extents"], float), np.asarray(ob["position"], float), rot)))
        elif ob.get("type") == "cylinder":
            out.append(("cylinder", (float(ob["radius"]), float(ob["height"]), np.asarray(ob["position"], float), rot)))
    return out


def _rotation(q_xyzw: Sequence[float]) -> np.ndarray:
    x, y, z, w = (float(v) for v in q_xyzw)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _gap_normal(kind: str, geo: Any, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance from points p (n, 3) to a surface [m] (negative inside) and the outward normals."""
    if kind == "plane":
        return p[:, 2] - geo, np.tile([0.0, 0.0, 1.0], (len(p), 1))
    if kind == "box":
        he, c, rot = geo
        local = (p - c) @ rot
        d = np.abs(local) - he
        outside = np.linalg.norm(np.maximum(d, 0.0), axis=1)
        inside = np.minimum(d.max(axis=1), 0.0)
        gap = outside + inside
        q = np.clip(local, -he, he)
        n_out = local - q
        face = np.argmax(d, axis=1)
        n_in = np.zeros_like(local)
        n_in[np.arange(len(p)), face] = np.sign(local[np.arange(len(p)), face])
        nrm = np.where((outside > 1e-12)[:, None], n_out / np.maximum(outside, 1e-12)[:, None], n_in)
        return gap, nrm @ rot.T
    radius, height, c, rot = geo
    local = (p - c) @ rot
    rho = np.linalg.norm(local[:, :2], axis=1)
    dr, dz = rho - radius, np.abs(local[:, 2]) - height / 2
    gap = np.where((dr > 0) & (dz > 0), np.hypot(dr, dz), np.maximum(dr, dz))
    radial = np.column_stack([local[:, :2] / np.maximum(rho, 1e-12)[:, None], np.zeros(len(p))])
    axial = np.column_stack([np.zeros((len(p), 2)), np.sign(local[:, 2])])
    nrm = np.where((dr >= dz)[:, None], radial, axial)
    return gap, nrm @ rot.T


def contacts(run: Run) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Per row, the contact points [m] (c, 3) (on the surface below each touching mass) and the
    estimated normal contact forces [N] (c, 3) on the cable (zeros where the cable model is unknown)."""
    surfaces = _surfaces(run)
    model_force = _model_forces(run)
    points, forces = [], []
    for r in range(run.frames):
        x = run.cable_x[r]
        pts, fs = [], []
        for kind, geo in surfaces:
            gap, nrm = _gap_normal(kind, geo, x)
            touching = np.nonzero(gap - run.radius < CONTACT_MARGIN)[0]
            for i in touching:
                pts.append(x[i] - nrm[i] * gap[i])
                f = 0.0 if model_force is None else max(float(model_force[r, i] @ nrm[i]), 0.0)
                fs.append(f * nrm[i])
        points.append(np.asarray(pts, dtype=float).reshape(-1, 3))
        forces.append(np.asarray(fs, dtype=float).reshape(-1, 3))
    return points, forces


def _model_forces(run: Run) -> np.ndarray | None:
    """m a - f_model(x, v) per row and mass (k, n, 3) [N]: what the surroundings push on each mass with
    (held end masses too; only touching masses are read). None without a cable model."""
    if run.cable is None or run.frames < 3 or run.cable.n_masses != run.cable_x.shape[1]:
        return None
    from bullet_dlo.core.kernels.forces import total_forces
    from bullet_dlo.core.model import STANDARD_GRAVITY, build_arrays, kernel_arrays

    m = kernel_arrays(build_arrays(run.cable, "free", "free", np.asarray(STANDARD_GRAVITY, dtype=float)))
    if run.cable.twist_enabled:
        return None  # the twist terms need the material frame, which is not recorded
    t, x = run.t, run.cable_x
    v = run.cable_v if run.cable_v is not None else np.gradient(x, t, axis=0)
    a = np.gradient(v, t, axis=0)
    out = np.zeros_like(x)
    f = np.zeros(x.shape[1:])
    for r in range(len(t)):
        d = np.array([x[r, 1] - x[r, 0], x[r, -1] - x[r, -2]])
        dirs = d / np.linalg.norm(d, axis=1, keepdims=True)  # end tangents (the free ends' bending ignores them)
        total_forces(m, np.ascontiguousarray(x[r]), np.ascontiguousarray(v[r]), dirs, f)
        out[r] = m.mass[:, None] * a[r] - f
    return out


# ----- the scene -----------------------------------------------------------------------------------
def frame_rows(run: Run, max_frames: int = MAX_FRAMES) -> np.ndarray:
    """Indices of the rows shown: all of them, or ``max_frames`` evenly spaced (first and last kept)."""
    k = run.frames
    if k <= max_frames:
        return np.arange(k)
    return np.unique(np.linspace(0, k - 1, max_frames).round().astype(int))


def _plot_image(run: Run) -> tuple[np.ndarray, Any] | None:
    if run.wrench_world is None and run.end_forces is None:
        return None
    import tempfile

    import imageio.v3 as iio

    from bullet_dlo.render.plots import plot_wrenches

    model = run.end_forces if run.end_forces is not None else np.zeros((run.frames, 2, 3))
    sensor = run.wrench_world[:, :, :3] if run.wrench_world is not None else None
    with tempfile.TemporaryDirectory() as tmp:
        info = plot_wrenches(run.t, sensor, model, Path(tmp) / "forces.png", title=run.source[-60:])
        image = iio.imread(info.path)[:, :, :3]
    return image, info


def _unit_cylinder(sides: int) -> tuple[np.ndarray, np.ndarray]:
    """A closed cylinder of radius 1 and length 1 along z, centred at the origin: vertices (2 sides + 2, 3),
    faces (4 sides, 3) wound outward."""
    a = 2 * np.pi * np.arange(sides) / sides
    ring = np.column_stack([np.cos(a), np.sin(a)])
    v = np.vstack([np.column_stack([ring, np.full(sides, -0.5)]), np.column_stack([ring, np.full(sides, 0.5)]),
                   [[0.0, 0.0, -0.5], [0.0, 0.0, 0.5]]]).astype(np.float32)
    i = np.arange(sides)
    j = (i + 1) % sides
    bottom, top = 2 * sides, 2 * sides + 1
    faces = np.vstack([np.column_stack([i, j, sides + j]), np.column_stack([i, sides + j, sides + i]),
                       np.column_stack([np.full(sides, bottom), j, i]),
                       np.column_stack([np.full(sides, top), sides + i, sides + j])]).astype(np.uint32)
    return v, faces


def tube_transforms(x: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per segment of a cable at nodes x (n, 3) [m]: the unit cylinder's position (midpoint) [m], rotation
    (w x y z, its z axis onto the segment) and scale (radius, radius, length) [m], (n-1, 3/4/3)."""
    d = np.diff(x, axis=0)
    length = np.linalg.norm(d, axis=1)
    u = d / np.maximum(length, 1e-12)[:, None]
    # the shortest rotation from +z to u: q = (1 + u_z, -u_y, u_x, 0) normalised; u = -z turns about x
    q = np.column_stack([1.0 + u[:, 2], -u[:, 1], u[:, 0], np.zeros(len(u))])
    flip = q[:, 0] < 1e-9
    q[flip] = (0.0, 1.0, 0.0, 0.0)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    scale = np.column_stack([np.full(len(u), radius), np.full(len(u), radius), length])
    return (0.5 * (x[:-1] + x[1:])).astype(np.float32), q.astype(np.float32), scale.astype(np.float32)


class CableDrawing:
    """The cable on a viser scene: a tube of its diameter (one cylinder per segment), a 5 px centre line that
    keeps it visible from afar (a 4 mm tube is a pixel wide in a 1.5 m view) and its masses as discs;
    :meth:`show` moves all three to nodes ``x`` (n, 3) [m]."""

    def __init__(self, scene, x: np.ndarray, radius: float):
        self.radius = radius
        self.line = scene.add_line_segments("/cable/line", points=ViewerScene._segments(x), colors=CABLE_RGB,
                                            thickness=5.0, thickness_units="screen")
        pos, wxyz, scale = tube_transforms(x, radius)
        vertices, faces = _unit_cylinder(TUBE_SIDES)
        self.tube = scene.add_batched_meshes_simple("/cable/tube", vertices, faces, batched_wxyzs=wxyz,
                                                    batched_positions=pos, batched_scales=scale,
                                                    batched_colors=CABLE_RGB, lod="off")
        self.nodes = scene.add_point_cloud("/cable/nodes", points=np.asarray(x, np.float32),
                                           colors=np.tile(np.array(NODE_RGB, np.uint8), (len(x), 1)),
                                           point_size=max(2 * radius, 0.004), point_shape="circle")

    def show(self, x: np.ndarray) -> None:
        self.line.points = ViewerScene._segments(x)
        self.tube.batched_positions, self.tube.batched_wxyzs, self.tube.batched_scales = tube_transforms(x, self.radius)
        self.nodes.points = np.asarray(x, np.float32)


class ViewerScene:
    """The run's scene on a viser server: static parts once, :meth:`show` for a row."""

    def __init__(self, server, run: Run, max_frames: int = MAX_FRAMES):
        self.server, self.run = server, run
        self.rows = frame_rows(run, max_frames)
        scene = server.scene
        scene.set_up_direction("+z")
        x_all = run.cable_x[self.rows]
        lo, hi = x_all.reshape(-1, 3).min(axis=0), x_all.reshape(-1, 3).max(axis=0)
        if run.ee_pos is not None:
            lo = np.minimum(lo, run.ee_pos.reshape(-1, 3).min(axis=0))
            hi = np.maximum(hi, run.ee_pos.reshape(-1, 3).max(axis=0))
        centre = (lo + hi) / 2
        span = float(max(np.max(hi - lo), 0.2))
        if run.robot is not None:
            span = max(span, 1.4)  # both arms, bases 0.6 m from the middle
        self.centre, self.span = centre, span
        self.urdf_obstacles = 0
        if run.ground_height is not None:
            g = run.ground_height
            scene.add_box("/world/ground", dimensions=(2.5 * span, 2.5 * span, 0.002),
                          position=(centre[0], centre[1], g - 0.001), color=(215, 215, 220))
        if run.table is not None:
            he, c = run.table
            scene.add_box("/world/table", dimensions=tuple(2 * np.asarray(he)), position=tuple(c), color=(170, 140, 100))
        for k, ob in enumerate(run.obstacles):
            pos, wxyz = tuple(ob.get("position", (0, 0, 0))), _wxyz(ob.get("orientation", (0, 0, 0, 1)))
            rgb = tuple(int(255 * c) for c in ob.get("color", (0.6, 0.6, 0.65, 1.0))[:3])
            if ob.get("type") == "box":
                scene.add_box(f"/world/obstacles/{k}", dimensions=tuple(2 * np.asarray(ob["half_extents"], float)),
                              position=pos, wxyz=wxyz, color=rgb)
            elif ob.get("type") == "cylinder":
                scene.add_cylinder(f"/world/obstacles/{k}", radius=float(ob["radius"]), height=float(ob["height"]),
                                   position=pos, wxyz=wxyz, color=rgb)
        for k, (meshes, poses) in enumerate(urdf_geometry(run.obstacles)):
            for s, ((_link, mesh, rgb, lpos, lwxyz), pose) in enumerate(zip(meshes, poses)):
                frame = f"/world/urdf/{k}/visual{s}"
                scene.add_frame(frame, show_axes=False, position=tuple(pose[:3]), wxyz=tuple(pose[3:]))
                scene.add_mesh_simple(f"{frame}/mesh", vertices=np.asarray(mesh.vertices, np.float32),
                                      faces=np.asarray(mesh.faces, np.uint32), color=rgb, position=lpos, wxyz=lwxyz)
            self.urdf_obstacles = k + 1
        self.cable = CableDrawing(scene, run.cable_x[self.rows[0]], run.radius)
        # arms
        self.arm_frames: list[list] = []
        self.arms = arm_geometry(run.robot, run.joint_q[self.rows], run.ee_pos[self.rows],
                                 run.ee_quat[self.rows]) if run.robot is not None else []
        for a, (side, geom) in enumerate(zip(("left", "right"), self.arms)):
            frames = []
            for c, link in enumerate(geom.link_ids):
                frames.append(scene.add_frame(f"/arms/{side}/link{link}", show_axes=False,
                                              position=tuple(geom.poses[0, c, :3]), wxyz=tuple(geom.poses[0, c, 3:])))
            col = {link: c for c, link in enumerate(geom.link_ids)}
            for s, (link, mesh, rgb, lpos, lwxyz) in enumerate(geom.meshes):
                scene.add_mesh_simple(f"/arms/{side}/link{link}/visual{s}", vertices=np.asarray(mesh.vertices, np.float32),
                                      faces=np.asarray(mesh.faces, np.uint32), color=rgb, position=lpos, wxyz=lwxyz)
            self.arm_frames.append(frames)
            del col
        # wrenches: arrows at the grasp points, scaled so the largest is a fifth of the scene
        self.wrench = None
        if run.wrench_world is not None and run.ee_pos is not None:
            fmax = float(np.max(np.linalg.norm(run.wrench_world[:, :, :3], axis=2))) or 1.0
            self.force_scale = 0.2 * span / fmax  # [m/N]
            self.wrench = scene.add_arrows("/wrench", points=self._wrench_points(self.rows[0]),
                                           colors=np.array(FORCE_RGB, np.uint8), shaft_radius=0.004,
                                           head_radius=0.01, head_length=0.02)
        # contacts
        self.contact_points, self.contact_forces = contacts(run)
        fmax = max((float(np.max(np.linalg.norm(f, axis=1))) for f in self.contact_forces if len(f)), default=0.0)
        self.contact_scale = 0.1 * span / fmax if fmax > 0 else 0.0
        self.contacts = scene.add_point_cloud("/contacts/points", points=np.zeros((1, 3), np.float32),
                                              colors=CONTACT_RGB, point_size=max(3 * run.radius, 0.006),
                                              point_shape="circle", visible=False)
        self.contact_arrows = scene.add_arrows("/contacts/forces", points=np.zeros((1, 2, 3), np.float32),
                                               colors=CONTACT_RGB, shaft_radius=0.002, head_radius=0.005,
                                               head_length=0.01, visible=False)
        # the time plot, standing behind the scene (+y), facing -y, with its cursor
        self.plot = _plot_image(run)
        self.cursor = None
        if self.plot is not None:
            image, info = self.plot
            h_px, w_px = image.shape[:2]
            width = 1.2 * span
            height = width * h_px / w_px
            pos = (centre[0], centre[1] + 0.8 * span, max(centre[2], 0.0) + 0.5 * height + 0.05)
            rot = (0.7071068, -0.7071068, 0.0, 0.0)  # image x along world x, its rows (local y) downward
            plot = scene.add_frame("/plot", show_axes=False, position=pos, wxyz=rot)
            scene.add_image("/plot/image", image, render_width=width, render_height=height,
                            cast_shadow=False, receive_shadow=False)
            self._px = (width / w_px, height / h_px, w_px, h_px)
            self.cursor = scene.add_line_segments("/plot/cursor", points=self._cursor(self.rows[0]),
                                                  colors=(0, 0, 0), thickness=2.0, thickness_units="screen")
            del plot
        cam = centre + np.array([0.0, -1.3 * span, 0.55 * span])
        server.initial_camera.position = tuple(cam)
        server.initial_camera.look_at = tuple(centre + np.array([0.0, 0.1 * span, 0.0]))

    @staticmethod
    def _segments(x: np.ndarray) -> np.ndarray:
        return np.stack([x[:-1], x[1:]], axis=1).astype(np.float32)

    def _wrench_points(self, r: int) -> np.ndarray:
        p = self.run.ee_pos[r]
        return np.stack([p, p + self.force_scale * self.run.wrench_world[r, :, :3]], axis=1).astype(np.float32)

    def _cursor(self, r: int) -> np.ndarray:
        _, info = self.plot
        sx, sy, w_px, h_px = self._px
        t0, t1 = info.t_range
        segs = []
        for x0, x1, y0, y1 in info.axes_px:
            u = x0 + (x1 - x0) * (self.run.t[r] - t0) / max(t1 - t0, 1e-12)
            px = (u - w_px / 2) * sx
            segs.append([[px, (y0 - h_px / 2) * sy, -0.002], [px, (y1 - h_px / 2) * sy, -0.002]])  # in front
        return np.asarray(segs, dtype=np.float32)

    def show(self, r: int) -> None:
        """Show row ``r`` of the run (an index into its rows)."""
        run = self.run
        self.cable.show(run.cable_x[r])
        i = int(np.searchsorted(self.rows, r))
        for geom, frames in zip(self.arms, self.arm_frames):
            if i < len(self.rows) and self.rows[i] == r:
                for c, fr in enumerate(frames):
                    fr.position = tuple(geom.poses[i, c, :3])
                    fr.wxyz = tuple(geom.poses[i, c, 3:])
        if self.wrench is not None:
            self.wrench.points = self._wrench_points(r)
        pts, fs = self.contact_points[r], self.contact_forces[r]
        self.contacts.visible = len(pts) > 0
        if len(pts):
            self.contacts.points = pts.astype(np.float32)
        shown = np.linalg.norm(fs, axis=1) > 0 if len(fs) else np.zeros(0, bool)
        self.contact_arrows.visible = bool(shown.any()) and self.contact_scale > 0
        if self.contact_arrows.visible:
            p = pts[shown]
            self.contact_arrows.points = np.stack([p, p + self.contact_scale * fs[shown]], axis=1).astype(np.float32)
        if self.cursor is not None:
            self.cursor.points = self._cursor(r)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _server(port: int | None = None):
    viser = require_viser()
    import logging

    logging.getLogger("websockets").setLevel(logging.ERROR)
    with _quiet_stdout():
        return viser.ViserServer(host="127.0.0.1", port=port or _free_port(), verbose=False)


class _quiet_stdout:
    """viser prints a banner and 'Server stopped' on stdout: kept off the command's output."""

    def __enter__(self):
        import contextlib

        self._ctx = contextlib.redirect_stdout(io.StringIO())
        return self._ctx.__enter__()

    def __exit__(self, *exc):
        return self._ctx.__exit__(*exc)


@dataclasses.dataclass(frozen=True)
class ViewerInfo:
    """A written viewer: its file, the rows it holds and what it shows."""

    path: Path
    frames: int
    duration: float
    entities: tuple[str, ...]
    bytes: int


def write_viewer(run: Run, out: str | Path, max_frames: int = MAX_FRAMES, dark_mode: bool = False) -> ViewerInfo:
    """Write ``run`` as one self-contained HTML page (viewer + recording, opens from disk) to ``out``."""
    out = Path(out)
    server = _server()
    try:
        serializer = server.get_scene_serializer()
        view = ViewerScene(server, run, max_frames)
        rows = view.rows
        for i, r in enumerate(rows):
            view.show(int(r))
            if i + 1 < len(rows):
                serializer.insert_sleep(float(run.t[rows[i + 1]] - run.t[r]))
        serializer.insert_sleep(0.5)  # the last row stays on screen before the loop restarts
        html = serializer.as_html(dark_mode=dark_mode)
    finally:
        with _quiet_stdout():
            server.stop()
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(html, encoding="utf-8")
    return ViewerInfo(out, len(rows), float(run.t[rows[-1]] - run.t[rows[0]]), entities(view), out.stat().st_size)


def entities(view: ViewerScene) -> tuple[str, ...]:
    """Names of what the scene shows (for the command's summary and the tests)."""
    names = ["cable", "nodes"]
    if view.arms:
        names.append("arms")
    if view.run.ground_height is not None:
        names.append("ground")
    if view.run.table is not None:
        names.append("table")
    if view.run.obstacles:
        names.append(f"obstacles({len(view.run.obstacles)})")
    if view.urdf_obstacles:
        names.append(f"urdf meshes({view.urdf_obstacles})")
    if view.wrench is not None:
        names.append("wrenches")
    if view.plot is not None:
        names.append("time plot")
    names.append(f"contacts({sum(len(p) for p in view.contact_points)})")
    return tuple(names)


def serve(run: Run, port: int | None = None, max_frames: int = MAX_FRAMES, seconds: float | None = None,
          ready=None) -> None:
    """Show ``run`` live at http://127.0.0.1:PORT (a free port if None) with a frame slider and play
    button, until Ctrl-C (or ``seconds``). ``ready(url)`` is called once the page is up."""
    server = _server(port)
    try:
        view = ViewerScene(server, run, max_frames)
        rows = view.rows
        gui = server.gui
        slider = gui.add_slider("row", min=0, max=len(rows) - 1, step=1, initial_value=0)
        play = gui.add_checkbox("play", initial_value=True)
        readout = gui.add_markdown("")

        def update(i: int) -> None:
            r = int(rows[i])
            view.show(r)
            text = f"t = {run.t[r]:.4f} s"
            if run.wrench_world is not None:
                for a, side in enumerate(("left", "right")):
                    text += f"  \n{side} F = " + " ".join(f"{v:+.4f}" for v in run.wrench_world[r, a, :3]) + " N"
            readout.content = text

        slider.on_update(lambda _: update(int(slider.value)))
        update(0)
        url = f"http://127.0.0.1:{server.get_port()}"
        if ready is not None:
            ready(url)
        t_end = None if seconds is None else time.monotonic() + seconds
        while t_end is None or time.monotonic() < t_end:
            time.sleep(1 / 30)
            if play.value and len(rows) > 1:
                slider.value = (int(slider.value) + 1) % len(rows)
    finally:
        with _quiet_stdout():
            server.stop()


# ----- a live view of a running world (the environments' render_mode="human") ----------------------
class LiveView:
    """A PyBullet world drawn live in the browser at http://127.0.0.1:PORT: the cable (tube, centre line and
    masses) and every other body's visual shapes (the arms, obstacles, pegs), posed from Bullet's own link
    frames at each :meth:`update`; with ``wrench_points`` (2, 2, 3) [m] the wrist-force arrows. The page keeps
    its port across :meth:`attach` (a new episode's world): a browser left open shows the next episode.

    client: the PyBullet client; skip: body ids not drawn (the cable's spheres, the ground plane); radius: the
    cable's [m]. The URL is printed once on stderr (``announce``)."""

    def __init__(self, port: int | None = None, announce: bool = True):
        self.server = _server(port)
        self.url = f"http://127.0.0.1:{self.server.get_port()}"
        if announce:
            import sys

            print(f"bullet_dlo viewer: {self.url}", file=sys.stderr, flush=True)
        self.client: int | None = None
        self.frames: dict[tuple[int, int], Any] = {}

    def attach(self, client: int, skip: Sequence[int], radius: float, n_masses: int) -> None:
        """Draw a (new) world: every body of ``client`` not in ``skip``, and a cable of ``n_masses`` masses."""
        import pybullet as pb

        scene = self.server.scene
        scene.reset()
        scene.set_up_direction("+z")
        scene.add_box("/world/ground", dimensions=(4.0, 4.0, 0.002), position=(0.0, 0.0, -0.001), color=(215, 215, 220))
        self.client, self.frames = client, {}
        skipped = set(int(b) for b in skip)
        for b in (pb.getBodyUniqueId(i, physicsClientId=client) for i in range(pb.getNumBodies(physicsClientId=client))):
            if b in skipped:
                continue
            for s, (link, mesh, rgb, lpos, lwxyz) in enumerate(visual_meshes(client, b, ARM_RGB)):
                key = (b, link)
                if key not in self.frames:
                    self.frames[key] = scene.add_frame(f"/bodies/{b}/link{link}", show_axes=False)
                scene.add_mesh_simple(f"/bodies/{b}/link{link}/visual{s}", vertices=np.asarray(mesh.vertices, np.float32),
                                      faces=np.asarray(mesh.faces, np.uint32), color=rgb, position=lpos, wxyz=lwxyz)
        x = np.zeros((n_masses, 3))
        x[:, 0] = np.arange(n_masses) * 1e-3  # a placeholder until the first update
        self.cable = CableDrawing(scene, x, radius)
        self.arrows = None
        self.server.initial_camera.position = (0.0, -1.6, 1.0)
        self.server.initial_camera.look_at = (0.0, 0.0, 0.3)

    def update(self, cable_x: np.ndarray, wrench_points: np.ndarray | None = None) -> None:
        """Show the world now: the cable at ``cable_x`` (n, 3) [m], every drawn link at Bullet's pose."""
        self.cable.show(np.asarray(cable_x, dtype=float))
        for (body, link), frame in self.frames.items():
            p, o = _link_pose(self.client, body, link)
            frame.position, frame.wxyz = tuple(p), _wxyz(o)
        if wrench_points is not None:
            pts = np.asarray(wrench_points, np.float32)
            if self.arrows is None:
                self.arrows = self.server.scene.add_arrows("/wrench", points=pts, colors=np.array(FORCE_RGB, np.uint8),
                                                           shaft_radius=0.004, head_radius=0.01, head_length=0.02)
            else:
                self.arrows.points = pts

    def close(self) -> None:
        with _quiet_stdout():
            self.server.stop()
