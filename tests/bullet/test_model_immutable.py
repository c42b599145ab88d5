"""The model is read only: runs, grasps, releases and grips write the control and the state, never the model.

A :class:`~bullet_dlo.core.model.CableModel` is shared by every run and every cable built from it, so its
arrays are write-protected and what changes while a cable runs lives apart: the twist state in the
:class:`~bullet_dlo.core.model.CableState`, the end holds, clamp springs, holder poses, grips and external
forces in the :class:`~bullet_dlo.core.model.CableControl`. (Before, a twisting run advanced the twist state
inside the model's arrays, so a second run of the same model from the same state continued the first one's
twist instead of repeating it.)
"""
from __future__ import annotations

import math
from dataclasses import FrozenInstanceError

import numpy as np
import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.model import CableModel, CableState
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError

STRIP = CableSpec(length=0.3, mass=0.03, youngs_modulus=126e6, n_masses=10, damping=0.01, section="rectangle",
                  width=0.006, thickness=0.002, diameter=0.006)


def _model_bytes(model: CableModel) -> list[bytes]:
    return [a.tobytes() for a in model.arrays] + [model.x0.tobytes(), model.gravity.tobytes()]


def test_writing_to_the_model_raises():
    model = CableModel.straight(STRIP, ends=("clamped", "free"))
    for name, a in zip(model.arrays._fields, model.arrays):
        assert not a.flags.writeable, name
        with pytest.raises(ValueError, match="read-only"):
            a[...] = 0
    for a in (model.x0, model.gravity):
        with pytest.raises(ValueError, match="read-only"):
            a[...] = 0.0
    with pytest.raises(FrozenInstanceError):
        model.arrays = model.arrays  # type: ignore[misc]


def test_twisting_runs_grasp_release_and_grip_leave_the_model_unchanged():
    """Two core runs of one model from one explicit state, the last clamp rolling 90 degrees, twist the strip
    (the end segment turns with the clamp) and give the same bits; then a Bullet cable built from the model is
    grasped, released, gripped by friction, loaded and weighted: the model's arrays stay bit for bit as built
    (the cable's added mass is in a new model of its own)."""
    roll = Move("last", rotation=(math.pi / 2, 0.0, 0.0), start=0.0, duration=0.1)
    model = CableModel.straight(STRIP, ends=("clamped", "clamped"), motion=[roll])
    before = _model_bytes(model)
    rng = np.random.default_rng(0)
    x = model.x0 + 1e-4 * rng.standard_normal(model.x0.shape) * [0, 1, 1]
    x[[0, -1]] = model.x0[[0, -1]]
    state = CableState(x, np.zeros_like(x))
    first = simulate(model, "implicit_euler", 1e-3, 0.15, state=state)
    again = simulate(model, "implicit_euler", 1e-3, 0.15, state=state)
    assert first.stable and again.stable
    assert _model_bytes(model) == before  # (the old model arrays carried the twist state: the run wrote it)
    assert np.array_equal(first.final_state.x, again.final_state.x)  # (the second run continued the twist)
    # the end segment turned with the clamp (to within the twist over one segment, L/(n-1) of pi/2)
    assert first.final_state.twist.theta[-1] == pytest.approx(math.pi / 2, abs=0.25)
    assert np.array_equal(first.final_state.twist.theta, again.final_state.twist.theta)

    with BulletWorld(dt=1e-3) as world:
        cable = world.add_cable(model, integrator="implicit_euler")
        axis = (1.0, 0.0, 0.0)
        zero = np.zeros(3)
        for end, node in ((0, 0), (1, -1)):
            cable.set_external_pose(end, cable.x[node].copy(), zero, zero, zero, axis)
        cable.hold_externally(0, "clamped")
        world.run(0.02)
        cable.release(1)
        cable.grip_with_friction(1, 1.0, 0.5, 0.3)
        cable.set_external_force(4, (0.0, 0.0, -0.05))
        with pytest.raises(ParameterError, match="node must be in"):
            cable.set_external_force(10, (0.0, 0.0, -0.05))
        world.run(0.02)
        cable.release(0)
        cable.hold_externally(0, "pinned")
        cable.add_point_mass(3, 0.01)
        cable.set_parameters(damp=2.0 * cable.model.arrays.mass)
        world.run(0.02)
        assert cable.stable, cable.reason
        assert cable.model.arrays.mass[3] == pytest.approx(model.arrays.mass[3] + 0.01, rel=1e-12)
        assert np.all(cable.twist.flag == 1)  # the cable's own twist state was built and advanced
    assert _model_bytes(model) == before
