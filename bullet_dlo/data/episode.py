"""Running one episode: the dual-arm scene with the planned parameters, recorded and stored.

The scene is :class:`bullet_dlo.robots.dual_arm.DualArmScene`: both grippers grasp the cable
(clamped, or pinched by a friction grip: the spec's ``grip`` parameters), follow the episode's
motion (the drawn ``motion:`` entries, else the right gripper's straight move; stored in the
``params`` attribute) and the episode runs for the spec's duration (stopped early, and flagged,
if the cable goes unstable). Every ``1 / record_rate`` seconds a
row of the columns below is recorded; frames come from :func:`bullet_dlo.render.camera.render_frame`
at the spec's camera rate. Left arm = the cable's first end, right arm = its last end; k rows,
n masses, j arm joints:

=============== ================================================================ ============
column          meaning                                                          shape
=============== ================================================================ ============
t               time [s]                                                         (k,)
cable_x/v       mass positions [m] / velocities [m/s]                            (k, n, 3)
wrench_world    tared wrist load on the tool, world frame [N, N m]               (k, 2, 6)
wrench_sensor   the same in the sensor frame                                     (k, 2, 6)
wrench_raw      PyBullet's joint reaction at the sensor joint                    (k, 2, 6)
end_forces      force of the cable model on each holder [N]                      (k, 2, 3)
end_moments     clamp torque of the cable model on each holder [N m]             (k, 2, 3)
joint_q/qd/tau  arm joint angles [rad], velocities [rad/s], motor torques [N m]   (k, 2, j)
ee_pos/quat     grasp-frame position [m] and quaternion (x, y, z, w)             (k, 2, 3/4)
=============== ================================================================ ============
"""
from __future__ import annotations

import traceback
from typing import Any

import numpy as np
import pybullet as pb

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.config.robot import ArmsOptions
from bullet_dlo.config.scene import Scene
from bullet_dlo.config.world import BulletOptions
from bullet_dlo.core.model import STANDARD_GRAVITY
from bullet_dlo.data.plan import cable_spec, current_names, episode_motion, plan_episode
from bullet_dlo.data.quality import quality_issues, quality_metrics, sensor_metrics
from bullet_dlo.data.storage import (
    episode_name,
    episode_result,
    failed_record,
    status_attrs,
    version,
    write_episode,
)
from bullet_dlo.data.safeio import StorageError
from bullet_dlo.render.camera import default_camera, render_frame
from bullet_dlo.robots.arm import Robot
from bullet_dlo.robots.dual_arm import DualArmScene
from bullet_dlo.robots.sensors import WristSensor
from bullet_dlo.sim import build_arms

COLUMNS = ("t", "cable_x", "cable_v", "wrench_world", "wrench_sensor", "wrench_raw", "end_forces", "end_moments",
           "joint_q", "joint_qd", "joint_tau", "ee_pos", "ee_quat")
COLUMNS_NOTE = ("left arm = cable first end, right arm = last end; wrench rows [fx fy fz mx my mz]; "
                "wrench_world/sensor: tared load on the tool; wrench_raw: PyBullet joint reaction")
CAMERA_VIEW = [(-0.6, 0, 0), (0.6, 0, 0), (0, 0, 0.6)]  # points [m] the camera frames: both arms, above the cable


class EpisodeRecorder:
    """An ``after_step`` hook of the scene's world: a row every ``every`` steps, frames at ``fps`` [Hz]."""

    def __init__(self, scene: DualArmScene, every: int, spec: CaptureSpec):
        self.scene = scene
        self.every = every
        self.rows: dict[str, list] = {k: [] for k in COLUMNS}
        self.fps = spec.camera_fps
        self.camera = default_camera(CAMERA_VIEW, spec.camera_width, spec.camera_height)
        self.frames: list[np.ndarray] = []
        self.frame_t: list[float] = []
        self._next_frame = 0.0  # [s]

    def __call__(self) -> None:
        world = self.scene.world
        if world.steps % self.every == 0:
            self.record_row()
        if self.fps > 0 and world.time + 1e-12 >= self._next_frame:
            self.frames.append(render_frame(world.client, self.camera, world.renderer).rgb)
            self.frame_t.append(world.time)
            self._next_frame += 1.0 / self.fps

    def record_row(self) -> None:
        """Record one row of the columns now (the hook records every ``every`` steps; call it for the start)."""
        scene, rows = self.scene, self.rows
        rows["t"].append(scene.world.time)
        rows["cable_x"].append(scene.cable.x.copy())
        rows["cable_v"].append(scene.cable.v.copy())
        rows["wrench_world"].append([s.last.world() for s in scene.sensors])
        rows["wrench_sensor"].append([s.last.sensor() for s in scene.sensors])
        rows["wrench_raw"].append([s.raw() for s in scene.sensors])
        rows["end_forces"].append(scene.cable.end_forces())
        rows["end_moments"].append(scene.cable.end_moments())
        joints = [joint_state(r) for r in scene.robots]
        for i, key in enumerate(("joint_q", "joint_qd", "joint_tau")):
            rows[key].append([j[i] for j in joints])
        poses = [r.grasp_pose() for r in scene.robots]
        rows["ee_pos"].append([p for p, _ in poses])
        rows["ee_quat"].append([q for _, q in poses])

    def arrays(self) -> dict[str, np.ndarray]:
        """The recorded columns as float arrays (see module doc for shapes)."""
        return {k: np.asarray(v, dtype=float) for k, v in self.rows.items()}


def joint_state(robot: Robot) -> tuple[list[float], list[float], list[float]]:
    """Arm joint angles [rad], velocities [rad/s] and applied motor torques [N m], each of length j."""
    states = pb.getJointStates(robot.body, robot.arm_joints, physicsClientId=robot.client)
    return [s[0] for s in states], [s[1] for s in states], [s[3] for s in states]


def episode_scene(spec: CaptureSpec, params: dict[str, Any], decision: dict[str, Any]) -> Scene:
    """The scene of a planned episode: its cable, step, integrator and substeps (the stability decision),
    the arms' layout, grip and wrist sensors, the motion and the spec's duration (parameters of older
    episodes without the grip ones: a clamp)."""
    params = current_names(params)
    grip = {k: params[k] for k in ("grip", "grip_force", "grip_static_friction", "grip_dynamic_friction",
                                   "grip_reach") if k in params}
    arms = ArmsOptions(robot=params["robot"], hold_height=params["hold_height"],
                       sensor_rate=params["sensor_rate"] or None, noise_std=(params["noise_std"],) * 3 + (0.0,) * 3,
                       seed=params["noise_seed"], **grip)
    return Scene(cable=cable_spec(params), motion=episode_motion(params), integrator=params["integrator"],
                 dt=params["dt"], duration=spec.duration, name=f"episode (seed {spec.seed})",
                 bullet=BulletOptions(substeps=decision["substeps"]), arms=arms)


def run_episode(spec_dict: dict, index: int, out_dir: str) -> dict:
    """Plan, simulate and store episode ``index`` of the spec; returns its manifest record.

    Runs in a worker process: the spec comes as its dict form, the result goes to ``out_dir``.
    """
    spec = CaptureSpec.from_dict(spec_dict)
    params, decision = plan_episode(spec, index)
    scene_ = episode_scene(spec, params, decision)
    with build_arms(scene_, renderer="tiny" if spec.camera_fps > 0 else None, record=False) as sim:
        scene = sim.arms
        recorder = EpisodeRecorder(scene, max(1, int(round(1.0 / (spec.record_rate * scene_.dt)))), spec)
        sim.after_step.append(recorder)
        sim.run()
        stable, t_bad, reason = scene.cable.stable, scene.cable.time_to_instability, scene.cable.reason
        check = scene.observation.check
        compensation = scene.sensors[0].compensation
    data = recorder.arrays()
    metrics = quality_metrics(data["t"], data["wrench_world"][:, :, :3], data["end_forces"]) | sensor_metrics(check)
    attrs = {"params": params, "decision": decision, "metrics": metrics, "seed": spec.seed, "episode": index,
             "version": version(), "sensor_compensation": compensation,
             "sensor_transmitted": WristSensor.TRANSMITTED, "spec_digest": spec.digest(),
             "stable": bool(stable),
             "time_to_instability": -1.0 if t_bad is None else float(t_bad), "columns": COLUMNS_NOTE}
    weight = scene_.cable.mass * float(np.linalg.norm(STANDARD_GRAVITY))
    issues = (quality_issues(metrics, weight, spec.max_sensor_model_rms, spec.max_hf_energy) + check.failures()
              if stable else [])
    record = episode_result(index, episode_name(index), stable, t_bad, reason, params, decision, metrics, issues)
    attrs |= status_attrs(record)  # the file rebuilds this record, flags and all, if the manifest line is lost
    frames = np.asarray(recorder.frames, dtype=np.uint8) if recorder.frames else None
    write_episode(out_dir, index, data, attrs, frames, np.asarray(recorder.frame_t))
    return record


def run_episode_safely(spec_dict: dict, index: int, out_dir: str) -> dict:
    """:func:`run_episode` with an exception turned into a failed record (the worker survives)."""
    try:
        return run_episode(spec_dict, index, out_dir)
    except StorageError as err:  # the directory, not the episode: the coordinator stops, nothing recorded
        return failed_record(index, str(err), write_error=True, path=str(err.path), cause=err.cause)
    except Exception as err:  # noqa: BLE001 - recorded, not swallowed
        return failed_record(index, f"{type(err).__name__}: {err}", traceback=traceback.format_exc(limit=3))
