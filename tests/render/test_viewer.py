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
