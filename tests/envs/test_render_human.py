"""``render_mode="human"``: a live browser view of the environment (viser on the loopback), posed from Bullet's
own link frames after every reset and step; loaded in headless Chromium where one is installed."""
from __future__ import annotations

import shutil
import sys
import urllib.request
from pathlib import Path

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")
pytest.importorskip("viser", reason="the live view needs viser (pip install 'bullet-dlo[view]')")

import bullet_dlo  # noqa: E402,F401  (registers the environments)

pytestmark = pytest.mark.bullet
CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)), None)


@pytest.fixture(scope="module")
def env():
    env = gym.make("bullet_dlo/TensionTracking-v0", render_mode="human", settle_time=0.05)
    env.reset(seed=3)
    env.step(np.array([0.5, 0, 0, -0.5, 0, 0], np.float32))
    yield env
    env.close()


def test_live_view_follows_bullet_after_each_step(env):
    """The page answers on the loopback; each arm's grasp link is drawn at Bullet's grasp frame, the held cable
    ends at the grippers (the clamp's offset is below a few mm), and the drawing moves with the next step."""
    base = env.unwrapped
    live = base._live
    assert live.url.startswith("http://127.0.0.1:")
    with urllib.request.urlopen(live.url, timeout=30) as page:
        assert page.status == 200
    import pybullet as pb

    client = base.physics.world.client
    for (body, link), frame in live.frames.items():  # every drawn link where Bullet has its URDF frame
        pos = pb.getLinkState(body, link, computeForwardKinematics=True, physicsClientId=client)[4] if link >= 0 \
            else pb.getBasePositionAndOrientation(body, physicsClientId=client)[0]
        if link < 0 and np.any(pb.getDynamicsInfo(body, -1, physicsClientId=client)[3]):
            continue  # a base whose centre of mass is offset: checked in tests/render (URDF frames)
        assert np.allclose(frame.position, pos, atol=1e-6)  # (viser keeps float32)
    for robot, end in zip(base.physics.robots, (0, -1)):  # the held ends are at the drawn hands
        grasp, _ = robot.grasp_pose()
        assert np.linalg.norm(base.physics.cable.x[end] - grasp) < 5e-3
        hand = min(np.linalg.norm(np.array(f.position) - grasp) for (b, _), f in live.frames.items() if b == robot.body)
        assert hand < 0.15
    before = np.array(live.cable.nodes.points)
    env.step(np.array([1.0, 0, 0, 1.0, 0, 0], np.float32))
    after = np.array(live.cable.nodes.points)
    # (viser sends point clouds as float16: 2.4e-4 m resolution at 0.5 m)
    assert np.allclose(after, base.physics.cable.x, atol=5e-4) and np.abs(after - before).max() > 1e-3
    assert env.render() is None


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium on this machine (apt-get install chromium): the live view "
                    "is not loaded in a browser here")
def test_live_view_shows_the_cable_and_arms_in_headless_chromium(env, tmp_path):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "render"))
    from test_viewer import read_png, screenshot

    red = lambda im: (im[..., 0] - im[..., 1] > 30) & (im[..., 0] - im[..., 2] > 30) & (np.abs(im[..., 1] - im[..., 2]) < 40)  # noqa: E731
    blue = lambda im: (im[..., 2] - im[..., 0] > 40) & (im[..., 2] - im[..., 1] > 20)  # noqa: E731
    crop = lambda im: im[int(0.32 * im.shape[0]): int(0.9 * im.shape[0])]  # noqa: E731  (below the panels)
    png = tmp_path / "human.png"
    screenshot(env.unwrapped._live.url, png, ready=lambda p: red(crop(read_png(p))).sum() >= 30 and
               blue(crop(read_png(p))).sum() >= 300)
    scene = crop(read_png(png))
    print(f"\nhuman view: red pixels {red(scene).sum()}, blue pixels {blue(scene).sum()}")
    assert red(scene).sum() >= 30, "the cable's red is not on screen"
    assert blue(scene).sum() >= 300, "the arms' blue links are not on screen"
