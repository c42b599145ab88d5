"""Episodes of capture specs with drawn gripper trajectories (``motion:``) and friction grips.

Real dual-arm episodes, kept short (8 masses, 240 Hz, at most 1.5 s):

* a sine of the right gripper (drawn amplitude A and frequency f, starting abruptly at t0) shows
  in the recorded grasp-frame height as A' sin(2 pi f' (t - t0 - lag)). The arm's position servo
  follows its IK targets like a first-order lag: a sine comes through at the same frequency,
  delayed by ``lag`` and scaled by cos(2 pi f lag) (a first-order lag of phase phi passes
  cos(phi) of the amplitude). So f' = f, and A' = A cos(2 pi f lag) with the fitted lag;
* the left gripper turns about the vertical by a drawn angle: its recorded quaternion ends turned
  by exactly that rotation vector (IK solves to about 1e-4 rad);
* friction grips (drawn F_n, mu_s, mu_d): pulling the arms apart, the wrist sensors' axial force
  rises to the break-away force and then stays at the Coulomb force of two fingers,
  2 mu_d F_n, while the ends slide along the grippers (tests/robots/test_friction_grasp.py).
"""
from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.optimize import curve_fit
from scipy.spatial.transform import Rotation

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.core.boundary import Move, parse_motion
from bullet_dlo.data import plan
from bullet_dlo.config.robot import DualArmSpec
from bullet_dlo.data.episode import episode_scene, run_episode
from bullet_dlo.data.plan import episode_motion, gripper_move, plan_episode
from bullet_dlo.data.reader import load_episode

PULL = 0.03  # [m] each gripper moves outwards in the friction episode


def U(low: float, high: float) -> dict:
    return {"dist": "uniform", "low": low, "high": high}


SHAKE_AND_TURN = {"seed": 5, "episode": {"duration": 1.5, "record_rate": 240},
                  "sample": {"n_masses": 8, "robot": "kuka"},
                  "motion": [{"type": "sine", "end": "last", "amplitude": [0, 0, U(0.01, 0.03)],
                              "frequency": U(0.8, 1.5), "start": 0.25},
                             {"type": "move", "end": "first", "rotation": [0, 0, U(0.2, 0.4)], "start": 0.2,
                              "duration": 0.8}]}
PULL_APART = {"seed": 2, "episode": {"duration": 1.3, "record_rate": 240},
              "sample": {"n_masses": 8, "grip": "friction", "grip_force": U(2.5, 3.5), "grip_static_friction": U(0.5, 0.6),
                         "grip_dynamic_friction": U(0.35, 0.45), "grip_reach": 0.05},
              "motion": [{"end": "first", "displacement": [-PULL, 0, 0], "start": 0.3, "duration": 0.8},
                         {"end": "last", "displacement": [PULL, 0, 0], "start": 0.3, "duration": 0.8}]}


def episode(tmp_path_factory, data: dict) -> tuple[dict, dict, CaptureSpec]:
    """Run episode 0 of the spec ``data``; (its manifest record, its file's contents, the spec)."""
    spec = CaptureSpec.from_dict(data)
    out = tmp_path_factory.mktemp("capture")
    record = run_episode(spec.to_dict(), 0, str(out))
    assert record["status"] == "ok", record
    return record, load_episode(out / record["file"]), spec


@pytest.fixture(scope="module")
def shaken(tmp_path_factory):
    return episode(tmp_path_factory, SHAKE_AND_TURN)


@pytest.fixture(scope="module")
def pulled(tmp_path_factory):
    return episode(tmp_path_factory, PULL_APART)


def test_the_drawn_motion_is_stored_with_the_params(shaken):
    record, ep, spec = shaken
    drawn = json.loads(json.dumps(spec.draw(0)["motion"]))
    assert ep["params"]["motion"] == record["params"]["motion"] == drawn
    assert "speed" not in ep["params"] and "displacement_x" not in ep["params"]


def test_a_drawn_sine_shows_in_the_grippers_height(shaken):
    _, ep, _ = shaken
    sine = parse_motion(ep["params"]["motion"])[0]
    amplitude, f, t0 = sine.amplitude[2], sine.frequency, sine.start
    t, pos = ep["t"], ep["ee_pos"][:, 1]  # the right gripper holds the last end
    late = t > t0 + 0.2  # after the servo's start transient (the sine starts abruptly)

    def shape(t, a, freq, lag, z0):
        return a * np.sin(2 * np.pi * freq * (t - t0 - lag)) + z0

    (a, freq, lag, _), _ = curve_fit(shape, t[late], pos[late, 2], p0=[amplitude, f, 0.0, pos[0, 2]])
    assert freq == pytest.approx(f, rel=5e-3)
    assert 0.0 < lag < 0.06  # [s] a servo's delay, not a missed cycle
    assert a == pytest.approx(amplitude * np.cos(2 * np.pi * f * lag), rel=0.02)
    assert np.std(pos[late, 2] - shape(t[late], a, freq, lag, 0.0) - np.mean(pos[late, 2])) < 0.02 * amplitude
    assert np.abs(pos[:, :2] - pos[0, :2]).max() < 0.1 * amplitude  # a vertical sine: x and y stay put
    assert np.allclose(pos[t < t0 - 0.05, 2], pos[0, 2], atol=1e-4)  # nothing before it starts


def test_a_drawn_rotation_turns_the_gripper_by_the_drawn_angle(shaken):
    _, ep, _ = shaken
    turn = parse_motion(ep["params"]["motion"])[1]
    t, quat = ep["t"], ep["ee_quat"][:, 0]  # the left gripper holds the first end
    turned = Rotation.from_quat(quat[-1]) * Rotation.from_quat(quat[0]).inv()  # world-frame rotation, as the motion
    assert np.allclose(turned.as_rotvec(), turn.rotation, atol=1e-4)
    assert abs(turn.rotation[2]) > 0.2
    early = Rotation.from_quat(quat[t < turn.start][-1]) * Rotation.from_quat(quat[0]).inv()
    assert early.magnitude() < 1e-3  # not before the move starts
    assert np.abs(ep["ee_pos"][:, 0] - ep["ee_pos"][0, 0]).max() < 2e-3  # it turns about the grasp point


def test_a_friction_grip_saturates_at_two_mu_d_grip_force(pulled):
    _, ep, _ = pulled
    p = ep["params"]
    cap_s, cap_d = 2 * p["grip_static_friction"] * p["grip_force"], 2 * p["grip_dynamic_friction"] * p["grip_force"]
    t = ep["t"]
    axial = np.abs(ep["wrench_world"][:, :, 0])  # (k, 2): both sensors' pull along the cable [N]
    model = np.abs(ep["end_forces"][:, :, 0])
    assert axial[t < 0.3].max() < 0.9 * cap_d  # before the pull the grips hold less than they could
    assert 0.95 * cap_d < axial.max() <= 1.05 * cap_s  # the pull rises to the break-away force, no further
    sliding = (t > 0.5) & (t < 1.1)  # the grippers still move apart, the ends slide
    assert np.allclose(axial[sliding], cap_d, rtol=0.05)
    assert np.allclose(model[sliding], cap_d, rtol=0.01)
    # the grippers moved 2 PULL apart while the cable, barely stretched, slid along them
    x, ee = ep["cable_x"], ep["ee_pos"]
    grip_gain = np.linalg.norm(ee[-1, 1] - ee[-1, 0]) - np.linalg.norm(ee[0, 1] - ee[0, 0])
    span_gain = np.linalg.norm(x[-1, -1] - x[-1, 0]) - np.linalg.norm(x[0, -1] - x[0, 0])
    assert grip_gain == pytest.approx(2 * PULL, abs=2e-3) and abs(span_gain) < 2e-3


def test_the_grip_parameters_reach_the_dual_arm_scene():
    spec = CaptureSpec.from_dict(PULL_APART)
    params, decision = plan_episode(spec, 3)
    setup = DualArmSpec.from_scene(episode_scene(spec, params, decision))
    assert (setup.grip, setup.grip_force, setup.grip_reach) == ("friction", params["grip_force"], 0.05)
    assert (setup.grip_static_friction, setup.grip_dynamic_friction) == (params["grip_static_friction"], params["grip_dynamic_friction"])
    # parameters stored by older versions (no grip keys) give today's clamp
    old = {k: v for k, v in params.items() if not k.startswith("grip")}
    assert DualArmSpec.from_scene(episode_scene(spec, old, decision)).grip == "clamp"


def test_without_motion_the_right_gripper_makes_the_straight_move():
    spec = CaptureSpec.from_dict({"sample": {"displacement_x": -0.05, "displacement_z": 0.02, "speed": 0.1,
                                             "move_start": 0.4}})
    params, _ = plan_episode(spec, 0)
    displacement, duration = gripper_move(params)
    assert duration == pytest.approx(np.hypot(0.05, 0.02) / 0.1)
    assert episode_motion(params) == (Move("last", tuple(displacement), 0.4, duration),)
    still = CaptureSpec.from_dict({"sample": {"displacement_z": 0.0}})
    assert episode_motion(plan_episode(still, 0)[0]) == ()


def test_auto_masses_resolves_on_the_drawn_motion(monkeypatch):
    """``n_masses: auto`` tests convergence on the episode's own (drawn) motion: the core scene gets those items."""
    seen = []
    problem_of = plan.resolve_problem

    def problem(scene, **options):
        seen.append(scene)
        return problem_of(scene, **options)

    monkeypatch.setattr(plan, "resolve_problem", problem)
    monkeypatch.setattr(plan, "resolve_masses", lambda problem, tol, target: (12, 0.01))
    spec = CaptureSpec.from_dict({**SHAKE_AND_TURN, "sample": {"n_masses": "auto"}, "resolve_tol": 0.05})
    params, decision = plan_episode(spec, 1)
    assert (params["n_masses"], decision["resolved_n_masses"]) == (12, 12)
    assert seen[0].motion == parse_motion(spec.draw(1)["motion"]) == episode_motion(params)
    assert seen[0].ends == ("clamped", "clamped") and seen[0].duration == spec.duration
