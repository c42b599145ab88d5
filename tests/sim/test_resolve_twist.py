"""Twist by need (issue 22, deliverable 3): ``resolve`` and ``n_masses: auto`` switch the material frame on
when a scene rolls a clamp about the cable's axis or holds a non-round section, say why, and leave a round
cable whose clamps never roll with the model (and cost) it had."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from bullet_dlo.analysis.resolve import end_roll, resolve, twist_need
from bullet_dlo.config.scene import Scene
from bullet_dlo.core.boundary import EndHolder, Move, Sine, Waypoints
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.sim import build, resolve_problem, resolved

ROUND = CableSpec.lv2017(n_masses=7, damping_rate=5.0, internal_damping=1e-3)
STRIP = CableSpec(length=0.3, diameter=0.001, mass=0.024, youngs_modulus=2e11, section="rectangle", width=0.01,
                  thickness=0.001, n_masses=7, damping_rate=5.0)
ROLL = Move("last", rotation=(math.pi / 2, 0.0, 0.0), start=0.02, duration=0.1)  # about the axis (cable along x)
SWING = Move("last", displacement=(0.0, 0.0, 0.01), rotation=(0.0, 0.3, 0.2), start=0.02, duration=0.1)


def _quick(problem, seen: list):
    """resolve on one candidate each (the choice is not what is tested here), recording each trial's cable."""
    run = problem.run

    def spy(cable, integrator, dt, duration):
        seen.append(cable.twist_enabled)
        return run(cable, integrator, dt, duration)

    return resolve(replace(problem, run=spy), tol=1.0, target="forces", rollout=0.15, n_masses=(5,),
                   dts=(1e-3,), integrators=("implicit_euler",))


def test_roll_about_the_tangent_is_read_exactly():
    """The swing-twist roll: a turn about the held tangent is all roll; a turn about a normal axis is none,
    even combined with a displacement; a sine about the tangent rolls by its amplitude."""
    d = np.array([1.0, 0.0, 0.0])
    t = np.linspace(0.0, 0.2, 201)
    rolled = end_roll(EndHolder("clamped", np.zeros(3), d, (ROLL,)), t)
    assert rolled[-1] == pytest.approx(math.pi / 2, abs=1e-9) and rolled[0] == 0.0
    assert np.abs(end_roll(EndHolder("clamped", np.zeros(3), d, (SWING,)), t)).max() < 1e-9
    # a roll about the tangent after a swing: the swing-twist decomposition recovers it whatever the swing
    tilted = EndHolder("clamped", np.zeros(3), np.array([0.0, 0.6, 0.8]), (Sine("last", frequency=5.0,
                       rotation=(0.0, 0.3, 0.4), duration=0.2, ramp=0.0),))
    assert np.abs(end_roll(tilted, t)).max() == pytest.approx(0.5, rel=1e-6)
    # a motion whose only rotation is in its last waypoint is sampled (not taken for a translation)
    late = Waypoints("last", times=(0.0, 0.1, 0.2), displacements=((0, 0, 0), (0, 0, 0.01), (0, 0, 0.01)),
                     rotations=((0, 0, 0), (0, 0, 0), (0.4, 0, 0)))
    assert np.abs(end_roll(EndHolder("clamped", np.zeros(3), d, (SWING, late)), t)).max() == pytest.approx(0.4)


def test_a_rolled_clamp_turns_the_frame_on_and_says_why():
    scene = Scene(cable=ROUND, motion=(ROLL,), gravity=(0, 0, 0), duration=0.15)
    seen: list = []
    r = _quick(resolve_problem(scene), seen)
    assert r.twist and all(seen) and "last clamp rolls 90 deg about the cable axis" in r.why
    # what the frame buys: the rolled clamp's moment is the torsion G J (pi/2) / L (1 % at the end of the run)
    spec = ROUND.with_(n_masses=r.n_masses, twist=True)
    res = resolve_problem(scene).run(spec, r.integrator, r.dt, 0.15)
    assert res.end_moments[1, 0] == pytest.approx(-spec.torsional_rigidity * (math.pi / 2) / spec.length, rel=0.01)


def test_a_strip_is_resolved_with_its_frame_and_the_reason():
    scene = Scene(cable=STRIP, motion=(SWING,), duration=0.15, ends=("clamped", "pinned"))
    seen: list = []
    r = _quick(resolve_problem(scene), seen)
    assert r.twist and all(seen) and "rectangle section" in r.why


def test_a_tube_or_strip_scene_says_why_its_frame_is_on():
    """Every path (``resolved``, not only ``auto``) gives a non-round section's reason (it was "": the frame is on
    by the section, so the scene was returned as it was); ``twist: true`` asked for it and keeps ""."""
    for cable in (ROUND.with_(section="tube", inner_diameter=0.002),
                  ROUND.with_(section="rectangle", width=0.01, thickness=0.001)):
        new = resolved(Scene(cable=cable, duration=0.1))
        assert f" {cable.section} section " in new.twist_reason and new.cable == cable
    assert resolved(Scene(cable=ROUND.with_(twist=True), duration=0.1)).twist_reason == ""


def test_a_round_cable_that_never_rolls_keeps_the_model_without_frame():
    """A swinging, moving clamp (no roll), and a pinned end that rotates about the axis (a pin does not hold
    the roll): no frame, and the trials' results are those of the cable without twist."""
    for scene in (Scene(cable=ROUND, motion=(SWING,), duration=0.15),
                  Scene(cable=ROUND, motion=(ROLL,), duration=0.15, ends=("clamped", "pinned"))):
        problem = resolve_problem(scene)
        assert twist_need(problem) == ""
        seen: list = []
        r = _quick(problem, seen)
        assert not r.twist and not any(seen) and "no material frame" in r.why
        spec = ROUND.with_(n_masses=r.n_masses, damping=r.damping)
        a = problem.run(spec, r.integrator, r.dt, 0.05)
        assert spec.twist_enabled is False and a.stable


def test_n_masses_auto_scene_gets_the_frame():
    """``n_masses: auto`` (sim.resolved): the rolled scene comes back with twist on, the still one without."""
    base = Scene(cable=ROUND, gravity=(0, 0, 0), duration=0.12, auto_n=True, tolerance=0.5,
                 tolerance_target="forces")
    assert resolved(replace(base, motion=(ROLL,))).cable.twist_enabled
    assert not resolved(replace(base, motion=(SWING,))).cable.twist_enabled


def test_a_given_number_of_masses_gets_the_frame_too():
    """Twist by need on every path, not only ``auto``: a scene with n given that rolls a clamp by 90 deg comes
    back from ``resolved`` with the frame and its reason, and the built simulation's rolled clamp reads the
    torsion G J (pi/2) / L (before: zero, silently). A swinging clamp leaves the scene as it was."""
    scene = Scene(cable=ROUND, motion=(ROLL,), gravity=(0, 0, 0), duration=0.15)
    new = resolved(scene)
    assert new.cable.twist_enabled and new.cable.n_masses == ROUND.n_masses
    assert "last clamp rolls 90 deg about the cable axis" in new.twist_reason
    with build(scene, "core") as sim:
        res = sim.run()
    spec = new.cable
    assert res.end_moments[1, 0] == pytest.approx(-spec.torsional_rigidity * (math.pi / 2) / spec.length, rel=0.01)
    still = Scene(cable=ROUND, motion=(SWING,), duration=0.15)
    assert resolved(still) is still


def test_the_reason_names_a_roll_past_half_a_turn():
    """The reason reports the largest roll over the run, unwrapped: a clamp rolled 229 deg said "rolls 180 deg"
    (each sample's roll is an angle in [-pi, pi])."""
    turn = Move("last", rotation=(math.radians(229.0), 0.0, 0.0), start=0.02, duration=0.1)
    why = twist_need(resolve_problem(Scene(cable=ROUND, motion=(turn,), duration=0.15)))
    assert "last clamp rolls 229 deg about the cable axis" in why, why
