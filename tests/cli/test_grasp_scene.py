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
