"""One call from a scene to a folder of video and plots (``bullet-dlo render``)."""
from __future__ import annotations

import json
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Sequence

import numpy as np
from tqdm import tqdm

from bullet_dlo.config.robot import ArmsOptions
from bullet_dlo.core.boundary import motion_offset
from bullet_dlo.render.camera import Camera, framing_camera
from bullet_dlo.render.plots import plot_wrenches
from bullet_dlo.render.tube import CableTube
from bullet_dlo.render.video import Recorder, VideoWriter, probe_video, side_by_side
from bullet_dlo.sim import build, engine_for

GRIPPER_HEIGHT = 0.08  # [m] of gripper shown above a held cable end


def _sample_times(motion: Sequence, step: float = 0.05) -> np.ndarray:
    """Times [s] at which to sample ``motion`` (Move, Waypoints, Sine items): every ``step`` over its span
    and every item's start and end; an endless sine is sampled over one period after its start."""
    marks = [0.0]
    for m in motion:
        duration = m.duration if m.duration is not None and np.isfinite(m.duration) else 1.0 / m.frequency
        marks += [m.start, m.start + duration]
    return np.unique(np.r_[np.arange(0.0, max(marks), step), marks])


def cable_envelope(ends: np.ndarray, length: float, motion: Sequence, free: Sequence[bool] = (False, False),
                   ground: float = 0.0) -> np.ndarray:
    """Points (k, 3) [m] that bound where a cable of ``length`` goes while its ends follow ``motion``.

    ends: the two end positions at t = 0, (2, 3); motion: Move, Waypoints or Sine items of
    :mod:`bullet_dlo.core.boundary`. Every 50 ms and at every item's start and end the two held
    ends are taken, and below their midpoint
    the lowest point an inextensible cable between them can reach (half of sqrt(L^2 - s^2) for
    ends s apart); a ``free`` end may swing anywhere within ``length`` of the other end, above
    ``ground`` [m].
    """
    ends = np.asarray(ends, float)
    motion = tuple(motion)
    times = _sample_times(motion)
    shift = [motion_offset(motion, end, times)[0] for end in ("first", "last")]  # (k, 3) each
    points = []
    for k in range(len(times)):
        now = ends + np.stack([shift[0][k], shift[1][k]])
        span = float(np.linalg.norm(now[1] - now[0]))
        sag = 0.5 * np.sqrt(max(length**2 - span**2, 0.0))
        points += [now[0], now[1], 0.5 * (now[0] + now[1]) - (0.0, 0.0, sag)]
        for k, is_free in enumerate(free):
            if is_free:
                anchor = now[1 - k]
                points += [anchor + d for d in length * np.vstack([np.eye(3), -np.eye(3)])]
    pts = np.array(points)
    pts[:, 2] = np.maximum(pts[:, 2], ground)
    return pts


RUN_FILE = "run.npz"
"""The run a render writes beside its video, at the video's rate (``bullet-dlo view OUT`` shows it)."""


class _CableSeries:
    """An ``after_step`` hook: the cable's time [s], nodes [m] and end forces [N] every ``every`` steps."""

    def __init__(self, world, cable, every: int):
        self.world, self.cable, self.every = world, cable, every
        self.rows: dict[str, list] = {"t": [], "cable_x": [], "end_forces": []}

    def __call__(self) -> None:
        if self.world.steps % self.every:
            return
        self.rows["t"].append(self.world.time)
        self.rows["cable_x"].append(self.cable.x.copy())
        self.rows["end_forces"].append(self.cable.end_forces())

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.array(v) for k, v in self.rows.items()}


def _write_run(path: Path, series, scene, robot: str | None) -> None:
    """The recorded rows as one .npz (the series format of :mod:`bullet_dlo.data.recording`)."""
    from bullet_dlo.robots.dual_arm.series import save_npz

    attrs = {"cable": scene.cable.to_dict(), "dt": scene.dt, "name": scene.name}
    if robot is not None:
        attrs["robot"] = robot
    save_npz(path, series.arrays(), attrs)


def render_scene(scene, out: str | Path, *, robot: str | None = None, fps: float = 30.0, width: int = 640,
                 height: int = 480, renderer: str = "auto", fmt: str = "auto", camera: Camera | None = None,
                 arm_options: dict | None = None, phases: Sequence[tuple[float, float, str]] = (),
                 still_time: float | None = None, progress: bool = True, on_arm_scene=None) -> dict:
    """Run ``scene`` in Bullet and film it; write ``scene.<mp4|webm>``, ``forces.png``,
    ``side_by_side.<ext>``, ``still.png`` and ``render.json`` into ``out``.

    robot: two arms of this kind hold the cable ends (the scene's first end is the left arm's)
    and the plot shows their wrist sensors (a scene whose ``arms:`` names a robot needs none);
    arm_options: :class:`~bullet_dlo.config.robot.ArmsOptions` fields replacing the scene's (e.g.
    ``hold_height``); the runtime comes from :func:`bullet_dlo.sim.build`; camera: default frames the cable's whole motion (see
    :func:`cable_envelope`); phases: (start [s], end [s], label) spans marked on the force plot;
    still_time: time [s] of the frame saved as ``still.png`` (default: the last frame);
    progress: a frame counter with ETA on stderr; on_arm_scene: called with the dual-arm scene once it
    is built, before it runs (e.g. to attach a time-series recorder). Returns the summary (renderer, codec,
    frames, wall time, sizes).
    """
    import cv2

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if arm_options:
        scene = replace(scene, arms=replace(scene.arms or ArmsOptions(), **arm_options))
    engine = engine_for(scene, robot)
    sim = build(scene, engine, robot=robot, renderer=renderer,
                command="render --robot" if engine == "arms" else "render")
    scene = sim.scene  # n_masses: auto and dt: auto resolved
    world, cable = sim.world, sim.cable
    arm_scene = sim.arms if engine == "arms" else None
    free = (False, False) if arm_scene is not None else tuple(mode == "free" for mode in scene.ends)
    if arm_scene is not None and on_arm_scene is not None:
        on_arm_scene(arm_scene)
    writer = bar = None
    try:
        ground = world.ground_height if world.ground_id is not None else -np.inf
        envelope = cable_envelope(cable.x[[0, -1]], scene.cable.length, scene.motion, free, ground)
        if arm_scene is not None:  # the fingers above each held end stay in the picture too
            envelope = np.vstack([envelope, envelope + (0.0, 0.0, GRIPPER_HEIGHT)])
        cam = camera or framing_camera(envelope, width=width, height=height)
        tube = CableTube(cable)
        writer = VideoWriter(out / "scene", fps, fmt)
        n_frames = int(np.floor(scene.duration * fps + 1e-9)) + 1
        bar = tqdm(total=n_frames, desc="rendering", unit="frame", disable=not progress)
        rec = Recorder(world, cam, world.renderer, fps, writer, tube, progress=bar)
        forces, times, still = [], [], []

        def after_step() -> None:
            rec.on_step()
            times.append(world.time)
            forces.append(cable.end_forces())
            if not still and still_time is not None and rec.times[-1] >= still_time - 1e-9:
                still.append(rec.last.rgb)

        world.after_step.append(after_step)
        # the run at the video's rate, for `bullet-dlo view OUT` (the whole run, not only its last shape)
        every = max(1, int(round(1.0 / (fps * world.dt))))
        if arm_scene is not None:
            from bullet_dlo.robots.dual_arm.series import SeriesRecorder

            series = SeriesRecorder(arm_scene, every)
        else:
            series = _CableSeries(world, cable, every)
            series()  # the row at t = 0 (the wrist sensors have no reading before the first step)
        world.after_step.append(series)
        rec.on_step()  # frame at t = 0
        wall = world.run_while_stable(world.steps_in(scene.duration), cable)
        bar.close()
        writer.close()
        cv2.imwrite(str(out / "still.png"), (still[0] if still else rec.last.rgb)[:, :, ::-1])
        sensor = arm_scene.record.arrays()["wrench_world"] if arm_scene is not None else None
        title = f"{scene.name}: " + ("wrist sensors vs model" if sensor is not None else "force on the held ends")
        plot = plot_wrenches(np.array(times), sensor, np.array(forces), out / "forces.png", title=title, phases=phases)
        summary = {"renderer": world.renderer.name, "renderer_note": world.renderer.note, "frames": writer.frames,
                   "video": str(writer.path), "format": writer.format, "codec": writer.codec,
                   "fps": fps, "width": cam.width, "height": cam.height, "wall_time_s": wall,
                   "stable": bool(cable.stable), "final_positions": cable.x.tolist()}
        if arm_scene is not None:  # every wrist sample against the cable's load in the same step
            summary["sensor_check"] = arm_scene.observation.check.summary()
            for line in summary["sensor_check"]["failures"]:
                warnings.warn(f"wrist sensor check: {line}", stacklevel=2)
        if writer.format != "png":
            summary["decoded"] = probe_video(writer.path)
            summary["bytes_per_second"] = writer.path.stat().st_size / max(scene.duration, 1e-9)
            sbs = side_by_side(writer.path, plot, np.array(rec.times), out / "side_by_side", fps)
            summary["side_by_side"] = str(sbs.path)
        _write_run(out / RUN_FILE, series, scene, robot if arm_scene is not None else None)
        summary["run"] = str(out / RUN_FILE)
        (out / "render.json").write_text(json.dumps(summary, indent=2))
        return summary
    except BaseException:
        if bar is not None:
            bar.close()  # before the caller's message, so that it gets a line of its own
        if writer is not None:
            writer.abort()  # a Ctrl-C leaves no partial video under the final name
        raise
    finally:
        sim.close()
