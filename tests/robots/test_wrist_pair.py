"""The dual-arm step's fused wrist-sensor call against the sensors updated one by one: the same bits."""
from __future__ import annotations

import copy

import numpy as np

from bullet_dlo.config.robot import DualArmSpec
from bullet_dlo.robots.dual_arm import DualArmObservation, DualArmPhysics
from bullet_dlo.robots.transforms import cross3


def test_both_sensors_in_one_call_read_what_each_sensor_reads_alone():
    """A noisy, rate-limited pair of sensors on a moving, loaded scene: after each step the fused read
    (DualArmObservation.read_sensors) is replayed from a copy of the sensors' state before it through
    WristSensor.update, one sensor after the other; readings, offsets and the check agree bit for bit."""
    spec = DualArmSpec(robot="panda", sensor_rate=120.0, noise_std=(0.01, 0.02, 0.03, 1e-3, 2e-3, 3e-3))
    physics = DualArmPhysics(spec)
    try:
        obs = DualArmObservation(physics, record=False)
        physics.clamp(0)
        physics.clamp(1)
        world = physics.world
        robot = physics.robots[1]
        q = robot.joint_positions()
        compared = 0
        for step in range(12):
            robot.set_targets(q + 0.002 * step)  # the right hand moves: inertia and a changing load
            state = [copy.deepcopy((s.gate, s.rng, s._noise_rows, s._noise_next, s._tool_memory, s._memory))
                     for s in obs.sensors]
            # the loads the cable applies in this step: planned by its last step (its next step replaces them)
            forces, torques = (a.copy() for a in physics.cable.planned_end_loads())
            world.step()
            for arm, s in enumerate(obs.sensors):
                fused = (s.values.copy(), s.offset.copy(), s.last)
                s.gate, s.rng, s._noise_rows, s._noise_next, tool_memory, memory = state[arm]
                s._tool_memory.momentum[:] = tool_memory.momentum  # the kernels' memories, back to before
                s._tool_memory.valid[:] = tool_memory.valid
                s._memory.momentum[:] = memory.momentum
                s._memory.valid[:] = memory.valid
                applied = np.r_[forces[arm], torques[arm] + cross3(physics.load_points[arm], forces[arm])]
                alone = s.update(world.time, world.dt, applied)
                assert np.array_equal(s.values, fused[0]) and np.array_equal(s.offset, fused[1])
                assert alone.t == fused[2].t and np.array_equal(alone.world(), fused[2].world())
                compared += 1
        assert compared == 24
        assert obs.check.samples > 0 and not obs.check.failures()
    finally:
        physics.close()


def test_noise_drawn_in_blocks_is_the_noise_drawn_per_sample():
    """A sensor drawing its noise 240 samples at a time (the dual-arm sensors, whose generators are their own)
    gives every sample the bias plus noise a draw per sample gives, bit for bit, across block ends."""
    from types import SimpleNamespace

    from bullet_dlo.robots.sensors import WristSensor

    def sensor(block):
        return SimpleNamespace(bias=np.array([0.1, -0.2, 0.3, 0.0, 1e-3, -2e-3]), rng=np.random.default_rng(5),
                               noise_std=np.array([0.01, 0.02, 0.03, 1e-3, 2e-3, 3e-3]), noise_block=block,
                               _noise_rows=None, _noise_next=0)

    one, block = sensor(1), sensor(240)
    for _ in range(500):
        assert np.array_equal(WristSensor._noise(one), WristSensor._noise(block))
