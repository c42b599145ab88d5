"""The common part of the dual-arm environments: two arms holding a cable, driven by gripper velocities.

Every reset draws a scene (:class:`~.randomisation.EnvRandomisation`), builds it
(:class:`~bullet_dlo.robots.dual_arm.DualArmPhysics` and its wrist sensors), clamps both cable
ends, lets the cable settle for ``settle_time`` and asks the task (a subclass) for its targets.

**Action** (6,) in [-1, 1]: the grippers' linear velocities (left xyz, right xyz) as fractions of
``max_speed`` [m/s], world frame; clipped (a task may define its own: :meth:`DualArmEnv._action_space`,
:meth:`DualArmEnv._apply_action`). The gripper targets integrate them over the control
period, stay inside a box of half-width ``workspace`` [m] around the grasp poses after reset, keep
their orientation, and become joint targets by one IK solve per arm per control step (the arms'
position control follows). A target stays where its arm can follow: an action that takes it beyond
the arm's reach (the IK misses it by more than 1 mm: out of the workspace, a joint at its limit)
leaves that arm's target and joint targets as they were, and so does one that takes it more than
:meth:`DualArmEnv.lag_limit` from a grasp frame that does not follow (blocked by an obstacle, the
table or the other arm) and farther than it was: reversing acts at once, with no wind-up hidden
from the observation. ``info["gripper_lag"]`` (2,) [m]: each grasp frame's distance from its target.
``control_dt`` [s] must be a whole multiple of the physics step (ParameterError otherwise), checked at
construction for every dt the randomisation can draw.

**Observation** (a Dict, float32 unless said; arms in the order left, right; j arm joints):

============ ================================================================== ==============
key          meaning                                                            shape
============ ================================================================== ==============
joint_q      arm joint angles [rad]                                             (2, j)
joint_qd     arm joint velocities [rad/s]                                       (2, j)
gripper_pos  grasp-frame positions [m]                                          (2, 3)
gripper_quat grasp-frame quaternions (x, y, z, w)                               (2, 4)
wrench       wrist F/T readings as the sensors report them (their rate, noise,  (2, 6)
             bias): load on the tool [N, N m], world frame
task         the task's targets and measures (see the subclass)                 (task_dim,)
cable        privileged: ``shape_points`` points along the cable [m]            (shape_points, 3)
             (``privileged=True``)
rgb / depth  camera image uint8 / depth [m] (``camera="rgb" | "depth" |         (H, W, 3) / (H, W, 1)
             "rgbd"``), rendered through :func:`bullet_dlo.render.camera.render_frame`
============ ================================================================== ==============

Every value is finite and inside its box: a non-finite reading (an unstable step) is replaced by
0 and ends the episode. **Termination**: the cable went unstable (``info["unstable"]``, with
``info["reason"]``), or the task's own condition; the time limit is the registration's
``max_episode_steps`` (a truncation). **Rendering**: ``render_mode="rgb_array"`` returns the
``render_size`` view of :meth:`render`; ``render_mode="human"`` opens a live browser view on the
loopback (its URL printed once; the cable, the arms, obstacles and wrist-force arrows as Bullet has
them after every reset and step; needs viser, ``pip install 'bullet-dlo[view]'``).

**Vectorising** (Gymnasium 1.x): ``metadata["autoreset_mode"]`` is ``AutoresetMode.NEXT_STEP``, the
mode ``gymnasium.make_vec`` (``vectorization_mode="sync"`` or ``"async"``) gives its vector env by
default: the step after a sub-environment's episode ends ignores its action, resets it (unseeded:
its generator continues from the seeded reset) and returns the new episode's first observation with
reward 0 and both flags false. ``SAME_STEP`` and ``DISABLED`` (``vector_kwargs={"autoreset_mode": ...}``)
work as well: a reset rebuilds the scene from the generator only, nothing of the ended episode stays.
"""
from __future__ import annotations

from typing import Any, Mapping

import gymnasium as gym
import numpy as np
import pybullet as pb
from gymnasium import spaces

try:  # np.clip's ufunc without its Python wrapper (the same bits; NumPy 1.x names its module numpy.core)
    from numpy._core.umath import clip as _clip
except ImportError:  # pragma: no cover - NumPy 1.x
    from numpy.core.umath import clip as _clip

try:  # Gymnasium >= 1.1 names the vector autoreset modes; 1.0 vectorises in next-step order without a name
    from gymnasium.vector import AutoresetMode
    AUTORESET = {"autoreset_mode": AutoresetMode.NEXT_STEP}
except ImportError:  # pragma: no cover - Gymnasium 1.0
    AUTORESET = {}

from bullet_dlo.config.robot import load_robot_spec
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.envs import params
from bullet_dlo.envs.randomisation import EnvRandomisation, RandomisationLike, check_control_period
from bullet_dlo.render.camera import default_camera, render_frame
from bullet_dlo.robots.dual_arm import DualArmPhysics
from bullet_dlo.robots.dual_arm.task import POSE_MISS
from bullet_dlo.robots.kernels import FRAME, FRAME_QUAT
from bullet_dlo.sim import build_arms

CAMERA_VIEW = [(-0.45, 0.0, 0.2), (0.45, 0.0, 0.2), (0.0, 0.0, 0.5)]  # points [m] the cameras frame
BOUNDS = {"joint_q": 2 * np.pi, "joint_qd": 50.0, "gripper_pos": 3.0, "gripper_quat": 1.0, "wrench": 500.0,
          "cable": 3.0, "depth": 10.0}
"""Half-width of each observation box (values are clipped into it)."""


class DualArmEnv(gym.Env):
    """Two arms holding a cable; subclasses set the task (:meth:`_task_reset`, :meth:`_task_observation`,
    :meth:`_task_reward`, ``task_dim``, ``default_randomisation``).

    Args (every one checked at construction, before anything is built, by :mod:`~.params`: a bad value raises
    ParameterError naming it and its range; numbers must be real numbers, flags real bools):
        randomisation: a capture spec (CaptureSpec, dict or YAML path) whose distributions are
            re-drawn at every reset; None: the task's ``default_randomisation``. Its errors are
            prefixed ``randomisation:``.
        control_dt: control period [s] in (0, 1], a whole multiple of the physics step and at most
            10 000 of them (checked for every dt the randomisation can draw, and at reset).
        max_speed: gripper speed [m/s] of a full action, in (0, 2].
        workspace: half-width [m] of the box the gripper targets stay in, around the reset grasp poses, in (0, 2].
        settle_time: time [s] the clamped cable settles (actions held at zero) before the episode starts,
            in [0, 10] and at most 100 000 physics steps (0: one step).
        privileged: (bool) add the cable's shape (``cable``) to the observation.
        shape_points: points along the cable in ``cable`` (and in shape targets), an integer in [2, 1000].
        camera: None, "rgb", "depth" or "rgbd": camera images in the observation, ``image_size`` (width, height)
            [px], integers in [16, 4096].
        render_mode: None, "rgb_array" or "human" (a live browser view; needs viser); render_size: (width, height) [px] of :meth:`render`, integers in [16, 4096].

    ``reset(seed=..., options=...)``: seed None or an integer >= 0; options None or {} (no reset options).
    """

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 20, **AUTORESET}
    task_dim = 0
    default_randomisation: Mapping[str, Any] = {}

    def __init__(self, randomisation: RandomisationLike = None, control_dt: float = 0.05, max_speed: float = 0.05,
                 workspace: float = 0.1, settle_time: float = 0.25, privileged: bool = False, shape_points: int = 10,
                 camera: str | None = None, image_size: tuple[int, int] = (64, 64), render_mode: str | None = None,
                 render_size: tuple[int, int] = (320, 240)):
        self.control_dt = params.number("control_dt", control_dt)
        self.max_speed = params.number("max_speed", max_speed)
        self.workspace = params.number("workspace", workspace)
        self.settle_time = params.number("settle_time", settle_time)
        self.privileged = params.flag("privileged", privileged)
        self.shape_points = params.shape_points(shape_points)
        self.camera = params.choice("camera", camera, params.CAMERAS)
        self.image_size = params.size("image_size", image_size)
        self.render_mode = params.choice("render_mode", render_mode, params.RENDER_MODES)
        self.render_size = params.size("render_size", render_size)
        self.randomisation = EnvRandomisation(randomisation, self.default_randomisation)
        for dt in self.randomisation.values("dt"):  # refuse a control period the physics cannot hit, now
            check_control_period(self.control_dt, float(dt))
            params.check_work(self.control_dt, self.settle_time, float(dt))
        self.n_joints = self._joint_count()
        self.action_space = self._action_space()
        self.observation_space = spaces.Dict(self._observation_boxes())
        self.physics: DualArmPhysics | None = None
        self._sim = None
        self.sensors = None
        self.observation = None
        self.draw = None
        self._live = None  # render_mode="human": the browser view, and the world it draws
        self._live_world = None

    # ----- spaces ---------------------------------------------------------------------------------
    def _action_space(self) -> spaces.Box:
        """Both grippers' velocities (left xyz, right xyz) as fractions of ``max_speed``."""
        return spaces.Box(-1.0, 1.0, (6,), np.float32)

    def _apply_action(self, a: np.ndarray) -> None:
        """Move the gripper targets ``self.target`` (2, 3) [m] (and orientations ``self._quat``) by the clipped
        action ``a`` over one control period."""
        self.target = _clip(self.target + a.reshape(2, 3) * self.max_speed * self.control_dt,
                            self.home - self.workspace, self.home + self.workspace)

    def lag_limit(self) -> float:
        """Largest distance [m] an action may put a gripper target from its grasp frame: the run-time pose
        check's 2 cm (:data:`~bullet_dlo.robots.dual_arm.task.POSE_MISS`) plus two control periods at
        ``max_speed`` (the lag of an arm that follows)."""
        return POSE_MISS + 2.0 * self.max_speed * self.control_dt

    def _grasp_positions(self) -> np.ndarray:
        """The grasp frames' positions (2, 3) [m] as the coupling read them after the last physics step."""
        return self.physics.reader.link_rows[:, 0, FRAME:FRAME + 3]

    def _hold_unfollowed(self, before: np.ndarray) -> None:
        """Put back an arm's target ``before`` (its value before the action) where the action took it beyond
        :meth:`lag_limit` from the grasp frame and farther than it was: the arm does not follow."""
        grasp, limit = self._grasp_positions(), self.lag_limit()
        for arm in range(2):
            gap = self.target[arm] - grasp[arm]
            if gap.dot(gap) > limit * limit:
                was = before[arm] - grasp[arm]
                if gap.dot(gap) > was.dot(was):
                    self.target[arm] = before[arm]

    def _joint_count(self) -> int:
        robots = self.randomisation.values("robot")
        counts = {len(load_robot_spec(name).home) for name in robots}
        if len(counts) != 1:
            raise ParameterError(f"sample.robot: the robots drawn must have one joint count, got {sorted(counts)}")
        return counts.pop()

    def _observation_boxes(self) -> dict[str, spaces.Space]:
        def box(key: str, shape: tuple[int, ...], bound: float | None = None) -> spaces.Box:
            b = BOUNDS[key] if bound is None else bound
            return spaces.Box(-b, b, shape, np.float32)

        j = self.n_joints
        out = {"joint_q": box("joint_q", (2, j)), "joint_qd": box("joint_qd", (2, j)),
               "gripper_pos": box("gripper_pos", (2, 3)), "gripper_quat": box("gripper_quat", (2, 4)),
               "wrench": box("wrench", (2, 6)), "task": box("task", (self.task_dim,), 1e3)}
        if self.privileged:
            out["cable"] = box("cable", (self.shape_points, 3))
        w, h = self.image_size
        if self.camera in ("rgb", "rgbd"):
            out["rgb"] = spaces.Box(0, 255, (h, w, 3), np.uint8)
        if self.camera in ("depth", "rgbd"):
            out["depth"] = spaces.Box(0.0, BOUNDS["depth"], (h, w, 1), np.float32)
        return out

    # ----- episode --------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        seed = params.check_reset(seed, options)
        super().reset(seed=seed)
        self._close_scene()
        renderer = "tiny" if (self.camera or self.render_mode == "rgb_array") else None
        self.draw = self.randomisation.draw(self.np_random, renderer)
        setup = self.draw.setup
        self.substeps = check_control_period(self.control_dt, setup.dt)
        settle_steps = params.check_work(self.control_dt, self.settle_time, setup.dt)[1]  # before building anything
        # grasped, no per-step record (the observation's check still compares every sample with the model)
        self._sim = build_arms(self.draw.scene, renderer=renderer, record=False)
        self.physics = self._sim.physics
        self.observation = self._sim.observation
        self.sensors = self.observation.sensors
        robots = self.physics.robots
        self._quat = [q for _, q in self.physics.grasp_poses]
        self._q_target = [r.joint_positions() for r in robots]
        self.physics.world.step(settle_steps)
        self.home = np.array([r.grasp_pose()[0] for r in robots])  # (2, 3) [m] after settling
        self.target = self.home.copy()
        self.unstable = not self.physics.cable.stable
        self._task_reset(self.np_random)
        self._cameras = None
        obs, info = self._observation(), self._info()
        if self.render_mode == "human":
            self._render_human()
        return obs, info

    def step(self, action):
        if self.physics is None:
            raise RuntimeError("call reset() before step()")
        before, quat_before = self.target.copy(), list(self._quat)
        self._apply_action(self._clean_action(action))
        self._hold_unfollowed(before)
        for arm, robot in enumerate(self.physics.robots):
            q = robot.track_within(self.target[arm], self._quat[arm])
            if q is None:  # beyond reach: the target and the joint targets stay
                self.target[arm], self._quat[arm] = before[arm], quat_before[arm]
                continue
            self._q_target[arm] = q
            robot.set_targets(q)
        world, cable = self.physics.world, self.physics.cable
        for _ in range(self.substeps):
            world.step()
            if not cable.stable:
                break
        self.unstable = not cable.stable
        obs = self._observation()
        reward, done = (0.0, True) if self.unstable else self._task_reward()
        if self.render_mode == "human":
            self._render_human()
        return obs, float(reward), bool(done or self.unstable), False, self._info()

    @staticmethod
    def _clean_action(action) -> np.ndarray:
        """``action`` as a new float array clipped to [-1, 1], NaN read as 0 (what ``np.clip(np.nan_to_num(a), -1, 1)``
        gives, at a fifth of its cost: an infinity clips to +-1 as nan_to_num's largest float does)."""
        a = _clip(np.asarray(action, dtype=float), -1.0, 1.0)
        nan = np.isnan(a)
        if nan.any():
            a[nan] = 0.0
        return a

    def _info(self) -> dict[str, Any]:
        cable = self.physics.cable
        lag = self.target - self._grasp_positions()
        return {"unstable": bool(self.unstable), "reason": cable.reason if self.unstable else None,
                "time": float(self.physics.world.time), "gripper_lag": np.sqrt((lag * lag).sum(axis=1)),
                "params": dict(self.draw.params), **self._task_info()}

    # ----- observation ----------------------------------------------------------------------------
    def _observation(self) -> dict[str, np.ndarray]:
        robots = self.physics.robots
        states = [pb.getJointStates(r.body, r.arm_joints, physicsClientId=r.client) for r in robots]
        # the grasp frames as the coupling read them after the last physics step (the same bits as getLinkState)
        frames = self.physics.reader.link_rows[:, 0, FRAME:FRAME_QUAT + 4]
        raw = {"joint_q": [[s[0] for s in st] for st in states], "joint_qd": [[s[1] for s in st] for st in states],
               "gripper_pos": frames[:, :3], "gripper_quat": frames[:, 3:],
               "wrench": [s.values[6:12] for s in self.sensors], "task": self._task_observation()}
        if self.privileged:
            raw["cable"] = self.cable_points()
        # every value written as float32 (np.asarray(value, np.float32)'s bits) into one new buffer, whose boxes are
        # checked and clipped in one pass (the same elementwise clip as key by key); the keys are views of it
        layout, low, high = self._flat_layout(raw)
        flat = np.empty(len(low), np.float32)
        obs = {}
        for (key, start, stop, shape), value in zip(layout, raw.values()):
            view = obs[key] = flat[start:stop].reshape(shape)
            view[...] = value
        if not np.isfinite(flat).all():  # an unstable step: key by key, which zeroes and ends the episode
            obs = {key: self._finite(key, value) for key, value in obs.items()}
        else:
            np.clip(flat, low, high, out=flat)
        if self.camera:
            obs.update(self._images())
        return obs

    def _flat_layout(self, raw: dict) -> tuple[tuple, np.ndarray, np.ndarray]:
        """Where each key of ``raw`` lies in the flat observation buffer, in its order ((key, start, stop, shape)
        per key, the shapes of the observation space), and the boxes' low and high there as flat float32 arrays
        (made once)."""
        keys = tuple(raw)
        if getattr(self, "_layout", (None,))[0] != keys:
            space, layout, start = self.observation_space, [], 0
            for k in keys:
                shape = space[k].shape
                layout.append((k, start, start + int(np.prod(shape)), shape))
                start = layout[-1][2]
            self._layout = (keys, tuple(layout), np.concatenate([space[k].low.ravel() for k in keys]),
                            np.concatenate([space[k].high.ravel() for k in keys]))
        return self._layout[1:]

    def _finite(self, key: str, value: np.ndarray) -> np.ndarray:
        """``value`` inside its box; a non-finite entry (an unstable step) becomes 0 and ends the episode."""
        if not np.all(np.isfinite(value)):
            self.unstable = True
            value = np.nan_to_num(value, nan=0.0, posinf=0.0, neginf=0.0)
        space = self.observation_space[key]
        return np.clip(value, space.low, space.high)

    def cable_points(self, x: np.ndarray | None = None) -> np.ndarray:
        """``shape_points`` points [m] evenly spaced by node index along the cable's nodes ``x`` (n, 3)
        (default: now), linearly interpolated: a fixed-size shape whatever the number of masses."""
        x = self.physics.cable.x if x is None else x
        s = np.linspace(0.0, len(x) - 1.0, self.shape_points)
        return np.stack([np.interp(s, np.arange(len(x)), x[:, k]) for k in range(3)], axis=1)

    def _images(self) -> dict[str, np.ndarray]:
        if self._cameras is None:
            self._cameras = default_camera(CAMERA_VIEW, *self.image_size)
        world = self.physics.world
        frame = render_frame(world.client, self._cameras, world.renderer)
        out = {}
        if self.camera in ("rgb", "rgbd"):
            out["rgb"] = frame.rgb
        if self.camera in ("depth", "rgbd"):
            out["depth"] = self._finite("depth", frame.depth[:, :, None].astype(np.float32))
        return out

    def render(self) -> np.ndarray | None:
        """The scene as RGB (H, W, 3) uint8 at ``render_size`` (``render_mode="rgb_array"``); with
        ``render_mode="human"`` the live browser view is brought up to date (it also is after every reset and
        step) and None is returned; else None."""
        if self.render_mode == "human":
            self._render_human()
            return None
        if self.render_mode != "rgb_array" or self.physics is None:
            return None
        world = self.physics.world
        if getattr(self, "_render_camera", None) is None:
            self._render_camera = default_camera(CAMERA_VIEW, *self.render_size)
        return render_frame(world.client, self._render_camera, world.renderer).rgb

    def _render_human(self) -> None:
        """The live browser view (:class:`~bullet_dlo.render.viewer.LiveView`; its URL is printed once): the
        cable, the arms and every obstacle as Bullet has them, and the wrist forces as arrows (0.05 m/N)."""
        if self.physics is None:
            return
        from bullet_dlo.render.viewer import LiveView

        world, cable = self.physics.world, self.physics.cable
        if self._live is None:
            self._live = LiveView()
        if self._live_world is not world:  # a new episode's world
            skip = list(cable.body_ids) + ([world.ground_id] if getattr(world, "ground_id", None) is not None else [])
            self._live.attach(world.client, skip, cable.radius, cable.model.n)
            self._live_world = world
        ends = np.array([r.grasp_pose()[0] for r in self.physics.robots])
        forces = np.array([s.last.world()[:3] for s in self.sensors])
        self._live.update(cable.x, np.stack([ends, ends + 0.05 * forces], axis=1))

    # ----- the task (subclasses) ------------------------------------------------------------------
    def _task_reset(self, rng: np.random.Generator) -> None:
        """Draw the episode's targets (after the cable settled)."""

    def _task_observation(self) -> np.ndarray:
        return np.zeros(self.task_dim)

    def _task_reward(self) -> tuple[float, bool]:
        """Reward of the step just taken and whether the task ends the episode."""
        return 0.0, False

    def _task_info(self) -> dict[str, Any]:
        return {}

    def obstacles(self) -> list[dict]:
        """The episode's obstacles as scene ``bullet.obstacles`` entries (SI units): the drawn scene's and those
        the task adds (Routing's pegs and clip); recorded with every rollout so a viewer can draw them."""
        scene_obstacles = list(self.draw.scene.bullet.obstacles) if self.draw is not None else []
        return scene_obstacles + list(getattr(self, "task_obstacles", []))

    def scripted_policy(self):
        """The task's scripted baseline: a callable ``policy(obs) -> action``, optionally with a
        ``reset(obs)`` called at the first observation of every episode (subclasses)."""
        raise NotImplementedError(f"{type(self).__name__} has no scripted policy")

    # ----- closing --------------------------------------------------------------------------------
    def _close_scene(self) -> None:
        if self.physics is not None:
            self._sim.close()
        self.physics = None

    def close(self) -> None:
        self._close_scene()
        if self._live is not None:
            self._live.close()
            self._live = None
