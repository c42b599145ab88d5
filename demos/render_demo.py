"""Headless video of the dual-arm cable manipulation, and the cost of each renderer.

Renders the Panda scene (hold, the study's 5 mm lift, bringing the ends together, lifting)
to an H.264 MP4 plus a side-by-side video (scene left, wrist forces with a moving cursor
right), and times a 640x480 frame with TinyRenderer and with the EGL plugin (when it loads).
Writes into the output folder: ``scene.mp4``, ``side_by_side.mp4``, ``forces.png``,
``still.png``, ``render.json``, ``frame_times.json``.

Usage: ``python demos/render_demo.py [--out DIR] [--robot panda] [--quick]``
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path

from bullet_dlo.config.scene import Scene
from bullet_dlo.core.boundary import Move
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.render.camera import RenderError, capture, default_camera
from bullet_dlo.render.pipeline import render_scene
from bullet_dlo.robots.dual_arm import DualArmConfig, DualArmScene


def frame_time(renderer: str, robot: str, repeats: int = 5) -> dict:
    """Median time [s] of one 640x480 frame (RGB + depth + segmentation) of the dual-arm scene."""
    try:
        scene = DualArmScene(DualArmConfig(robot=robot, renderer=renderer))
    except RenderError as err:
        return {"renderer": renderer, "available": False, "note": str(err)}
    with scene:
        cam = default_camera([(-0.6, 0, 0), (0.6, 0, 0), (0, 0, 0.6)], 640, 480)
        capture(scene.world.client, cam, scene.world.renderer)  # first frame: set-up costs
        times = []
        for _ in range(repeats):
            tic = time.perf_counter()
            capture(scene.world.client, cam, scene.world.renderer)
            times.append(time.perf_counter() - tic)
        return {"renderer": scene.world.renderer.name, "available": True, "note": scene.world.renderer.note,
                "frame_time_s": statistics.median(times)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join("out", "render_demo"), help="output folder")
    parser.add_argument("--robot", default="panda", help="robot holding the cable (kuka, panda)")
    parser.add_argument("--quick", action="store_true", help="a 1 s clip at 160x120 (smoke test)")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    motion = [Move("last", (0.0, 0.0, 0.005), 1.0, 0.1)]
    if not args.quick:
        motion += [Move("last", (-0.12, 0.0, 0.0), 2.0, 1.5), Move("first", (0.0, 0.0, 0.15), 4.0, 1.5),
                   Move("last", (0.0, 0.0, 0.15), 4.0, 1.5)]
    scene = Scene(cable=CableSpec.lv2017(n_masses=15, damping=0.02), motion=tuple(motion), dt=1 / 240,
                  duration=1.0 if args.quick else 6.0, name="dual-arm cable")
    size = (160, 120) if args.quick else (640, 480)
    summary = render_scene(scene, out, robot=args.robot, width=size[0], height=size[1])
    print(f"video: {summary['video']} ({summary['codec']}, {summary['frames']} frames, "
          f"{summary.get('bytes_per_second', 0) / 1000:.0f} kB per second of video); renderer {summary['renderer']}")
    timings = [frame_time(r, args.robot, 2 if args.quick else 5) for r in ("tiny", "egl")]
    for t in timings:
        if t["available"]:
            print(f"640x480 frame, {t['renderer']:4s}: {1000 * t['frame_time_s']:.1f} ms")
        else:
            print(f"{t['renderer']}: unavailable ({t['note']})")
    (out / "frame_times.json").write_text(json.dumps(timings, indent=2))
    print(f"\noutputs written to {out.resolve()}")


if __name__ == "__main__":
    main()
