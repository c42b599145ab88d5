"""Cameras and frames in PyBullet's DIRECT mode (no display).

* :class:`Camera` is fixed (look-at) or attached to a link (e.g. a wrist camera); it also
  carries the light, so shadows are drawn from the first frame on with either renderer.
* :func:`render_frame` returns RGB, depth in metres and segmentation (body, link and, for
  cable spheres and tube segments, the cable mass) from one ``getCameraImage`` call.
* :func:`framing_camera` places a camera so that given points fill the frame;
  :func:`default_camera` looks at points from the front-right, above.

The renderer itself (TinyRenderer or the EGL plugin) is part of the world's set-up:
:class:`bullet_dlo.bullet.renderer.Renderer`, re-exported here.
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import pybullet as pb

from bullet_dlo.bullet.world import sync_bullet_spheres
from bullet_dlo.bullet.renderer import RENDERERS, Renderer, RenderError  # noqa: F401  (re-exported)
from bullet_dlo.core.validate import ParameterError, check_int, check_positive, check_vector3
from bullet_dlo.robots.transforms import rotation

LIGHT_DISTANCE = 10.0  # [m] the EGL renderer puts its shadow-casting light at lightDirection: beyond the scene
_SHADOWS_READY: weakref.WeakSet = weakref.WeakSet()  # EGL renderers whose shadow map exists


@dataclass(frozen=True)
class Camera:
    """A pinhole camera (SI units, degrees for angles).

    Fixed: ``eye`` and ``target`` [m] with ``up``. Attached: ``link`` = (body id, link index)
    with ``eye``/``target`` in that link's frame (e.g. a wrist camera). width, height [px];
    fov: vertical field of view [deg]; near, far: clipping planes [m]; light_direction: towards
    the light (world frame, any length); shadows: cast shadows with TinyRenderer (the EGL
    renderer always casts them once it is given a light, which :func:`render_frame` always does).
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
    light_direction: tuple[float, float, float] = (0.4, -0.5, 1.0)
    shadows: bool = True

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
        if np.linalg.norm(check_vector3("camera light_direction", self.light_direction)) < 1e-9:
            raise ParameterError("camera light_direction must not be zero")

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
        rot = rotation(quat)
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
    """One rendered view: rgb (H, W, 3) uint8; depth [m] (H, W) along the optical axis; body, link
    (H, W) int (-1: background); cable_mass (H, W) int (-1: not a cable mass)."""

    rgb: np.ndarray
    depth: np.ndarray
    body: np.ndarray
    link: np.ndarray
    cable_mass: np.ndarray
    renderer: str


def render_frame(client: int, camera: Camera, renderer: Renderer, mass_of_body: dict[int, int] | None = None) -> Frame:
    """Render ``camera`` and return RGB, metric depth and segmentation from one call.

    mass_of_body: body id -> cable mass index (spheres and tube segments), for ``cable_mass``.
    """
    sync_bullet_spheres(client)  # parked proxy spheres to where the cables are (bullet_dlo.bullet.cable)
    view, proj = camera.matrices(client)
    w, h = camera.width, camera.height
    light = np.asarray(camera.light_direction, float)
    light *= LIGHT_DISTANCE / np.linalg.norm(light)
    if renderer.name == "egl" and renderer not in _SHADOWS_READY:
        # the EGL renderer draws shadows from its third image on: two 16x16 ones first, so frame 0 has them
        for _ in range(2):
            pb.getCameraImage(16, 16, view.T.reshape(-1).tolist(), proj.T.reshape(-1).tolist(),
                              lightDirection=light.tolist(), renderer=renderer.flag, physicsClientId=client)
        _SHADOWS_READY.add(renderer)
    img = pb.getCameraImage(w, h, view.T.reshape(-1).tolist(), proj.T.reshape(-1).tolist(),
                            shadow=int(camera.shadows), lightDirection=light.tolist(),
                            renderer=renderer.flag, flags=pb.ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX,
                            physicsClientId=client)
    rgb = np.reshape(np.asarray(img[2], dtype=np.uint8), (h, w, 4))[:, :, :3].copy()
    renderer.check(rgb)
    zbuf = np.reshape(np.asarray(img[3], dtype=float), (h, w))
    near, far = camera.near, camera.far
    depth = far * near / (far - (far - near) * zbuf)  # OpenGL depth buffer -> distance along the axis
    seg = np.reshape(np.asarray(img[4], dtype=np.int64), (h, w))
    body = np.where(seg >= 0, seg & ((1 << 24) - 1), -1)
    link = np.where(seg >= 0, (seg >> 24) - 1, -2)
    cable_mass = np.full((h, w), -1, dtype=np.int64)
    if mass_of_body:
        ids = np.array(sorted(mass_of_body))
        masses = np.array([mass_of_body[b] for b in ids])
        idx = np.clip(np.searchsorted(ids, body), 0, len(ids) - 1)
        hit = ids[idx] == body
        cable_mass[hit] = masses[idx][hit]
    return Frame(rgb, depth, body, link, cable_mass, renderer.name)


capture = render_frame  # the name before 0.2; data/ and scripts move to render_frame


def framing_camera(points: Sequence[Sequence[float]], view_direction: Sequence[float] = (0.35, -1.0, 0.45),
                   width: int = 640, height: int = 480, fov: float = 40.0, margin: float = 1.1) -> Camera:
    """A camera looking along ``-view_direction`` at the box around ``points`` [m], (k, 3), so close that
    every point is in the frame with ``margin`` (1.1: 10 % of the half-width to spare).

    For each point at offset q from the box centre, with right/up/towards-eye axes r, u, f, a
    distance d keeps it in view when |r.q| <= tan(hfov/2) (d - f.q) / margin (and the same with u
    and the vertical fov); the camera takes the smallest d that satisfies every point.
    """
    pts = np.asarray(points, float).reshape(-1, 3)
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    f = np.asarray(view_direction, float) / np.linalg.norm(view_direction)
    r = np.cross([0.0, 0.0, 1.0], f)
    r /= np.linalg.norm(r)
    u = np.cross(f, r)
    tan_v = math.tan(math.radians(fov) / 2.0)
    tan_h = tan_v * width / height
    q = pts - centre
    need = np.maximum(np.abs(q @ r) * margin / tan_h, np.abs(q @ u) * margin / tan_v) + q @ f
    distance = max(float(need.max()), 0.1)
    return Camera(eye=tuple(centre + distance * f), target=tuple(centre), width=width, height=height, fov=fov,
                  far=max(5.0, 3.0 * distance))


def default_camera(points: Sequence[Sequence[float]], width: int = 640, height: int = 480) -> Camera:
    """A camera looking at the centre of ``points`` [m] from the front-right, above."""
    pts = np.asarray(points, float)
    centre = pts.mean(axis=0)
    span = max(float(np.ptp(pts, axis=0).max()), 0.3)
    eye = centre + np.array([0.55, -1.0, 0.6]) * span * 1.1
    return Camera(eye=tuple(eye), target=tuple(centre), width=width, height=height)
