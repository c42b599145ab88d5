"""Fork ends (issue 22) in a scene file, through the core engine and Bullet (the closed forms are in
``tests/core/test_fork.py``)."""
from __future__ import annotations

import math
from dataclasses import replace

import pytest

from bullet_dlo.config.scene import Scene, result_json
from bullet_dlo.sim import build, resolved


@pytest.mark.parametrize("engine", ["core", "bullet"])
def test_a_scene_file_holds_forks_and_turns_the_frame_on_when_one_rolls(tmp_path, engine):
    """``ends: {first: fork, last: fork}`` in a scene file on a round cable without ``twist``: a fork that rolls
    turns the material frame on (saying why), and ``bullet-dlo simulate``'s output gives the forks' moments, the
    torsion G J (pi/2) / L about the axis, in the core engine and in Bullet; without the roll the round cable
    keeps its frameless model."""
    path = tmp_path / "forks.yaml"
    path.write_text("cable: {length: 0.3, diameter: 0.004, mass: 0.03, youngs_modulus: 126.0e6, n_masses: 9,\n"
                    "        damping_rate: 5.0}\n"
                    "ends: {first: fork, last: fork}\n"
                    "motion: [{end: last, rotation: [1.5707963267948966, 0, 0], duration: 0.3}]\n"
                    "gravity: [0, 0, 0]\nintegrator: bdf2\ndt: 0.001\nduration: 0.6\n")
    scene = Scene.from_yaml(path)
    assert scene.ends == ("fork", "fork") and not scene.cable.twist_enabled
    assert "the last fork rolls 90 deg about the cable axis" in resolved(scene).twist_reason
    with build(scene, engine) as sim:
        res = sim.run()
    out = result_json(scene, sim.model, res, engine=engine)
    assert out["stable"]
    expected = scene.cable.torsional_rigidity * (math.pi / 2) / scene.cable.length
    assert out["end_moments"]["first"][0] == pytest.approx(expected, rel=0.01)
    assert out["end_moments"]["last"][0] == pytest.approx(-expected, rel=0.01)
    still = resolved(replace(scene, motion=()))
    assert not still.cable.twist_enabled and not still.twist_reason
