"""Headless video of a dual-arm cable manipulation, and what a frame costs with each renderer.

1. Renders the Panda scene (hold, the study's 5 mm lift, bringing the ends 12 cm together so
   the Lv cable buckles, lifting both) to an H.264 MP4 plus a side-by-side video (scene left,
   wrist forces with a moving cursor right).
2. Times one 640x480 frame (RGB + depth + segmentation, one ``getCameraImage`` call) of the
   same dual-arm scene (floor, table, two Pandas, the cable as 15 spheres + 14 tube segments)
   with TinyRenderer (shadows on and off) and with the EGL plugin, from the camera framed on
   the cable (the arms fill much of the picture) and from a wide view of the whole scene, all
   settings interleaved frame by frame so that machine load hits all alike; prints the median
   wall and CPU time, the spread and the conditions (GL renderer: llvmpipe is Mesa's CPU
   rasteriser, anything else a GPU; cores and load; frames).

Writes into the output folder: ``scene.mp4``, ``side_by_side.mp4``, ``forces.png``,
``still.png``, ``render.json``, ``frame_times.json``.

Usage: ``python demos/render_demo.py [--out DIR] [--robot panda] [--frames 30] [--quick]``
"""
from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import time
from dataclasses import replace
from pathlib import Path

from bullet_dlo.cli.quiet import native_output
from bullet_dlo.config.scene import Scene
from bullet_dlo.core.boundary import Move
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.render.camera import RenderError, default_camera, framing_camera, render_frame
from bullet_dlo.render.pipeline import cable_envelope, render_scene
from bullet_dlo.render.tube import CableTube
from bullet_dlo.robots.dual_arm import DualArmConfig, DualArmScene

CABLE = CableSpec.lv2017(n_masses=15, damping=0.02)
PHASES = ((1.0, 1.1, "5 mm"), (1.5, 3.5, "ends together"), (4.0, 5.5, "lift"))


def motion(quick: bool) -> tuple[Move, ...]:
    moves = [Move("last", (0.0, 0.0, 0.005), 1.0, 0.1)]
    if not quick:
        moves += [Move("last", (-0.12, 0.0, 0.0), 1.5, 2.0), Move("first", (0.0, 0.0, 0.15), 4.0, 1.5),
                  Move("last", (0.0, 0.0, 0.15), 4.0, 1.5)]
    return tuple(moves)


def frame_times(robot: str, frames: int, size=(640, 480)) -> dict:
    """Median, min and max time [s] of one frame per renderer setting, interleaved; and the conditions."""
    scenes, notes = {}, {}
    for name in ("tiny", "egl"):
        try:
            with native_output() as said:
                scenes[name] = DualArmScene(DualArmConfig(robot=robot, cable=CABLE, renderer=name))
            notes[name] = said
        except RenderError as err:
            notes[name] = [str(err)]
    try:
        for sc in scenes.values():
            sc.grasp()
        any_scene = next(iter(scenes.values()))
        framed = framing_camera(cable_envelope(any_scene.cable.x[[0, -1]], CABLE.length, motion(False)),
                                width=size[0], height=size[1])
        wide = default_camera([(-0.6, 0.0, 0.0), (0.6, 0.0, 0.0), (0.0, 0.0, 0.6)], *size)
        settings = {"framed, tiny, shadows on": ("tiny", framed),
                    "framed, tiny, shadows off": ("tiny", replace(framed, shadows=False)),
                    "framed, egl, shadows on": ("egl", framed),
                    "wide, tiny, shadows on": ("tiny", wide), "wide, egl, shadows on": ("egl", wide)}
        settings = {k: v for k, v in settings.items() if v[0] in scenes}
        tubes = {name: CableTube(sc.cable) for name, sc in scenes.items()}
        times = {k: [] for k in settings}
        cpu = {k: [] for k in settings}
        for k in range(frames + 2):  # the first two of each are warm-up (EGL builds its shadow map)
            for label, (name, camera) in settings.items():
                sc = scenes[name]
                tic, cpu_tic = time.perf_counter(), time.process_time()
                render_frame(sc.world.client, camera, sc.world.renderer, tubes[name].mass_of_body())
                if k >= 2:
                    times[label].append(time.perf_counter() - tic)
                    cpu[label].append(time.process_time() - cpu_tic)
        gl = re.search(r"GL_RENDERER=(.*)", "".join(notes.get("egl", [""])))
        return {
            "resolution": f"{size[0]}x{size[1]}", "frames": frames, "cores": os.cpu_count(),
            "load_average_1min": os.getloadavg()[0],
            "scene": f"floor, table, two {robot} arms, the cable as {CABLE.n_masses} spheres + "
                     f"{CABLE.n_masses - 1} tube segments; framed: the camera the video uses, wide: the whole "
                     "scene from 1.7 m",
            "per_frame": "one getCameraImage: RGB + depth + segmentation (object and link index)",
            "gl_renderer": gl.group(1).strip() if gl else "EGL unavailable: " + " ".join(notes.get("egl", [])),
            "egl_shadows": "always on (the EGL renderer ignores the shadow flag)",
            "median_ms": {k: 1000 * statistics.median(v) for k, v in times.items()},
            "median_cpu_ms": {k: 1000 * statistics.median(v) for k, v in cpu.items()},
            "min_ms": {k: 1000 * min(v) for k, v in times.items()},
            "max_ms": {k: 1000 * max(v) for k, v in times.items()},
        }
    finally:
        for sc in scenes.values():
            sc.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join("out", "render_demo"), help="output folder")
    parser.add_argument("--robot", default="panda", help="robot holding the cable (kuka, panda)")
    parser.add_argument("--frames", type=int, default=30, help="timed frames per renderer setting (median)")
    parser.add_argument("--quick", action="store_true", help="a 1 s clip at 160x120 and 3 timed frames (smoke test)")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    scene = Scene(cable=CABLE, motion=motion(args.quick), dt=1 / 240, duration=1.5 if args.quick else 6.0,
                  name="Lv cable held by two Pandas")
    size = (160, 120) if args.quick else (640, 480)
    summary = render_scene(scene, out, robot=args.robot, width=size[0], height=size[1], phases=PHASES,
                           still_time=None if args.quick else 3.6)
    print(f"video: {summary['side_by_side']} ({summary['codec']}, {summary['frames']} frames, "
          f"{summary.get('bytes_per_second', 0) / 1000:.0f} kB per second of video); renderer {summary['renderer']}")
    timing = frame_times(args.robot, 3 if args.quick else args.frames)
    print(f"\nframe time, {timing['resolution']}, {timing['per_frame']}")
    print(f"  scene: {timing['scene']}")
    print(f"  GL renderer: {timing['gl_renderer']}; {timing['cores']} cores, load average {timing['load_average_1min']:.1f}; "
          f"median of {timing['frames']} interleaved frames (after 2 warm-up frames); EGL {timing['egl_shadows']}")
    for label, median in timing["median_ms"].items():
        print(f"  {label:26s} {median:6.1f} ms wall, {timing['median_cpu_ms'][label]:6.1f} ms CPU  "
              f"(wall min {timing['min_ms'][label]:.1f}, max {timing['max_ms'][label]:.1f})")
    (out / "frame_times.json").write_text(json.dumps(timing, indent=2))
    print(f"\noutputs written to {out.resolve()}")


if __name__ == "__main__":
    main()
