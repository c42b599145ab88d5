"""``bullet-dlo view``: every kind of recorded run written as one self-contained page, its contents
checked (entities, frames), and the page loaded in headless Chromium: a screenshot shows the cable
and the arms (pixels checked, not only that the page loaded).

The browser is the system's (``apt-get install chromium``), driven over the DevTools protocol
with software WebGL (SwiftShader); the browser test is skipped, saying so, where none is installed.
"""
from __future__ import annotations

import base64
import io
import json
import os
import re
import shutil
import subprocess
import tempfile
import time
import urllib.request
import zlib
from pathlib import Path

import numpy as np
import pytest
import yaml

pytest.importorskip("viser", reason="the viewer needs viser (pip install 'bullet-dlo[view]')")

from bullet_dlo.cli.main import main  # noqa: E402
from bullet_dlo.render.viewer import CABLE_RGB, ARM_RGB  # noqa: E402

pytestmark = pytest.mark.bullet
ROOT = Path(__file__).resolve().parents[2]
PEG = ROOT / "demos" / "scenes" / "panda_peg.yaml"
CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)), None)


def embedded(page: Path) -> dict:
    """The recording inlined in a viewer page, decoded (viser's format: zstd msgpack + buffers)."""
    import msgspec
    import zstandard

    html = page.read_text()
    b64 = re.search(r'window.__VISER_EMBED_DATA__="([^"]+)"', html).group(1)
    raw = base64.b64decode(b64)
    inner = zstandard.ZstdDecompressor().decompress(raw[8:], max_output_size=int.from_bytes(raw[:8], "little"))
    n = int.from_bytes(inner[:8], "little")
    return msgspec.msgpack.decode(inner[8:8 + n])


def names(rec: dict) -> set[str]:
    return {m[1]["name"] for m in rec["messages"] if isinstance(m[1], dict) and "name" in m[1]}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A 0.2 s grasp of the peg scene (Pandas, a peg obstacle) with its series, a 0.2 s capture episode and
    a short rollout, each written as a page by the CLI."""
    tmp = tmp_path_factory.mktemp("view")
    assert main(["grasp", "--scene", str(PEG), "--robot", "panda", "--duration", "0.2",
                 "--series", str(tmp / "grasp.npz"), "-q"]) == 0
    spec = yaml.safe_load((ROOT / "demos" / "specs" / "dr_small.yaml").read_text())
    spec["episode"]["duration"] = 0.2
    spec["sample"]["robot"] = {"dist": "fixed", "value": "kuka"}
    from bullet_dlo.config.capture import CaptureSpec
    from bullet_dlo.data.capture import capture
    from bullet_dlo.envs.rollouts import record_rollouts

    assert capture(CaptureSpec.from_dict(spec), tmp / "cap", 1, progress=False).failed == 0
    record_rollouts("bullet_dlo/TensionTracking-v0", "zero", tmp / "roll", 1, record_rate=60.0,
                    env_kwargs={"settle_time": 0.05, "max_episode_steps": 3}, progress=False)
    pages = {}
    for kind, args in {"grasp": [str(tmp / "grasp.npz"), "--scene", str(PEG)],
                       "capture": [str(tmp / "cap")],
                       "episode": [str(next((tmp / "cap").rglob("*.h5")))],
                       "rollout": [str(tmp / "roll"), "--episode", "0"]}.items():
        page = tmp / f"{kind}.html"
        assert main(["view", *args, "--out", str(page), "-q"]) == 0, kind
        pages[kind] = page
    return tmp, pages


def test_grasp_page_holds_cable_arms_obstacle_wrenches_plot_and_every_row(runs):
    tmp, pages = runs
    rec = embedded(pages["grasp"])
    got = names(rec)
    for name in ("/cable/line", "/cable/nodes", "/world/ground", "/world/obstacles/0", "/wrench", "/plot/image",
                 "/plot/cursor", "/contacts/points", "/contacts/forces"):
        assert name in got, name
    assert any(n.startswith("/arms/left/link") for n in got) and any(n.startswith("/arms/right/link") for n in got)
    with np.load(tmp / "grasp.npz") as f:
        k = len(f["t"])
    # one cable update per row: the first comes with the node, then one per row
    updates = [m for m in rec["messages"] if m[1].get("name") == "/cable/line" and m[1].get("type") != "LineSegmentsMessage"]
    assert len(updates) + 1 >= k and k == 48  # 0.2 s at 1/240 s
    assert rec["durationSeconds"] == pytest.approx(0.2 - 1 / 240 + 0.5, abs=1e-6)


@pytest.mark.parametrize("kind", ["capture", "episode", "rollout"])
def test_dataset_episode_and_rollout_pages(runs, kind):
    _, pages = runs
    got = names(embedded(pages[kind]))
    assert {"/cable/line", "/world/table", "/wrench", "/plot/image"} <= got
    assert any(n.startswith("/arms/right/link") for n in got)


def test_simulate_and_render_results(tmp_path):
    scene = ROOT / "demos" / "scenes" / "hanging.yaml"
    assert main(["simulate", str(scene), "--duration", "0.05", "--npz", str(tmp_path / "s.npz"), "-q"]) == 0
    assert main(["view", str(tmp_path / "s.npz"), "--scene", str(scene), "--out", str(tmp_path / "s.html"), "-q"]) == 0
    got = names(embedded(tmp_path / "s.html"))
    assert "/cable/line" in got and not any(n.startswith("/arms") for n in got)
    (tmp_path / "r").mkdir()
    (tmp_path / "r" / "render.json").write_text(json.dumps({"final_positions": [[0, 0, 0.3], [0.1, 0, 0.3]]}))
    assert main(["view", str(tmp_path / "r"), "--out", str(tmp_path / "r.html"), "-q"]) == 0


@pytest.mark.parametrize("args, words", [
    (["missing.npz", "--out", "x.html"], "no such file"),
    (["{run}", "--out", "x.png"], "must end in .html"),
    (["{run}"], "--out PAGE.html, --serve"),
    (["{tmp}", "--out", "x.html"], "neither a capture"),
    (["{run}", "--out", "x.html", "--max-frames", "0"], "--max-frames"),
    (["{junk}", "--out", "x.html"], "not a readable .npz"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, args, words):
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    np.savez(tmp_path / "run.npz", t=np.arange(3.0), x=np.zeros((3, 4, 3)))
    fill = {"run": str(tmp_path / "run.npz"), "tmp": str(tmp_path), "junk": str(tmp_path / "junk.npz")}
    argv = [a.format(**fill) for a in args]
    os.chdir(tmp_path)
    assert main(["view", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and words in err[0], err


def test_contacts_on_the_ground_carry_the_weight():
    """A cable lying on the ground at rest: every mass touches, and the estimated contact forces add up
    to its weight (m a - f_model with a = 0: gravity, the stretch forces cancel)."""
    from bullet_dlo.core.model import STANDARD_GRAVITY
    from bullet_dlo.core.spec import CableSpec
    from bullet_dlo.render.viewer import Run, contacts

    cable = CableSpec.lv2017(n_masses=10, damping=0.02)
    x = np.zeros((4, 10, 3))
    x[:, :, 0] = np.linspace(0, cable.length, 10)
    x[:, :, 2] = cable.diameter / 2
    points, forces = contacts(Run(t=np.arange(4) * 0.01, cable_x=x, radius=cable.diameter / 2, cable=cable))
    assert all(len(p) == 10 for p in points)
    assert np.allclose(points[0][:, 2], 0.0)
    assert np.sum(forces[0][:, 2]) == pytest.approx(cable.mass * np.linalg.norm(STANDARD_GRAVITY), rel=1e-6)


# ----- the browser ------------------------------------------------------------------------------------
def screenshot(url: str, png: Path, ready=None, timeout: float = 90.0, size=(1024, 768)) -> str:
    """Load ``url`` in headless Chromium (software WebGL) and save a screenshot once ``ready(png)`` holds (every
    2 s; software WebGL on a busy machine takes from 3 s to tens of seconds to draw the page) or ``timeout`` [s]
    has passed; returns the page title."""
    from websockets.sync.client import connect

    profile = tempfile.mkdtemp()
    proc = subprocess.Popen([CHROMIUM, "--headless=new", "--no-sandbox", "--use-angle=swiftshader",
                             "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist", "--no-first-run",
                             f"--window-size={size[0]},{size[1]}", "--remote-debugging-port=0",
                             f"--user-data-dir={profile}", "about:blank"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        port_file = Path(profile) / "DevToolsActivePort"
        deadline = time.monotonic() + 30
        while not (port_file.exists() and port_file.read_text().strip()):
            assert time.monotonic() < deadline, "chromium did not start"
            time.sleep(0.1)
        port = int(port_file.read_text().split()[0])
        targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json"))
        ws_url = next(t["webSocketDebuggerUrl"] for t in targets if t["type"] == "page")
        with connect(ws_url, max_size=None) as ws:
            ids = iter(range(1, 1000))

            def call(method, **params):
                i = next(ids)
                ws.send(json.dumps({"id": i, "method": method, "params": params}))
                while True:
                    msg = json.loads(ws.recv(timeout=60))
                    if msg.get("id") == i:
                        return msg.get("result", {})

            call("Page.enable")
            call("Page.navigate", url=url)
            end = time.monotonic() + timeout
            while True:
                time.sleep(2.0)
                png.write_bytes(base64.b64decode(call("Page.captureScreenshot", format="png")["data"]))
                if ready is None or ready(png) or time.monotonic() > end:
                    break
            title = call("Runtime.evaluate", expression="document.title")["result"]["value"]
        return title
    finally:
        proc.terminate()
        proc.wait(10)
        shutil.rmtree(profile, ignore_errors=True)


def read_png(path: Path) -> np.ndarray:
    import imageio.v3 as iio

    return iio.imread(path)[:, :, :3].astype(int)


def near(img: np.ndarray, rgb, tol: int = 40) -> np.ndarray:
    return np.all(np.abs(img - np.array(rgb)) <= tol, axis=2)


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium on this machine (apt-get install chromium): the page is "
                    "not loaded in a browser here")
def test_page_renders_cable_and_arms_in_headless_chromium(runs):
    tmp, pages = runs
    png = tmp / "grasp.png"
    drawn = lambda path: near(read_png(path), CABLE_RGB, 45).sum() >= 50  # noqa: E731  (the last thing drawn)
    title = screenshot(pages["grasp"].resolve().as_uri(), png, ready=drawn)
    assert "Viser" in title
    img = read_png(png)
    h, w = img.shape[:2]
    scene = img[: int(0.9 * h)]  # above the timeline bar
    cable = near(scene, CABLE_RGB, 45)
    arms = near(scene, ARM_RGB, 45)
    background = np.median(scene.reshape(-1, 3), axis=0)
    differs = np.any(np.abs(scene - background) > 30, axis=2)
    print(f"\ncable-red pixels {cable.sum()}, arm-blue pixels {arms.sum()}, pixels differing from the "
          f"background {background.tolist()}: {differs.mean():.1%}")
    assert cable.sum() >= 50, "the cable's red is not on screen"
    assert arms.sum() >= 500, "the arms' blue links are not on screen"
    ys, xs = np.nonzero(arms)
    assert xs.min() < w / 2 < xs.max(), "both arms: blue pixels on either side of the middle"
    assert differs.mean() > 0.02, "the scene is (nearly) blank"


# ----- the tube, URDF obstacles, contacts of a recorded run, the live page ------------------------------
def test_tube_cylinders_join_the_masses():
    """Each cylinder of the tube, mapped from the unit cylinder by its transform, ends at its two masses and
    has the cable's radius (a wrong rotation or scale puts its ends elsewhere)."""
    from bullet_dlo.render.viewer import _unit_cylinder, tube_transforms

    rng = np.random.default_rng(3)
    x = np.cumsum(rng.normal(size=(12, 3)) * 0.05, axis=0)
    x[5] = x[4] - (0, 0, 0.05)  # a segment pointing straight down (the rotation's singular case)
    pos, wxyz, scale = tube_transforms(x, 0.003)
    verts, _ = _unit_cylinder(12)
    for k in range(len(x) - 1):
        w, qx, qy, qz = wxyz[k].astype(float)
        rot = np.array([[1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * w), 2 * (qx * qz + qy * w)],
                        [2 * (qx * qy + qz * w), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * w)],
                        [2 * (qx * qz - qy * w), 2 * (qy * qz + qx * w), 1 - 2 * (qx * qx + qy * qy)]])
        world = (verts * scale[k]) @ rot.T + pos[k]
        assert np.allclose(world[-2], x[k], atol=1e-6) and np.allclose(world[-1], x[k + 1], atol=1e-6)
        radial = np.linalg.norm(np.cross(world[:12] - x[k], (x[k + 1] - x[k]) / np.linalg.norm(x[k + 1] - x[k])), axis=1)
        assert np.allclose(radial, 0.003, atol=1e-6)


def test_urdf_obstacle_is_drawn_where_bullet_has_it(tmp_path):
    """A scene's URDF obstacle (a table with child-link legs) appears in the page, each visual mesh at its
    link's pose: the drawn vertices span the box PyBullet gives the loaded body (within 1 cm)."""
    import pybullet as pb

    from bullet_dlo.bullet.world import resolve_asset
    from bullet_dlo.render.viewer import Run, urdf_geometry, write_viewer

    ob = {"type": "urdf", "path": "table_square/table_square.urdf", "position": [0.3, -0.2, 0.0], "orientation": [0, 0, 0.3826834, 0.9238795]}
    geo = urdf_geometry([ob])
    assert len(geo) == 1
    meshes, poses = geo[0]
    pts = []
    for (_link, mesh, _rgb, lpos, lwxyz), pose in zip(meshes, poses):
        def rot(q):
            w, x, y, z = q
            return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                             [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                             [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        local = np.asarray(mesh.vertices) @ rot(lwxyz).T + lpos
        pts.append(local @ rot(pose[3:]).T + pose[:3])
    pts = np.vstack(pts)
    cid = pb.connect(pb.DIRECT)
    try:
        body = pb.loadURDF(str(resolve_asset(ob["path"])), ob["position"], ob["orientation"], useFixedBase=True,
                           physicsClientId=cid)
        boxes = [pb.getAABB(body, link, physicsClientId=cid) for link in range(-1, pb.getNumJoints(body, physicsClientId=cid))]
    finally:
        pb.disconnect(cid)
    lo = np.min([b[0] for b in boxes], axis=0)
    hi = np.max([b[1] for b in boxes], axis=0)
    assert np.allclose(pts.min(axis=0), lo, atol=0.01) and np.allclose(pts.max(axis=0), hi, atol=0.01)
    x = np.zeros((2, 5, 3))
    x[:, :, 0] = np.linspace(0, 0.3, 5)
    info = write_viewer(Run(t=[0.0, 0.1], cable_x=x, obstacles=(ob,)), tmp_path / "t.html")
    assert "urdf meshes(1)" in info.entities
    assert sum(n.startswith("/world/urdf/0/visual") and n.endswith("/mesh") for n in names(embedded(info.path))) == len(meshes)


def test_contacts_of_a_recorded_bullet_run_carry_the_weight(tmp_path):
    """A Bullet run in which the cable falls onto a box and comes to rest: the page shows contacts on the
    box's top face, and at the last row the estimated contact forces carry the cable's weight (within 3 %)."""
    from bullet_dlo.core.model import STANDARD_GRAVITY
    from bullet_dlo.data.runs import load_run
    from bullet_dlo.render.viewer import contacts

    scene = {"name": "on_box", "cable": {"preset": "lv2017", "n_masses": 12, "damping_rate": 20.0},
             "layout": {"start": [-0.15, 0.0, 0.215], "direction": [1, 0, 0]}, "ends": {"first": "free", "last": "free"},
             "integrator": "implicit_euler", "dt": 1 / 240, "duration": 1.0,
             "bullet": {"obstacles": [{"type": "box", "half_extents": [0.25, 0.1, 0.1], "position": [0, 0, 0.1]}]}}
    path = tmp_path / "on_box.yaml"
    path.write_text(yaml.safe_dump(scene))
    assert main(["simulate", str(path), "--engine", "bullet", "--npz", str(tmp_path / "r.npz"), "-q"]) == 0
    from bullet_dlo.config.scene import Scene

    run = load_run(tmp_path / "r.npz", scene=Scene.from_yaml(path))
    points, forces = contacts(run)
    assert len(points[-1]) == run.cable_x.shape[1], "every mass rests on the box"
    assert np.allclose(points[-1][:, 2], 0.2, atol=1e-3), "contact points on the box's top face"
    weight = run.cable.mass * np.linalg.norm(STANDARD_GRAVITY)
    assert np.sum(forces[-1][:, 2]) == pytest.approx(weight, rel=0.03)
    assert main(["view", str(tmp_path / "r.npz"), "--scene", str(path), "--out", str(tmp_path / "r.html"), "-q"]) == 0
    shown = [m for m in embedded(tmp_path / "r.html")["messages"] if m[1].get("name") == "/contacts/points"]
    assert len(shown) > 1, "the contact points are updated in the page"


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium on this machine (apt-get install chromium): the live page is "
                    "not loaded in a browser here")
def test_live_page_renders_the_cable_in_headless_chromium(runs, tmp_path):
    """``--serve``'s page (viser over a websocket on the loopback), opened in a real browser: the cable's
    tube and line are drawn."""
    import threading

    from bullet_dlo.data.runs import load_run
    from bullet_dlo.render.viewer import serve

    tmp, _ = runs
    from bullet_dlo.config.scene import Scene

    run = load_run(tmp / "grasp.npz", scene=Scene.from_yaml(PEG))
    urls: list[str] = []
    thread = threading.Thread(target=serve, args=(run,), kwargs={"seconds": 150.0, "ready": urls.append}, daemon=True)
    thread.start()
    deadline = time.monotonic() + 60
    while not urls:
        assert time.monotonic() < deadline and thread.is_alive(), "the live page did not come up"
        time.sleep(0.2)
    png = tmp_path / "live.png"
    # by hue, not by exact colour: the live client fades the scene in for a few seconds after connecting
    red = lambda im: (im[..., 0] - im[..., 1] > 30) & (im[..., 0] - im[..., 2] > 30) & (np.abs(im[..., 1] - im[..., 2]) < 40)  # noqa: E731
    blue = lambda im: (im[..., 2] - im[..., 0] > 40) & (im[..., 2] - im[..., 1] > 20)  # noqa: E731
    # below the panels (the slider and play box are blue) and above the axes gizmo (red)
    crop = lambda im: im[int(0.32 * im.shape[0]): int(0.9 * im.shape[0])]  # noqa: E731
    drawn = lambda im: red(im).sum() >= 50 and blue(im).sum() >= 300  # noqa: E731
    screenshot(urls[0], png, ready=lambda path: drawn(crop(read_png(path))))
    img = read_png(png)
    scene = crop(img)
    print(f"\nlive page: red pixels {red(scene).sum()}, blue pixels {blue(scene).sum()}")
    assert red(scene).sum() >= 50, "the cable's red is not on screen"
    assert blue(scene).sum() >= 300, "the arms' blue links are not on screen"
    ys, xs = np.nonzero(blue(scene))
    assert xs.min() < img.shape[1] / 2 < xs.max(), "both arms: blue pixels on either side of the middle"


def test_routing_rollout_page_draws_the_pegs_and_the_clip(tmp_path):
    """A Routing-v0 rollout records its episode's obstacles (pegs and clip, drawn per episode); the page draws
    each where the environment put it."""
    import h5py

    from bullet_dlo.data.runs import load_run
    from bullet_dlo.envs.rollouts import record_rollouts

    record_rollouts("bullet_dlo/Routing-v0", "zero", tmp_path / "roll", 1, record_rate=20.0,
                    env_kwargs={"settle_time": 0.05, "max_episode_steps": 2}, progress=False)
    episode = next((tmp_path / "roll").rglob("*.h5"))
    with h5py.File(episode) as f:
        recorded = json.loads(f.attrs["obstacles"])
    pegs = [ob for ob in recorded if ob["name"].startswith("peg_")]
    clip = [ob for ob in recorded if ob["name"].startswith("clip_")]
    assert 1 <= len(pegs) <= 2 and len(clip) == 2 and all(ob["type"] == "cylinder" for ob in pegs)
    run = load_run(tmp_path / "roll")
    assert [ob["position"] for ob in run.obstacles] == [ob["position"] for ob in recorded]
    assert main(["view", str(tmp_path / "roll"), "--out", str(tmp_path / "r.html"), "-q"]) == 0
    got = names(embedded(tmp_path / "r.html"))
    assert {f"/world/obstacles/{k}" for k in range(len(recorded))} <= got


def test_render_output_directory_is_viewed_as_its_whole_run(tmp_path):
    """``render`` writes its run at the video's rate (run.npz) beside the video; ``view OUT`` shows every row
    of it (not only the last shape), with the cable's model for the contact forces."""
    scene = yaml.safe_load((ROOT / "demos" / "scenes" / "hanging.yaml").read_text())
    scene["duration"] = 0.3
    path = tmp_path / "hanging.yaml"
    path.write_text(yaml.safe_dump(scene))
    assert main(["render", str(path), "--out", str(tmp_path / "r"), "--fps", "20", "--width", "64", "--height", "48",
                 "-q"]) == 0
    with np.load(tmp_path / "r" / "run.npz") as f:
        t, x = f["t"], f["cable_x"]
    assert np.allclose(np.diff(t), 0.05, atol=1e-9) and len(t) == 7 and x.shape == (7, 20, 3)
    summary = json.loads((tmp_path / "r" / "render.json").read_text())
    np.testing.assert_allclose(x[-1], summary["final_positions"], atol=1e-12)  # the last row is the final shape
    from bullet_dlo.data.runs import load_run

    run = load_run(tmp_path / "r")
    assert run.frames == 7 and run.cable is not None and run.cable.n_masses == 20
    assert main(["view", str(tmp_path / "r"), "--out", str(tmp_path / "r.html"), "-q"]) == 0
    assert embedded(tmp_path / "r.html")["durationSeconds"] == pytest.approx(0.3 + 0.5, abs=1e-6)  # every row


def test_render_with_arms_records_the_arms_for_the_viewer(tmp_path):
    scene = yaml.safe_load(PEG.read_text())
    scene["duration"] = 0.15
    path = tmp_path / "peg.yaml"
    path.write_text(yaml.safe_dump(scene))
    assert main(["render", str(path), "--robot", "panda", "--out", str(tmp_path / "r"), "--fps", "20",
                 "--width", "64", "--height", "48", "-q"]) == 0
    with np.load(tmp_path / "r" / "run.npz") as f:
        assert f["joint_q"].shape == (3, 2, 7) and f["wrench_world"].shape == (3, 2, 6)
    assert main(["view", str(tmp_path / "r"), "--scene", str(path), "--out", str(tmp_path / "r.html"), "-q"]) == 0
    got = names(embedded(tmp_path / "r.html"))
    assert any(n.startswith("/arms/left/link") for n in got) and "/world/obstacles/0" in got and "/wrench" in got
