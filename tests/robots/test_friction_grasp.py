"""Dual-arm scene with friction grips: grippers pulling the cable apart, the ends slipping at 2 mu F_n.

Both grippers pinch their end with F_n per finger (grip: friction) and move 3 cm apart each over
1 s at 240 Hz. The cable's tension rises until the grips break away at 2 mu_s F_n; from then on
the ends slide along the grippers and the wrist sensors' axial (x) force is 2 mu_d F_n (closed
form of Coulomb friction at two fingers), while the ends slip by what the grippers moved.
"""
from __future__ import annotations

import numpy as np
import pytest

from bullet_dlo.config.robot import DualArmSpec
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.robots.dual_arm import DualArmScene

F_N, MU_S, MU_D = 2.0, 0.5, 0.4
PULL = 0.03  # [m] each gripper moves outwards


@pytest.mark.parametrize("robot", ["kuka", "panda"])
def test_wrist_force_saturates_at_two_mu_d_fn_while_the_ends_slip(robot):
    spec = DualArmSpec(robot=robot, grip="friction", grip_force=F_N, grip_static_friction=MU_S, grip_dynamic_friction=MU_D, grip_reach=0.05)
    cap_s, cap_d = 2 * MU_S * F_N, 2 * MU_D * F_N
    with DualArmScene(spec) as scene:
        scene.grasp()
        scene.run(0.5)
        held = scene.cable.grip_state()
        assert held["active"].all() and not held["sliding"].any()
        start = scene.world.time
        scene.move("left", (-PULL, 0.0, 0.0), 1.0, start=start)
        scene.move("right", (PULL, 0.0, 0.0), 1.0, start=start)
        sliding = []
        for _ in range(int(round(1.2 / scene.world.dt))):
            scene.run(scene.world.dt)
            sliding.append(scene.cable.grip_state()["sliding"].all())
        slip = scene.cable.grip_state()["slip"]
        assert scene.cable.stable
        rec = scene.record.arrays()
    moving = rec["t"] > start
    axial = np.abs(rec["wrench_world"][moving][:, :, 0])  # (k, 2): the sensors' pull along the cable [N]
    model = np.abs(rec["end_forces"][moving][:, :, 0])
    sliding = np.array(sliding)[-len(axial):]
    assert axial[0].max() < 0.9 * cap_d  # before the move the grips hold less than they could
    assert 0.95 * cap_d < axial.max() <= 1.05 * cap_s  # the pull rises to the break-away force, no further
    onset = int(np.argmax(sliding))
    pulling = rec["t"][moving] <= start + 1.0  # the grippers move; after it the ends may stick again
    assert sliding[onset:][pulling[onset:]].all() and onset > 0
    assert np.allclose(axial[onset + 2:], cap_d, rtol=0.05)  # saturated at 2 mu_d F_n while the ends slip
    assert np.allclose(model[onset + 2:], cap_d, rtol=0.01)
    # each end slid along its gripper by about what the gripper moved (the cable's stretch barely changes)
    assert np.allclose(np.abs(slip), PULL, atol=0.003)


def test_clamp_stays_the_default():
    assert DualArmSpec().grip == "clamp"


@pytest.mark.parametrize("kwargs, word", [({"grip": "glue"}, "grip"), ({"grip_force": 0.0}, "grip_force"),
                                          ({"grip_static_friction": 0.3, "grip_dynamic_friction": 0.5}, "grip_dynamic_friction"),
                                          ({"grip_reach": -1.0}, "grip_reach")])
def test_bad_grip_settings_are_refused(kwargs, word):
    with pytest.raises(ParameterError, match=word):
        DualArmSpec(**kwargs)
