"""Held-end trajectories: waypoint paths and sines in the Numba holder kernels, superposed with moves.

Samples are checked against their own finite differences (velocity, acceleration), against the
waypoints and closed forms, and a cable carried rigidly by both ends pushes on its holders
with -M a(t) (the sampled acceleration is the one the cable feels).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bullet_dlo.config.scene import Scene
from bullet_dlo.core.boundary import Move, Sine, Waypoints, motion_offset, parse_motion
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.kernels.holders import empty_samples, sample_holders
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError

PATH = Waypoints("last", (0.2, 0.5, 0.9, 1.3), ((0, 0, 0), (0, 0, 0.01), (0.005, -0.002, 0.0), (0.004, 0, 0.003)),
                 ((0, 0, 0), (0, 0.2, 0), (0.1, 0, 0.05), (0, 0, 0)))
SINE = Sine("last", (0.002, 0.0, -0.003), 2.5, phase=0.4, rotation=(0.0, 0.15, 0.0), start=0.1, duration=1.0,
            ramp=0.2)


def sampled(items, t: float, end: int = 1):
    """pos, vel, acc, dir of end ``end`` at t [s] for a clamped-clamped cable following ``items``."""
    model = CableModel.straight(CableSpec.lv2017(n_masses=5), motion=items)
    samples = empty_samples()
    sample_holders(model.holder_plan(), t, 0.0, samples)
    return model, tuple(a[0, end].copy() for a in samples)


@pytest.mark.parametrize("items", [[PATH], [SINE], [PATH, SINE, Move("last", (0.0, 0.01, 0.0), 0.3, 0.4)]],
                         ids=["waypoints", "sine", "superposed"])
def test_velocity_and_acceleration_are_derivatives_of_the_position(items):
    eps = 1e-5
    for t in np.linspace(0.0, 1.5, 61) + 0.0013:
        _, (p, v, a, _) = sampled(items, t)
        _, (p_plus, v_plus, _, _) = sampled(items, t + eps)
        _, (p_minus, v_minus, _, _) = sampled(items, t - eps)
        assert np.allclose(v, (p_plus - p_minus) / (2 * eps), atol=1e-7), t
        assert np.allclose(a, (v_plus - v_minus) / (2 * eps), atol=1e-5), t


def test_waypoint_path_passes_its_waypoints_is_c2_and_rests_at_both_ends():
    start = CableModel.straight(CableSpec.lv2017(n_masses=5)).x0[-1]
    for t, disp, rot in zip(PATH.times, PATH.displacements, PATH.rotations):
        model, (p, v, a, d) = sampled([PATH], t)
        assert np.allclose(p, start + disp, atol=1e-15)
        assert np.allclose(d, Rotation.from_rotvec(rot).apply(model.last.direction), atol=1e-12)
    for t in PATH.times[1:-1]:  # continuous position, velocity and acceleration across the knots
        left, right = sampled([PATH], t - 1e-9)[1], sampled([PATH], t + 1e-9)[1]
        for k in range(3):
            assert np.allclose(left[k], right[k], atol=1e-6)
    for t in (0.0, PATH.times[0], PATH.times[-1], 2.0):
        _, (p, v, a, _) = sampled([PATH], t)
        assert np.allclose(v, 0.0) and np.allclose(a, 0.0)
    assert np.allclose(sampled([PATH], 2.0)[1][0], start + PATH.displacements[-1])


def test_sine_matches_its_closed_form_and_turns_the_clamp():
    sine = Sine("first", (0.0, 0.004, 0.0), 2.0, phase=0.3, rotation=(0.0, 0.0, 0.2), start=0.25)
    for t in (0.0, 0.3, 0.61, 1.7):
        model, (p, v, a, d) = sampled([sine], t, end=0)
        arg = 2 * math.pi * 2.0 * (t - 0.25) + 0.3
        f = math.sin(arg) if t >= 0.25 else 0.0
        w = 2 * math.pi * 2.0
        assert np.allclose(p, model.x0[0] + np.array([0, 0.004, 0]) * f, atol=1e-15)
        assert np.allclose(v, np.array([0, 0.004, 0]) * (w * math.cos(arg) if t >= 0.25 else 0.0), atol=1e-13)
        assert np.allclose(a, -w * w * np.array([0, 0.004, 0]) * f, atol=1e-11)
        assert np.allclose(d, Rotation.from_rotvec([0, 0, 0.2 * f]).apply(model.first.direction), atol=1e-12)
    _, (p, v, a, _) = sampled([SINE], SINE.start + SINE.duration + 0.01)  # ramped out: back at rest
    assert np.allclose(v, 0.0) and np.allclose(a, 0.0)


def test_motion_offset_gives_the_rotation_the_kernel_applies():
    disp, vel, acc, rot = motion_offset([PATH, SINE], "last", [0.35, 0.7])
    for i, t in enumerate((0.35, 0.7)):
        model, (p, v, a, d) = sampled([PATH, SINE], t)
        assert np.allclose(disp[i], p - model.x0[-1]) and np.allclose(vel[i], v) and np.allclose(acc[i], a)
        assert np.allclose(rot[i] @ model.last.direction, d)
        assert np.allclose(rot[i] @ rot[i].T, np.eye(3), atol=1e-12)


def test_rigidly_carried_cable_pushes_its_holders_with_minus_mass_times_acceleration():
    spec = CableSpec.lv2017(n_masses=6, youngs_modulus=2e9)
    # along a stiff cable, slow against its axial modes: it moves as a rigid body
    motion = [Sine(end, (0.03, 0.0, 0.0), 2.0, start=0.0, ramp=0.3) for end in ("first", "last")]
    model = CableModel.straight(spec, motion=motion, gravity=(0.0, 0.0, 0.0))
    res = simulate(model, "implicit_midpoint", 1e-4, 1.2, record_every=25)
    assert res.stable
    acc = motion_offset(motion, "first", res.t)[2]
    total = res.end_forces.sum(axis=1)  # force of the cable on both holders [N]
    peak = spec.mass * float(np.abs(acc).max())
    assert peak > 0.1  # the test moves something
    assert np.allclose(total, -spec.mass * acc, atol=0.01 * peak)


def test_scene_file_motion_types_and_their_errors():
    scene = Scene.from_dict({
        "cable": {"preset": "lv2017"},
        "motion": [{"type": "waypoints", "end": "last", "times": [0.0, 0.5], "displacements": [[0, 0, 0], [0, 0, 0.01]]},
                   {"type": "sine", "end": "first", "amplitude": [0, 0.001, 0], "frequency": 2.0},
                   {"end": "last", "displacement": [0, 0, 0.001], "start": 0.6, "duration": 0.1}],
    })
    assert [type(m).__name__ for m in scene.motion] == ["Waypoints", "Sine", "Move"]
    assert scene.motion[1].duration == math.inf
    bad = [
        ([{"type": "spiral", "end": "last"}], "motion[0].type must be one of move, waypoints, sine"),
        ([{"type": "waypoints", "end": "last", "times": [0, 1], "displacements": [[0, 0, 0.1], [0, 0, 0]]}],
         "first waypoint must be [0, 0, 0]"),
        ([{"type": "waypoints", "end": "last", "times": [1, 0.5], "displacements": [[0, 0, 0], [0, 0, 0]]}],
         "strictly increasing"),
        ([{"type": "sine", "end": "last", "frequency": -1}], "sine frequency must be a finite number > 0"),
        ([{"type": "sine", "end": "last", "duration": 1.0, "ramp": 0.6}], "sine ramp must be at most half"),
        ([{"type": "sine", "end": "last", "period": 1.0}], "unknown sine motion key(s) period"),
    ]
    for motion, message in bad:
        with pytest.raises(ParameterError) as err:
            parse_motion(motion)
        assert message in str(err.value)
    two = [{"type": "waypoints", "end": "last", "times": [0, 1], "displacements": [[0, 0, 0], [0, 0, 0.01]]}] * 2
    with pytest.raises(ParameterError, match="at most one waypoints entry per end"):
        parse_motion(two)
