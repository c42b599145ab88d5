"""Camera framing, the tube's geometry, shadows from the first frame, plots that stay readable."""
from __future__ import annotations

import warnings

import cv2
import numpy as np
import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.boundary import Move
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.render import camera as camera_module
from bullet_dlo.render.camera import Camera, framing_camera, render_frame
from bullet_dlo.render.pipeline import cable_envelope
from bullet_dlo.render.plots import plot_wrenches
from bullet_dlo.render.tube import CableTube, segment_quat
from bullet_dlo.robots.transforms import rotation


def test_segment_quat_turns_the_cylinder_axis_onto_the_segment(rng):
    directions = np.vstack([rng.normal(size=(20, 3)), np.eye(3), -np.eye(3)])
    for d in directions:
        z = rotation(segment_quat(d)) @ np.array([0.0, 0.0, 1.0])
        assert np.allclose(z, d / np.linalg.norm(d), atol=1e-12)


def test_framing_camera_keeps_every_point_in_view_and_fills_the_frame(rng):
    points = rng.uniform(-0.3, 0.3, size=(40, 3)) + (0.0, 0.0, 0.5)
    margin = 1.1
    cam = framing_camera(points, width=320, height=240, margin=margin)
    with BulletWorld(ground=False) as world:
        uv, _ = cam.project(points, world.client)
    # in view, with the margin kept: |u - W/2| <= W/2 / margin (and the same for v)
    half = np.array([cam.width, cam.height]) / 2
    offset = np.abs(uv - half) / half
    assert np.all(offset <= 1.0 / margin + 1e-9)
    assert np.isclose(offset.max(), 1.0 / margin, atol=1e-6)  # the nearest distance that does it


def test_cable_envelope_holds_the_moved_ends_and_the_deepest_sag():
    ends = np.array([[-0.3, 0.0, 0.4], [0.3, 0.0, 0.4]])
    motion = [Move("first", (0.1, 0.0, 0.0), 0.0, 1.0), Move("last", (-0.1, 0.0, 0.2), 0.0, 1.0)]
    pts = cable_envelope(ends, 0.6, motion)
    final = np.array([[-0.2, 0.0, 0.4], [0.2, 0.0, 0.6]])
    assert any(np.allclose(p, final[0]) for p in pts) and any(np.allclose(p, final[1]) for p in pts)
    span = np.linalg.norm(final[1] - final[0])
    lowest = 0.5 * (final[0, 2] + final[1, 2]) - 0.5 * np.sqrt(0.6**2 - span**2)  # inextensible cable
    assert any(np.isclose(p[2], lowest) for p in pts)
    # half-way (min-jerk fraction 1/2) the ends are closer and lower on average: the cable hangs deeper
    # than at either end of the move, and the envelope must hold that too
    mid = np.array([[-0.25, 0.0, 0.4], [0.25, 0.0, 0.5]])
    mid_low = 0.5 * (mid[0, 2] + mid[1, 2]) - 0.5 * np.sqrt(0.6**2 - np.linalg.norm(mid[1] - mid[0]) ** 2)
    assert mid_low < lowest and pts[:, 2].min() <= mid_low + 1e-9
    free = cable_envelope(ends, 0.6, (), free=(False, True), ground=0.0)
    assert np.isclose(free[:, 0].max(), -0.3 + 0.6) and free[:, 2].min() == 0.0  # swings about the held end


@pytest.mark.parametrize("renderer", ["tiny", "auto"])
def test_shadows_are_drawn_on_the_first_frame(renderer):
    """A box floating 0.2 m above bare ground darkens the ground where the light's ray through it lands."""
    light = np.array([0.0, 1.0, 1.0]) / np.sqrt(2.0)
    cam = Camera(eye=(0.0, -1.0, 1.2), target=(0.0, -0.15, 0.0), width=160, height=120, light_direction=tuple(light))
    centre = np.array([0.0, 0.0, 0.3])
    shadow = centre - light * centre[2] / light[2]  # (0, -0.3, 0): the box's shadow centre on the ground
    far = np.array([0.45, 0.3, 0.0])  # ground the shadow does not reach
    frames = []
    for with_box in (True, False):
        with BulletWorld(renderer=renderer) as world:
            if with_box:
                world.add_box((0.1, 0.1, 0.1), tuple(centre))
            frames.append(render_frame(world.client, cam, world.renderer))  # each world's very first frame
            (u0, v0), (u1, v1) = np.rint(cam.project(np.array([shadow, far]), world.client)[0]).astype(int)
            ground = world.ground_id
    boxed, bare = (f.rgb.astype(float).sum(axis=-1) for f in frames)
    assert np.all(frames[0].body[v0 - 2:v0 + 3, u0 - 2:u0 + 3] == ground)  # the spot is ground, not the box
    assert np.median(bare[v0 - 2:v0 + 3, u0 - 2:u0 + 3] - boxed[v0 - 2:v0 + 3, u0 - 2:u0 + 3]) > 30
    assert abs(np.median(bare[v1 - 2:v1 + 3, u1 - 2:u1 + 3] - boxed[v1 - 2:v1 + 3, u1 - 2:u1 + 3])) < 10


def test_capture_is_the_old_name_of_render_frame():
    assert camera_module.capture is render_frame


def test_tube_shows_the_cable_thick_in_a_framed_shot():
    with BulletWorld(renderer="tiny") as world:
        cable = world.add_cable(CableSpec(length=0.6, diameter=0.012, mass=0.15, youngs_modulus=2e7, n_masses=12),
                                start=(-0.3, 0.0, 0.4), direction=(1.0, 0.0, 0.0), ends=("clamped", "clamped"))
        tube = CableTube(cable)
        cam = framing_camera(cable_envelope(cable.x[[0, -1]], 0.6, ()), width=320, height=240)
        frame = render_frame(world.client, cam, world.renderer, tube.mass_of_body())
    cols = np.flatnonzero((frame.cable_mass >= 0).any(axis=0))
    assert cols.max() - cols.min() > 0.8 * 320 / 1.1  # spans the frame width (10 % margin)
    thickness = (frame.cable_mass[:, 160] >= 0).sum()
    # a 12 mm cable whose 0.6 m fill ~290 px: about 12 / 600 * 290 = 6 px thick, seen from above at an angle
    assert 4 <= thickness <= 20


def test_force_plot_layout_without_warnings_and_cursor_boxes(tmp_path):
    t = np.linspace(0.0, 2.0, 201)
    model = np.zeros((201, 2, 3))
    model[:, 0, 0] = np.sin(t)
    sensor = np.concatenate([model, np.zeros((201, 2, 3))], axis=2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # e.g. "Tight layout not applied"
        info = plot_wrenches(t, sensor, model, tmp_path / "f.png", phases=((0.5, 1.5, "lift"), (3.0, 4.0, "later")))
    image = cv2.imread(str(info.path))
    h, w = image.shape[:2]
    assert len(info.axes_px) == 2
    (x0, x1, top0, bottom0), (_, _, top1, bottom1) = info.axes_px
    assert 0 < x0 < x1 < w and 0 < top0 < bottom0 < top1 < bottom1 < h  # stacked, inside the image
    # the sine's peak (1 N at t = pi/2) is drawn inside the first axis, in Fx's colour (blue)
    column = int(x0 + (x1 - x0) * (np.pi / 2) / 2.0)
    blue = np.flatnonzero((image[:, column, 0] > 150) & (image[:, column, 2] < 100))
    assert len(blue) and top0 <= blue.min() and blue.max() <= bottom0


def test_cable_envelope_follows_waypoints_and_sines():
    """Any motion item frames: a waypoint path's farthest knot and a sine's crest are inside the envelope."""
    from bullet_dlo.core.boundary import Sine, Waypoints

    ends = np.array([[-0.3, 0.0, 0.4], [0.3, 0.0, 0.4]])
    path = Waypoints("first", times=(0.0, 0.5, 1.0), displacements=((0, 0, 0), (0.0, 0.0, 0.15), (0.05, 0, 0)))
    wave = Sine("last", amplitude=(0.0, 0.08, 0.0), frequency=2.0, start=0.0, duration=1.0)
    pts = cable_envelope(ends, 0.6, [path, wave])
    assert pts[:, 2].max() >= 0.4 + 0.15 - 1e-9  # the path's highest knot (C2 path through it)
    assert pts[:, 1].max() > 0.06  # the sine's crest (sampled every 50 ms at 2 Hz: within 10 % of 0.08)
