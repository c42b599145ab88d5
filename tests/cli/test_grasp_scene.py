"""Scene files set the dual-arm layout and start for grasp (``arms:``, ``initial:``)."""
from __future__ import annotations

import numpy as np
import pytest

from bullet_dlo.cli.main import main
from bullet_dlo.config.robot import DualArmSpec
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
    spec = DualArmSpec.from_scene(Scene.from_dict({**base, "arms": {"table_height": 0}}))
    assert (spec.start, spec.table_height, spec.hold_height) == ("settled", 0.0, 0.35)  # given, and the defaults


def test_friction_grip_from_a_scene_file_saturates_at_two_mu_fn(tmp_path):
    """arms: {grip: friction, ...}: grippers pulling apart make the ends slip; the wrist force along the
    cable saturates at 2 mu_d F_n (two fingers), the closed form of a friction grip."""
    scene = tmp_path / "grip.yaml"
    scene.write_text("""
cable: {preset: lv2017, n_masses: 10}
arms: {grip: friction, grip_force: 2.0, grip_static_friction: 0.5, grip_dynamic_friction: 0.4, grip_reach: 0.05}
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


TILT = """
cable: {length: 0.3, diameter: 0.004, mass: 0.03, youngs_modulus: 126.0e6, n_masses: 16, damping: 0.01}
motion: [{end: last, displacement: MOVE, rotation: [ROT, 0, 0], start: 0.2, duration: DUR}]
integrator: bdf2
dt: 0.004166666666666667
duration: 2.0
"""


def test_grasp_with_a_tilted_gripper_reads_the_model_and_its_check_says_when_not(tmp_path, capsys):
    """Issue 27: the README's grasp with the right gripper turned 0.3 rad about the cable read -2.9 N sideways
    (-151 % balance) and exited 0. Now it reads the model, also while turning 90 degrees in 0.7 s (1.6 N off
    with Bullet's joint reaction); a gripper driven into the table (a load the cable model does not hold)
    makes grasp say so and exit 1."""
    import json

    slow, fast, table = tmp_path / "slow.yaml", tmp_path / "fast.yaml", tmp_path / "table.yaml"
    slow.write_text(TILT.replace("ROT", "0.3").replace("DUR", "0.7").replace("MOVE", "[0, 0, 0]"))
    fast.write_text(TILT.replace("ROT", "1.5708").replace("DUR", "0.7").replace("MOVE", "[0, 0, 0]"))
    table.write_text(TILT.replace("ROT", "0").replace("DUR", "1.0").replace("MOVE", "[-0.08, 0, -0.36]"))
    out = tmp_path / "out.json"
    code = main(["-q", "grasp", "--robot", "panda", "--scene", str(slow), "--json", str(out)])
    data = json.loads(out.read_text())
    assert abs(data["force_balance_error"]) < 0.005 and data["sensor_vs_model_error"] < 0.005  # at rest
    assert data["sensor_compensation"] == "urdf"
    assert code == 0 and not data["sensor_check"]["failures"]
    assert main(["-q", "grasp", "--robot", "panda", "--scene", str(fast), "--json", str(out)]) == 0
    assert max(json.loads(out.read_text())["sensor_check"]["worst_force"]) < 1e-6
    capsys.readouterr()
    assert main(["-q", "grasp", "--robot", "panda", "--scene", str(table)]) == 1
    assert "SENSOR CHECK FAILED: right wrist force differs" in capsys.readouterr().out
