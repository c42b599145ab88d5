"""Clean dual-arm starts (issue 12, item 2): the cable is attached in its static shape in the
grippers' hold, so the wrist sensors (tared on the unloaded arms) read the static load from the
first sample on, with no start transient."""
from __future__ import annotations

import numpy as np
import pytest

from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.robots.dual_arm import DualArmScene, DualArmSpec


def _start_deviation(robot: str, start: str) -> tuple[float, np.ndarray, np.ndarray]:
    """Peak |sensor force - its settled value| [N] in the first 0.3 s, first sample and settled value (2, 3)."""
    spec = DualArmSpec(robot=robot, cable=CableSpec.lv2017(n_masses=10, damping=0.02), start=start)
    with DualArmScene(spec) as sc:
        sc.grasp()
        sc.run(1.5)
        rec = sc.record.arrays()
    t, w = rec["t"], rec["wrench_world"][:, :, :3]
    static = w[t > 1.0].mean(axis=0)
    return float(np.abs(w[t <= 0.3] - static).max()), w[0], static


@pytest.mark.parametrize("robot", ["kuka", "panda"])
def test_settled_start_has_no_transient(robot):
    weight = 0.03 * 9.81
    before, _, _ = _start_deviation(robot, "straight")
    after, first, static = _start_deviation(robot, "settled")
    assert before > 3.0 * weight  # the old start: 1.18 N on a 0.29 N cable
    assert after < 0.01 * weight  # measured 0.6 mN (kuka), 1.6 mN (panda)
    assert np.allclose(first, static, atol=0.01 * weight)  # the first sample reads the static load
    assert first[0, 2] + first[1, 2] == pytest.approx(-weight, rel=0.01)  # which carries the cable's weight


def test_default_start_is_settled_and_bad_values_are_refused():
    assert DualArmSpec().start == "settled"
    with pytest.raises(ParameterError, match="start must be one of settled, straight"):
        DualArmSpec(start="static")


def test_cable_sagging_through_the_table_is_refused():
    soft = CableSpec.lv2017(n_masses=10, youngs_modulus=1e4, damping=0.02)
    with pytest.raises(ParameterError, match="through the table top"):
        DualArmScene(DualArmSpec(cable=soft, hold_height=0.26))
