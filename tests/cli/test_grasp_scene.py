"""Scene files set the dual-arm layout and start for grasp (``arms:``, ``initial:``)."""
from __future__ import annotations

import numpy as np
import pytest

from bullet_dlo.cli.main import main
from bullet_dlo.config.scene import Scene
from bullet_dlo.core.validate import ParameterError

SCENE = """
cable: {preset: lv2017, n_masses: 8}
arms: {hold_height: 0.45, base_distance: 0.55}
dt: 0.004166666666666667
duration: 0.3
"""


def test_grasp_holds_the_cable_where_the_scene_file_says(tmp_path):
    scene = tmp_path / "s.yaml"
    scene.write_text(SCENE)
    series = tmp_path / "run.npz"
    assert main(["-q", "grasp", "--robot", "kuka", "--scene", str(scene), "--series", str(series)]) == 0
    ee = np.load(series)["ee_pos"]  # (k, 2, 3) grasp-frame positions [m]
    assert np.allclose(ee[-1, :, 2], 0.45, atol=2e-3)  # the hold height of the file, not the default 0.35
    span = np.linalg.norm(ee[-1, 1] - ee[-1, 0])
    assert span == pytest.approx(0.3, abs=2e-3)  # the grippers hold the cable's ends: span = its length


def test_arms_section_is_validated_with_the_key_named():
    base = {"cable": {"preset": "lv2017", "n_masses": 8}}
    with pytest.raises(ParameterError, match="arms.hold_height"):
        Scene.from_dict({**base, "arms": {"hold_height": -1}})
    with pytest.raises(ParameterError, match="above the table top"):
        Scene.from_dict({**base, "arms": {"hold_height": 0.21}})
    with pytest.raises(ParameterError, match="unknown key"):
        Scene.from_dict({**base, "arms": {"span": 0.3}})
    assert Scene.from_dict({**base, "arms": {"table_height": 0}}).arm_options() == {"start": "settled",
                                                                                     "table_height": 0.0}


def test_friction_grip_from_a_scene_file_saturates_at_two_mu_fn(tmp_path):
    """arms: {grip: friction, ...}: grippers pulling apart make the ends slip; the wrist force along the
    cable saturates at 2 mu_d F_n (two fingers), the closed form of a friction grip."""
    scene = tmp_path / "grip.yaml"
    scene.write_text("""
cable: {preset: lv2017, n_masses: 10}
arms: {grip: friction, grip_force: 2.0, grip_friction: [0.5, 0.4], grip_reach: 0.05}
motion:
  - {end: first, displacement: [-0.015, 0, 0], start: 0.5, duration: 1.0}
  - {end: last, displacement: [0.015, 0, 0], start: 0.5, duration: 1.0}
dt: 0.004166666666666667
duration: 1.5
""")
    series = tmp_path / "run.npz"
    assert main(["-q", "grasp", "--robot", "kuka", "--scene", str(scene), "--series", str(series)]) == 0
    data = np.load(series)
    fx = data["wrench_world"][:, :, 0]  # (k, 2): the force along the cable at each wrist
    t = data["t"]
    late = (t > 1.2) & (t < 1.45)  # the ends slip: the grip force is at its dynamic cap
    assert np.all(np.abs(fx[late]) == pytest.approx(2 * 0.4 * 2.0, rel=0.05))
    assert np.max(np.abs(fx)) <= 1.05 * 2 * 0.5 * 2.0  # never beyond the static cap
