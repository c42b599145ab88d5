"""The cable's look: a continuous tube of cylinders between its spheres."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pybullet as pb

from bullet_dlo.robots.transforms import quat_from_axes


@dataclass
class CableTube:
    """Visual-only cylinders between a cable's spheres (the spheres are the joints of the tube).

    cable: a :class:`bullet_dlo.bullet.cable.BulletCable`; the tube has its collision radius
    [m]. Segments alternate between two ``colors`` (RGBA) so that the discretisation shows;
    the spheres of held ends are drawn in ``held_color``. Call :meth:`update` before each frame.
    """

    cable: object
    colors: tuple = ((0.95, 0.45, 0.1, 1.0), (0.8, 0.3, 0.05, 1.0))
    held_color: tuple = (0.1, 0.75, 0.3, 1.0)
    bodies: list[int] = field(default_factory=list)

    def __post_init__(self) -> None:
        c = self.cable
        cid = c.world.client
        length = float(c.model.arrays.rest_length[0])
        shapes = [pb.createVisualShape(pb.GEOM_CYLINDER, radius=c.radius, length=length, rgbaColor=list(col),
                                       physicsClientId=cid) for col in self.colors]
        for i in range(c.model.n - 1):
            self.bodies.append(pb.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=-1,
                                                  baseVisualShapeIndex=shapes[i % 2], basePosition=[0, 0, -10],
                                                  physicsClientId=cid))
        for b in c.body_ids:
            pb.changeVisualShape(b, -1, rgbaColor=list(self.colors[0]), physicsClientId=cid)
        self._held: tuple[bool, bool] | None = None
        self.update()

    def mass_of_body(self) -> dict[int, int]:
        """Body id -> cable mass index (a segment counts as its first mass)."""
        out = {b: i for i, b in enumerate(self.cable.body_ids)}
        out.update({b: i for i, b in enumerate(self.bodies)})
        return out

    def update(self) -> None:
        """Move the segments onto the current sphere positions and colour the held ends."""
        c = self.cable
        cid = c.world.client
        x = c.x
        for i, b in enumerate(self.bodies):
            mid = 0.5 * (x[i + 1] + x[i])
            pb.resetBasePositionAndOrientation(b, mid.tolist(), segment_quat(x[i + 1] - x[i]), physicsClientId=cid)
        held = (bool(c.arrays.held[0]), bool(c.arrays.held[-1]))
        if held != self._held:
            for flag, b in zip(held, (c.body_ids[0], c.body_ids[-1])):
                col = self.held_color if flag else self.colors[0]
                pb.changeVisualShape(b, -1, rgbaColor=list(col), physicsClientId=cid)
            self._held = held


def segment_quat(d: np.ndarray) -> list[float]:
    """Quaternion [x, y, z, w] turning a cylinder's axis (+z) onto the segment direction ``d`` (3,)."""
    if np.linalg.norm(d) < 1e-12:
        return [0.0, 0.0, 0.0, 1.0]
    # any x axis not parallel to d: the cylinder is symmetric about its own axis
    x_axis = (1.0, 0.0, 0.0) if abs(d[0]) < 0.9 * np.linalg.norm(d) else (0.0, 1.0, 0.0)
    return [float(v) for v in quat_from_axes(x_axis, d)]
