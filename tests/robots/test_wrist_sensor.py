"""Wrist F/T sensors: sampling rate (the shared RateGate rule), noise, bias, construction errors."""
from __future__ import annotations

import numpy as np
import pytest

from bullet_dlo.config.robot import DualArmSpec, load_robot_spec
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.robots.dual_arm import DualArmObservation, DualArmPhysics, DualArmScene
from bullet_dlo.robots.sensors import WristSensor


def test_sensor_rate_noise_and_bias():
    spec = DualArmSpec(robot="panda", dt=1e-3, sensor_rate=100.0, noise_std=(0.05, 0.05, 0.05, 0, 0, 0),
                       bias=(0.0, 0.0, 0.2, 0, 0, 0), seed=3)
    with DualArmScene(spec) as scene:
        scene.grasp()
        scene.run(2.0)
        rec = scene.record.arrays()
        fz = rec["wrench_world"][-1000:, 0, 2]
        changes = np.count_nonzero(np.diff(fz))
        assert 95 <= changes <= 101  # 100 Hz samples held between 1 kHz physics steps
        samples = fz[np.r_[True, np.diff(fz) != 0]]
        clean = rec["end_forces"][-1000:, 0, 2].mean()
        assert np.std(samples) == pytest.approx(0.05, rel=0.25)
        # the bias is in the sensor frame, whose z axis (the approach direction) points down in world
        assert np.mean(samples) - clean == pytest.approx(-0.2, abs=0.02)


def test_rate_that_is_no_multiple_of_the_step_keeps_its_average():
    """100 Hz sampled in 240 Hz steps: samples at the first step on or after each k / 100 s, so 2 s give 200
    samples (waiting a full period after each late sample would give 80 Hz)."""
    with DualArmScene(DualArmSpec(robot="kuka", sensor_rate=100.0)) as scene:
        times = []
        scene.world.after_step.append(lambda: times.append(scene.sensors[0].last.t))
        scene.run(2.0)
        t = np.unique(times)
        assert len(t) in (200, 201)
        k = np.arange(len(t))
        assert np.all(t >= t[0] + k / 100.0 - 1e-9)  # never early
        assert np.all(t < t[0] + k / 100.0 + scene.world.dt)  # late by less than one step


def test_sensor_errors():
    with DualArmScene(DualArmSpec(robot="kuka")) as scene:
        robot = scene.robots[0]
        with pytest.raises(ParameterError, match="rate must be a finite number > 0"):
            WristSensor(robot, scene.world.gravity, rate=-5.0)
        with pytest.raises(ParameterError, match="6 components"):
            WristSensor(robot, scene.world.gravity, noise_std=(0.1, 0.1, 0.1))
        spec = load_robot_spec("panda")
        robot.spec = type(spec)(**{**spec.__dict__, "sensor_joint": "wrist_ft"})
        with pytest.raises(ParameterError, match="no joint 'wrist_ft' for the F/T sensor"):
            WristSensor(robot, scene.world.gravity)


def test_observation_must_tare_before_the_first_step():
    physics = DualArmPhysics(DualArmSpec(robot="kuka"))
    try:
        physics.run(0.01)
        with pytest.raises(ParameterError, match="before the first step"):
            DualArmObservation(physics)
    finally:
        physics.close()
