"""Domain randomisation for the environments: a capture spec's distributions, re-drawn at every reset.

The same spec format as dataset captures (:class:`~bullet_dlo.config.capture.CaptureSpec`, a
YAML file or a dict), the same planning (:func:`~bullet_dlo.data.plan.plan_episode`: its
stability policy may switch integrator or add substeps) and the same scene
(:func:`~bullet_dlo.data.episode.episode_scene`, built by :func:`bullet_dlo.sim.build_arms`). An environment's reset draws one episode seed
from its own generator (seeded by ``reset(seed=...)``), so the drawn parameters depend only on
the reset seed. Used: the cable (length, diameter, mass, youngs_modulus, n_masses, damping,
damping_rate, internal_damping, dynamic_friction, static_friction), dt, integrator, robot, hold_height, the grip (grip,
grip_force, grip_static_friction, grip_dynamic_friction, grip_reach) and the wrist sensors (noise_std,
sensor_rate); the capture's gripper motion (displacement_*, speed, move_start or a ``motion:``
section) and its episode/camera sections are not: the policy moves the arms, the environment
sets its own length and camera.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.config.robot import DualArmSpec
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.config.scene import Scene
from bullet_dlo.data.episode import episode_scene
from bullet_dlo.data.plan import plan_episode

RandomisationLike = CaptureSpec | Mapping[str, Any] | str | Path | None


@dataclasses.dataclass(frozen=True)
class Draw:
    """One reset's draw, as a capture stores it.

    Attributes:
        scene: the reset's scene (what :func:`bullet_dlo.sim.build_arms` builds).
        setup: its dual-arm physics spec, with the renderer.
        params: the drawn parameters (:meth:`~bullet_dlo.config.capture.CaptureSpec.draw`; SI units, names of
            :data:`~bullet_dlo.config.capture.PARAMETERS`).
        decision: the stability decision (integrator, substeps, critical step).
    """

    scene: Scene
    setup: DualArmSpec
    params: dict
    decision: dict


class EnvRandomisation:
    """Draws a scene per reset from ``spec`` (a CaptureSpec, its dict form or a YAML path; None: ``default``)."""

    def __init__(self, spec: RandomisationLike, default: Mapping[str, Any] | None = None):
        if spec is None:
            spec = default or {}
        if not isinstance(spec, (CaptureSpec, Mapping, str, Path)):
            raise ParameterError("randomisation must be None, a CaptureSpec, a dict or a YAML path, "
                                 f"got {type(spec).__name__}")
        try:
            if isinstance(spec, (str, Path)):
                spec = CaptureSpec.from_yaml(spec)
            elif not isinstance(spec, CaptureSpec):
                spec = CaptureSpec.from_dict(spec)
        except ParameterError as err:  # the spec's own checks name the key; say it is this keyword's
            raise ParameterError("randomisation: " + " ".join(str(err).split())) from None
        self.spec = spec

    def draw(self, rng: np.random.Generator, renderer: str | None) -> Draw:
        """The scene of one episode, from ``rng`` (the environment's, seeded at reset); ``renderer`` for images."""
        seeded = dataclasses.replace(self.spec, seed=int(rng.integers(2**31 - 1)), camera_fps=0.0)
        params, decision = plan_episode(seeded, 0)
        scene = dataclasses.replace(episode_scene(seeded, params, decision), motion=())  # the policy moves the arms
        return Draw(scene, DualArmSpec.from_scene(scene, renderer=renderer), params, decision)

    def values(self, key: str) -> list:
        """Every value parameter ``key`` can take, for a ``fixed`` or ``choice`` distribution (else [])."""
        dist = self.spec.sample.get(key)
        if dist is None:
            from bullet_dlo.config.capture import PARAMETERS

            return [PARAMETERS[key][1]["value"]]
        if dist.dist == "fixed":
            return [dist.value]
        return list(dist.values) if dist.dist == "choice" else []

    def support(self, key: str) -> tuple[float, float] | None:
        """Smallest and largest value parameter ``key`` can draw [its unit]; None for ``auto``."""
        from bullet_dlo.config.capture import PARAMETERS, support

        dist = self.spec.sample.get(key)
        if dist is None:
            value = PARAMETERS[key][1]["value"]
            return float(value), float(value)
        if dist.dist == "fixed" and dist.value == "auto":
            return None
        return support(dist, PARAMETERS[key][2])


def check_control_period(control_dt: float, dt: float) -> int:
    """Physics steps per control step: ``control_dt / dt`` [s / s] must be a whole number >= 1 (as dm_control asks)."""
    ratio = control_dt / dt
    steps = int(round(ratio))
    if steps < 1 or abs(ratio - steps) > 1e-6 * max(1.0, ratio):
        raise ParameterError(f"control_dt = {control_dt} s must be a whole multiple (>= 1) of the physics step "
                             f"dt = {dt} s (ratio {ratio:.6g})")
    return steps
