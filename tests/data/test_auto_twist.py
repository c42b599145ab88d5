"""A capture spec turns the material frame on for an episode whose gripper rolls the cable about its axis (as
``resolve`` does for a scene), with ``n_masses: auto`` and with a given number of masses alike, and leaves a
yawing episode's round cable without it."""
from __future__ import annotations

import pytest

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.data.plan import plan_episode

pytestmark = pytest.mark.bullet


def spec(rotation, n_masses="auto") -> CaptureSpec:
    return CaptureSpec.from_dict({
        "seed": 1, "episode": {"duration": 0.6},
        "sample": {"n_masses": {"dist": "fixed", "value": n_masses},
                   "integrator": {"dist": "fixed", "value": "bdf2"}},
        "motion": [{"type": "move", "end": "last", "rotation": rotation, "start": 0.1, "duration": 0.3}]})


def test_a_rolling_gripper_gets_the_material_frame():
    params, decision = plan_episode(spec([0.5, 0.0, 0.0]), 0)  # about x: the cable's axis
    assert params["twist"] is True and "rolls" in params["twist_reason"] and decision["resolved_n_masses"] >= 3


def test_a_yawing_gripper_keeps_the_round_cable_without_it():
    params, _ = plan_episode(spec([0.0, 0.0, 0.3]), 0)  # about z: the cable turns, it does not twist
    assert not params.get("twist", False) and "twist_reason" not in params


def test_a_rolling_gripper_gets_the_frame_with_a_given_number_of_masses():
    """Not only ``auto``: a cable without the frame would read no torsion at the rolled wrist."""
    params, decision = plan_episode(spec([0.5, 0.0, 0.0], n_masses=12), 0)
    assert params["twist"] is True and "rolls 28.6 deg" in params["twist_reason"]
    assert params["n_masses"] == 12 and decision["resolved_n_masses"] is None
    params, _ = plan_episode(spec([0.0, 0.0, 0.3], n_masses=12), 0)
    assert not params.get("twist", False)
