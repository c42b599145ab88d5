"""Headless rendering in PyBullet's DIRECT mode: renderers, cameras, frames, the cable's look.

* :class:`Renderer` picks TinyRenderer (software, works everywhere) or the EGL plugin
  (Mesa llvmpipe on CPU machines, the GPU where there is one): ``"auto" | "tiny" | "egl"``,
  and says which it uses and why. A frame without content raises :class:`RenderError`
  (a loaded-then-unloaded EGL plugin returns blank images without any error).
* :class:`Camera` is fixed (look-at) or attached to a link (e.g. a wrist camera);
  :func:`capture` returns RGB, depth in metres and segmentation (body, link and, for cable
  spheres and tube segments, the cable mass) from one ``getCameraImage`` call.
* :class:`CableTube` draws the cable as a continuous tube: a cylinder per segment between
  the spheres, segments in alternating shades, held ends highlighted.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import pybullet as pb

from bullet_dlo.bullet.renderer import RENDERERS, Renderer, RenderError  # noqa: F401  (re-exported)
from bullet_dlo.core.validate import ParameterError, check_int, check_positive, check_vector3


@dataclass(frozen=True)
class Camera:
    """A pinhole camera (SI units, degrees for angles).

    Fixed: ``eye`` and ``target`` [m] with ``up``. Attached: ``link`` = (body id, link index)
    with ``eye``/``target`` in that link's frame (e.g. a wrist camera). width, height [px];
    fov: vertical field of view [deg]; near, far: clipping planes [m].
    """

    eye: tuple[float, float, float] = (0.7, -0.9, 0.75)
    target: tuple[float, float, float] = (0.0, 0.0, 0.3)
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    width: int = 640
    height: int = 480
    fov: float = 50.0
    near: float = 0.02
    far: float = 5.0
    link: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        check_int("camera width", self.width, 16, 8192)
        check_int("camera height", self.height, 16, 8192)
        if not 1.0 <= float(self.fov) <= 170.0:
            raise ParameterError(f"camera fov must be in [1, 170] degrees, got {self.fov}")
        near, far = check_positive("camera near", self.near), check_positive("camera far", self.far)
        if far <= near:
            raise ParameterError(f"camera far ({far}) must be greater than near ({near})")
        eye, target = check_vector3("camera eye", self.eye), check_vector3("camera target", self.target)
        if np.linalg.norm(eye - target) < 1e-9:
            raise ParameterError("camera eye and target must differ")

    def world_eye_target_up(self, client: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Eye, target and up in world coordinates (follows the link if attached)."""
        eye, target, up = (np.asarray(v, float) for v in (self.eye, self.target, self.up))
        if self.link is None:
            return eye, target, up
        body, link = self.link
        if link < 0:
            pos, quat = pb.getBasePositionAndOrientation(body, physicsClientId=client)
        else:
            st = pb.getLinkState(body, link, computeForwardKinematics=True, physicsClientId=client)
            pos, quat = st[4], st[5]
        rot = np.array(pb.getMatrixFromQuaternion(quat)).reshape(3, 3)
        return np.asarray(pos) + rot @ eye, np.asarray(pos) + rot @ target, rot @ up

    def matrices(self, client: int) -> tuple[np.ndarray, np.ndarray]:
        """4x4 view and projection matrices (row-major numpy; PyBullet's are column-major)."""
        eye, target, up = self.world_eye_target_up(client)
        view = pb.computeViewMatrix(eye.tolist(), target.tolist(), up.tolist())
        proj = pb.computeProjectionMatrixFOV(self.fov, self.width / self.height, self.near, self.far)
        return np.array(view).reshape(4, 4).T, np.array(proj).reshape(4, 4).T

    def project(self, points: np.ndarray, client: int) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates (u right, v down) of world points [m], (k, 2), and their distance [m] to the eye."""
        view, proj = self.matrices(client)
        pts = np.c_[np.asarray(points, float), np.ones(len(points))]
        clip = (proj @ view @ pts.T).T
        ndc = clip[:, :3] / clip[:, 3:4]
        u = (ndc[:, 0] + 1.0) * 0.5 * self.width
        v = (1.0 - ndc[:, 1]) * 0.5 * self.height
        eye = self.world_eye_target_up(client)[0]
        return np.c_[u, v], np.linalg.norm(np.asarray(points) - eye, axis=1)


@dataclass
class Frame:
    """One capture: rgb (H, W, 3) uint8; depth [m] (H, W) along the optical axis; body, link
    (H, W) int (-1: background); cable_mass (H, W) int (-1: not a cable mass)."""

    rgb: np.ndarray
    depth: np.ndarray
    body: np.ndarray
    link: np.ndarray
    cable_mass: np.ndarray
    renderer: str


def capture(client: int, camera: Camera, renderer: Renderer, mass_of_body: dict[int, int] | None = None) -> Frame:
    """Render ``camera`` and return RGB, metric depth and segmentation from one call.

    mass_of_body: body id -> cable mass index (spheres and tube segments), for ``cable_mass``.
    """
    view, proj = camera.matrices(client)
    w, h = camera.width, camera.height
    img = pb.getCameraImage(w, h, view.T.reshape(-1).tolist(), proj.T.reshape(-1).tolist(), renderer=renderer.flag,
                            flags=pb.ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX, physicsClientId=client)
    rgb = np.reshape(np.asarray(img[2], dtype=np.uint8), (h, w, 4))[:, :, :3].copy()
    renderer.check(rgb)
    zbuf = np.reshape(np.asarray(img[3], dtype=float), (h, w))
    near, far = camera.near, camera.far
    depth = far * near / (far - (far - near) * zbuf)
    seg = np.reshape(np.asarray(img[4], dtype=np.int64), (h, w))
    body = np.where(seg >= 0, seg & ((1 << 24) - 1), -1)
    link = np.where(seg >= 0, (seg >> 24) - 1, -2)
    cable_mass = np.full((h, w), -1, dtype=np.int64)
    if mass_of_body:
        lut_ids = np.array(list(mass_of_body.keys()))
        lut_mass = np.array(list(mass_of_body.values()))
        order = np.argsort(lut_ids)
        idx = np.searchsorted(lut_ids[order], body)
        idx = np.clip(idx, 0, len(order) - 1)
        hit = lut_ids[order][idx] == body
        cable_mass[hit] = lut_mass[order][idx][hit]
    return Frame(rgb, depth, body, link, cable_mass, renderer.name)


@dataclass
class CableTube:
    """Visual-only cylinders between a cable's spheres (the spheres are the joints of the tube).

    Segments alternate between two shades so that the discretisation shows; the spheres of
    held ends are drawn in ``held_color``.
    """

    cable: object  # BulletCable
    colors: tuple = ((0.95, 0.45, 0.1, 1.0), (0.8, 0.3, 0.05, 1.0))
    held_color: tuple = (0.1, 0.75, 0.3, 1.0)
    bodies: list[int] = field(default_factory=list)

    def __post_init__(self) -> None:
        c = self.cable
        cid = c.world.client
        r = c.radius
        lengths = c.model.arrays.rest_length
        shapes = [pb.createVisualShape(pb.GEOM_CYLINDER, radius=r, length=float(lengths[0]), rgbaColor=list(col),
                                       physicsClientId=cid) for col in self.colors]
        for i in range(c.model.n - 1):
            self.bodies.append(pb.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=-1,
                                                  baseVisualShapeIndex=shapes[i % 2], basePosition=[0, 0, -10],
                                                  physicsClientId=cid))
        for b in c.body_ids:
            pb.changeVisualShape(b, -1, rgbaColor=list(self.colors[0]), physicsClientId=cid)
        self._held = None
        self.update()

    def mass_of_body(self) -> dict[int, int]:
        """Body id -> cable mass index (a segment counts as its first mass)."""
        out = {b: i for i, b in enumerate(self.cable.body_ids)}
        out.update({b: i for i, b in enumerate(self.bodies)})
        return out

    def update(self) -> None:
        """Move the segments onto the current sphere positions (call before rendering)."""
        c = self.cable
        cid = c.world.client
        x = c.x
        for i, b in enumerate(self.bodies):
            d = x[i + 1] - x[i]
            mid = 0.5 * (x[i + 1] + x[i])
            pb.resetBasePositionAndOrientation(b, mid.tolist(), _quat_z_to(d), physicsClientId=cid)
        held = tuple(bool(h) for h in (c.arrays.held[0], c.arrays.held[-1]))
        if held != self._held:
            for flag, b in zip(held, (c.body_ids[0], c.body_ids[-1])):
                col = self.held_color if flag else self.colors[0]
                pb.changeVisualShape(b, -1, rgbaColor=list(col), physicsClientId=cid)
            self._held = held


def _quat_z_to(d: np.ndarray) -> list[float]:
    """Quaternion rotating +z onto direction d."""
    n = np.linalg.norm(d)
    if n < 1e-12:
        return [0.0, 0.0, 0.0, 1.0]
    d = d / n
    axis = np.cross([0.0, 0.0, 1.0], d)
    s = np.linalg.norm(axis)
    c = float(d[2])
    if s < 1e-12:
        return [0.0, 0.0, 0.0, 1.0] if c > 0 else [1.0, 0.0, 0.0, 0.0]
    angle = math.atan2(s, c)
    axis = axis / s * math.sin(angle / 2)
    return [float(axis[0]), float(axis[1]), float(axis[2]), math.cos(angle / 2)]


def default_camera(points: Sequence[Sequence[float]], width: int = 640, height: int = 480) -> Camera:
    """A camera looking at the centre of ``points`` [m] from the front-right, above."""
    pts = np.asarray(points, float)
    centre = pts.mean(axis=0)
    span = max(float(np.ptp(pts, axis=0).max()), 0.3)
    eye = centre + np.array([0.55, -1.0, 0.6]) * span * 1.1
    return Camera(eye=tuple(eye), target=tuple(centre), width=width, height=height)
