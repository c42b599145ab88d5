"""One call from a scene file to a folder of video and plots (``bullet-dlo render``)."""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from bullet_dlo.render.camera import CableTube, Camera, default_camera
from bullet_dlo.render.video import Recorder, VideoWriter, plot_wrenches, probe_video, side_by_side


def render_scene(scene, out: str | Path, *, robot: str | None = None, fps: float = 30.0, width: int = 640,
                 height: int = 480, renderer: str = "auto", fmt: str = "auto", camera: Camera | None = None,
                 progress: bool = True) -> dict:
    """Run ``scene`` in Bullet (with two arms holding the cable when ``robot`` is given) and
    write ``scene.<mp4|webm>``, ``forces.png``, ``side_by_side.<ext>``, ``still.png`` and
    ``render.json`` into ``out``. Returns the summary (renderer, codec, frame time, sizes).
    """
    import cv2

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if robot:
        from bullet_dlo.robots.dual_arm import DualArmConfig, DualArmScene

        arm_scene = DualArmScene(DualArmConfig(robot=robot, cable=scene.cable, dt=scene.dt,
                                               integrator=scene.integrator, renderer=renderer))
        arm_scene.grasp()
        for m in scene.motion:
            arm_scene.move("left" if m.end == "first" else "right", m.displacement, m.duration, start=m.start)
        world, cable = arm_scene.world, arm_scene.cable
    else:
        from bullet_dlo.bullet.world import build_world

        arm_scene = None
        world = build_world(scene, renderer=renderer)
        model = scene.build_model()
        cable = world.add_cable(model, integrator=scene.integrator, state=scene.initial_state(model),
                                substeps=scene.bullet.substeps, self_collision=scene.bullet.self_collision)
    try:
        frame_points = np.vstack([cable.x] + ([[(-0.6, 0.0, 0.0), (0.6, 0.0, 0.0), (0.0, 0.0, 0.6)]] if robot else []))
        cam = camera or default_camera(frame_points, width, height)
        rend = world.renderer
        tube = CableTube(cable)
        writer = VideoWriter(out / "scene", fps, fmt)
        n_frames = int(np.floor(scene.duration * fps + 1e-9)) + 1
        bar = tqdm(total=n_frames, desc="rendering", unit="frame", disable=not progress)
        rec = Recorder(world, cam, rend, fps, writer, tube, progress=bar)
        forces, times = [], []
        world.after_step.append(rec.on_step)
        world.after_step.append(lambda: (times.append(world.time), forces.append(cable.end_forces())))
        rec.on_step()  # frame at t = 0
        tic = time.perf_counter()
        n_steps = max(1, int(round(scene.duration / scene.dt)))
        for _ in range(n_steps):
            world.step()
            if not cable.stable:
                break
        wall = time.perf_counter() - tic
        bar.close()
        writer.close()
        cv2.imwrite(str(out / "still.png"), rec.last.rgb[:, :, ::-1])  # the last frame
        t = np.array(times)
        sensor = None
        if arm_scene is not None:
            r = arm_scene.record.arrays()
            sensor = r["wrench_world"]
        plot = plot_wrenches(t, sensor, np.array(forces), out / "forces.png",
                             title=f"{scene.name}: " + ("wrist sensors vs model" if sensor is not None
                                                        else "force on the held ends (model)"))
        summary = {"renderer": rend.name, "renderer_note": rend.note, "frames": writer.frames,
                   "video": str(writer.path), "format": writer.format, "codec": writer.codec,
                   "fps": fps, "width": cam.width, "height": cam.height, "wall_time_s": wall,
                   "stable": bool(cable.stable)}
        if writer.format != "png":
            info = probe_video(writer.path)
            summary["decoded"] = info
            summary["bytes_per_second"] = writer.path.stat().st_size / max(scene.duration, 1e-9)
            sbs = side_by_side(writer.path, plot, np.array(rec.times), out / "side_by_side", fps)
            summary["side_by_side"] = str(sbs.path)
        (out / "render.json").write_text(json.dumps(summary, indent=2))
        return summary
    finally:
        if arm_scene is not None:
            arm_scene.close()
        else:
            world.close()
