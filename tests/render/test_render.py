"""Headless rendering: frames with content where the cable is, metric depth, video files."""
from __future__ import annotations

import numpy as np
import pybullet as pb
import pytest

import bullet_dlo.bullet.renderer as bullet_renderer
from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.render.camera import Camera, Renderer, RenderError, render_frame
from bullet_dlo.render.plots import plot_wrenches
from bullet_dlo.render.tube import CableTube
from bullet_dlo.render.video import Recorder, VideoWriter, probe_video, side_by_side

CAMERA = Camera(eye=(0.15, -0.6, 0.75), target=(0.15, 0.0, 0.5), width=320, height=240, fov=50)


def cable_world(renderer):
    world = BulletWorld(dt=1 / 240, renderer=renderer)
    world.add_box((0.1, 0.1, 0.1), (0.6, 0.4, 0.1))
    cable = world.add_cable(CableSpec.lv2017(n_masses=12, diameter=0.01), start=(0.0, 0.0, 0.5),
                            direction=(1.0, 0.0, 0.0), ends=("clamped", "clamped"))
    return world, cable


@pytest.mark.parametrize("renderer", ["tiny", "auto"])
def test_frame_shows_the_cable_where_it_is(renderer):
    world, cable = cable_world(renderer)
    with world:
        tube = CableTube(cable)
        frame = render_frame(world.client, CAMERA, world.renderer, tube.mass_of_body())
        assert frame.rgb.shape == (240, 320, 3) and frame.rgb.std() > 5.0  # not blank
        uv, _ = CAMERA.project(cable.x, world.client)
        view, _ = CAMERA.matrices(world.client)
        z_cam = -(view @ np.c_[cable.x, np.ones(len(cable.x))].T)[2]  # distance along the optical axis
        for i, ((u, v), z) in enumerate(zip(uv, z_cam)):
            r, c = int(round(v)), int(round(u))
            window = frame.cable_mass[r - 1:r + 2, c - 1:c + 2]
            assert np.any(window >= 0), f"mass {i} not drawn at its projected pixel ({c}, {r})"
            assert abs(frame.depth[r, c] - z) < 0.01  # metric depth within 1 cm (radius 5 mm)
        body_pixels = np.isin(frame.body, cable.body_ids + tube.bodies)
        assert np.array_equal(body_pixels, frame.cable_mass >= 0)
        assert set(np.unique(frame.cable_mass[frame.cable_mass >= 0])) >= {0, 5, 11}  # whole cable visible
        assert frame.renderer == world.renderer.name


def test_egl_missing_gives_clear_error_and_auto_falls_back(monkeypatch):
    monkeypatch.setattr(bullet_renderer, "egl_plugin_path", lambda loader: "/nonexistent/eglRenderer.so")
    client = pb.connect(pb.DIRECT)
    try:
        with pytest.raises(RenderError, match="renderer='egl' is not available on this machine"):
            Renderer(client, "egl")
        auto = Renderer(client, "auto")
        assert auto.name == "tiny" and "EGL unavailable" in auto.note
    finally:
        pb.disconnect(client)
    with pytest.raises(ParameterError, match="renderer must be one of auto, tiny, egl"):
        Renderer(0, "opengl")


def test_blank_frame_is_an_error_not_a_picture():
    world, cable = cable_world("tiny")
    with world:
        empty_sky = Camera(eye=(0, 0, 3), target=(0, 0, 10), width=64, height=48)  # looks at nothing
        with pytest.raises(RenderError, match="blank frame"):
            render_frame(world.client, empty_sky, world.renderer)


def test_camera_validation():
    with pytest.raises(ParameterError, match="camera width"):
        Camera(width=0)
    with pytest.raises(ParameterError, match="far"):
        Camera(near=1.0, far=0.5)
    with pytest.raises(ParameterError, match="eye and target must differ"):
        Camera(eye=(0, 0, 1), target=(0, 0, 1))


def test_video_decodes_with_expected_frames_size_and_codec(tmp_path):
    world, cable = cable_world("tiny")
    with world:
        writer = VideoWriter(tmp_path / "clip", fps=20)
        rec = Recorder(world, CAMERA, world.renderer, fps=20, writer=writer, tube=CableTube(cable))
        world.after_step.append(rec.on_step)
        rec.on_step()
        world.run(1.0)  # 240 physics steps, 20 frames per second: 21 frames with t = 0
        writer.close()
    info = probe_video(writer.path)
    assert writer.format == "mp4" and info["codec"] == "h264"  # browser-playable
    assert info["frames"] == 21 == len(rec.times)
    assert (info["width"], info["height"]) == (320, 240)
    assert np.allclose(np.diff(rec.times), 1 / 20, atol=1 / 240)  # frames decoupled from the physics rate


def test_fallback_formats_and_side_by_side(tmp_path):
    frames = [np.full((48, 64, 3), k * 20, dtype=np.uint8) for k in range(5)]
    png = VideoWriter(tmp_path / "seq", fps=10, fmt="png")
    for f in frames:
        png.write(f)
    png.close()
    assert png.format == "png" and len(list(png.path.glob("*.png"))) == 5
    webm = VideoWriter(tmp_path / "v", fps=10, fmt="webm")
    for f in frames:
        webm.write(f)
    webm.close()
    assert probe_video(webm.path)["codec"] == "vp9" and probe_video(webm.path)["frames"] == 5
    t = np.linspace(0, 0.4, 5)
    model = np.zeros((5, 2, 3))
    model[:, 0, 0] = t
    plot = plot_wrenches(t, None, model, tmp_path / "f.png")
    mp4 = VideoWriter(tmp_path / "scene", fps=10)
    for f in frames:
        mp4.write(f)
    mp4.close()
    sbs = side_by_side(mp4.path, plot, t, tmp_path / "sbs", fps=10)
    info = probe_video(sbs.path)
    assert info["frames"] == 5 and info["width"] > 64 and info["height"] == 48


def test_an_interrupted_video_leaves_no_file_under_its_final_name(tmp_path):
    """Issue 26 audit: a Ctrl-C during ``render`` left a 48-byte scene.mp4 PyAV cannot open. Videos are written
    under a temporary name and renamed when closed; an interrupt removes the partial file."""
    frames = [np.full((48, 64, 3), k * 20, dtype=np.uint8) for k in range(5)]
    with pytest.raises(KeyboardInterrupt):
        with VideoWriter(tmp_path / "scene", fps=10, fmt="mp4") as writer:
            for f in frames:
                writer.write(f)
            assert not (tmp_path / "scene.mp4").exists()
            raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []
    with VideoWriter(tmp_path / "scene", fps=10, fmt="mp4") as writer:
        for f in frames:
            writer.write(f)
    assert [p.name for p in tmp_path.iterdir()] == ["scene.mp4"] and probe_video(writer.path)["frames"] == 5
