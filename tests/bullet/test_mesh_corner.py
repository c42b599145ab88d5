"""A cable in a concave corner of a triangle mesh meets every face of it (issue 23, the mesh-clip demo at 60 Hz).

Bullet answers a query against a triangle mesh triangle by triangle; the contact set kept only the closest
answer per node (segment), so a node in a concave corner met one face per step, the faces taking turns. A
cable laid along a V-groove (two faces at +-``half angle`` from the vertical, a static concave mesh) must
rest in it: by symmetry the groove pushes straight up with the cable's weight (each face W / (2 sin a)
along its normal) and the centre line stays outside both faces grown by Bullet's margin (signed distance
computed from the groove's own planes). Before: at 240 Hz the groove pushed the cable sideways with 0.52
(45 degrees) and 0.91 (30 degrees) of its weight; at 60 Hz the energy check stopped the run within 0.17-0.33 s.
"""
from __future__ import annotations

import math

import numpy as np
import pybullet as pb
import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

G = 9.81
MARGIN = 1e-3  # [m] Bullet's collision margin of a mesh made by createCollisionShape
HALF_W, DEPTH, HALF_L, TOP = 0.03, 0.01, 0.2, 0.1  # [m] the groove block; its vertex line at z = TOP


def v_groove(cid: int, half_angle: float) -> int:
    """A static block along x with a V notch on top (vertex line at y = 0, z = TOP), a concave triangle mesh."""
    h = HALF_W / math.tan(half_angle)
    outline = [(-HALF_W, -DEPTH), (HALF_W, -DEPTH), (HALF_W, h), (0.0, 0.0), (-HALF_W, h)]  # (y, z), ccw
    pieces = [[(-HALF_W, -DEPTH), (0.0, -DEPTH), (0.0, 0.0), (-HALF_W, h)],
              [(0.0, -DEPTH), (HALF_W, -DEPTH), (HALF_W, h), (0.0, 0.0)]]  # the end caps, two convex halves
    k = len(outline)
    verts = [[-HALF_L, y, z] for y, z in outline] + [[HALF_L, y, z] for y, z in outline]
    tris = [t for i in range(k) for t in ((i, (i + 1) % k, k + (i + 1) % k), (i, k + (i + 1) % k, k + i))]
    for piece in pieces:
        for s, flip in ((-HALF_L, True), (HALF_L, False)):
            b = len(verts)
            verts += [[s, y, z] for y, z in piece]
            tris += [(b, b + m + 1, b + m) if flip else (b, b + m, b + m + 1) for m in range(1, len(piece) - 1)]
    col = pb.createCollisionShape(pb.GEOM_MESH, vertices=verts, indices=[i for t in tris for i in t],
                                  flags=pb.GEOM_FORCE_CONCAVE_TRIMESH, physicsClientId=cid)
    return pb.createMultiBody(0, col, -1, [0.0, 0.0, TOP], physicsClientId=cid)


@pytest.mark.parametrize("half_angle", [45.0, 30.0])
@pytest.mark.parametrize("hz,n", [(60.0, 10), (240.0, 20)])
def test_a_cable_rests_in_a_v_groove_on_both_faces(hz, n, half_angle):
    a = math.radians(half_angle)
    with BulletWorld(dt=1.0 / hz) as world:
        body = v_groove(world.client, a)
        spec = CableSpec.lv2017(n_masses=n, damping=0.02)
        r = spec.diameter / 2
        rest = (r + MARGIN) / math.sin(a)  # the axis touching both grown faces, above the vertex line
        cable = world.add_cable(spec, start=(-0.15, 0.0, TOP + rest + 1e-4), direction=(1, 0, 0),
                                integrator="implicit_euler")
        worst = np.inf
        for _ in range(int(round(1.0 * hz))):
            world.step()
            assert cable.stable, cable.reason
            y, z = cable.x[:, 1], cable.x[:, 2] - TOP
            # distance of the axis to each face's plane (through the vertex line), minus margin and radius
            gap = np.minimum(z * math.sin(a) + y * math.cos(a), z * math.sin(a) - y * math.cos(a)) - MARGIN - r
            worst = min(worst, float(gap.min()))
        weight = spec.mass * G
        force = cable.body_forces()[body] / weight  # the cable's force on the groove
        assert abs(force[2] + 1.0) < 0.01, force  # it carries the weight
        assert np.hypot(force[0], force[1]) < 0.01, force  # straight down: both faces, symmetric
        assert worst > -0.02 * r, worst  # never into either face
        assert np.abs(cable.x[:, 1]).max() < 0.02 * r  # stays on the groove's middle
