"""Clamp moments of every recorded state (``SimulationResult.end_moment_history``), not only the final one."""
from __future__ import annotations

import numpy as np
import pytest

from bullet_dlo.analysis.closed_forms import cantilever_model
from bullet_dlo.core.boundary import Sine
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.kernels.forces import clamp_torque
from bullet_dlo.core.kernels.holders import empty_samples, sample_holders
from bullet_dlo.core.model import CableModel, CableState
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.statics import solve_static


def test_cantilever_clamp_moment_is_m_g_l_over_2_in_every_recorded_state():
    """A stiff cantilever started at its static shape: M g L / 2 about y at every row (closed form)."""
    spec = CableSpec.lv2017(n_masses=10, damping=0.05, youngs_modulus=5e9)
    model = cantilever_model(spec)
    state = CableState(solve_static(model).x, np.zeros((model.n, 3)), 0.0)
    res = simulate(model, "implicit_midpoint", 1e-3, 0.5, state=state, record_every=5)
    hist = res.end_moment_history
    assert hist.shape == (len(res.t), 2, 3) and len(res.t) == 101
    expected = spec.mass * 9.81 * spec.length / 2
    assert np.allclose(hist[:, 0, 1], expected, rtol=1e-2)
    assert np.allclose(hist[:, 0, [0, 2]], 0.0, atol=1e-9) and np.allclose(hist[:, 1], 0.0)  # free far end
    assert np.array_equal(hist[-1], res.end_moments)  # the last row is the final state's moment


def test_history_is_the_clamp_torque_of_each_recorded_moving_state():
    spec = CableSpec.lv2017(n_masses=8, damping_rate=2.0, internal_damping=0.01)
    model = CableModel.straight(spec, ends=("clamped", "clamped"),
                                motion=[Sine("first", (0.0, 0.0, 0.02), 2.0, rotation=(0.0, 0.3, 0.0))])
    res = simulate(model, "bdf2", 1e-3, 0.6, record_every=10)
    assert res.stable
    samples = empty_samples()
    for r in range(0, len(res.t), 7):
        sample_holders(model.holder_plan(), res.t[r], 0.0, samples)
        for e in (0, 1):
            want = clamp_torque(model.kernel_arrays(), res.x[r], res.v[r], samples.dir[0], e)
            assert res.end_moment_history[r, e] == pytest.approx(want, rel=1e-12, abs=1e-15)
    assert np.ptp(res.end_moment_history[:, 0, 1]) > 1e-3  # the moment really changes over the motion


def test_twisting_cable_history_follows_the_torsion_of_each_recorded_state():
    """A clamp turned about the cable's axis by a minimum-jerk angle theta(t) over 1 s: each row's moment about
    the axis is G J theta(t) / L (slow twist: quasi-static). The moment depends on the twist angles, which are
    state but not recorded: taken after the run from the final twist it read G J (pi/2) / L from t = 0 on."""
    import math

    from bullet_dlo.core.boundary import Move

    spec = CableSpec(length=0.5, diameter=0.01, mass=0.1, youngs_modulus=1e7, n_masses=11, twist=True,
                     internal_damping=0.01)
    model = CableModel.straight(spec, start=(0, 0, 0), direction=(1, 0, 0), ends=("clamped", "clamped"),
                                motion=[Move("last", rotation=(math.pi / 2, 0, 0), duration=1.0)], gravity=(0, 0, 0))
    res = simulate(model, "bdf2", 1e-3, 1.5, record_every=100)
    s = np.clip(res.t, 0.0, 1.0)
    theta = (math.pi / 2) * (10 * s**3 - 15 * s**4 + 6 * s**5)
    torsion = spec.effective_shear_modulus * math.pi * spec.diameter**4 / 32 / spec.length * theta
    np.testing.assert_allclose(res.end_moment_history[:, 0, 0], torsion, rtol=0.01, atol=1e-3 * torsion.max())
    np.testing.assert_allclose(res.end_moment_history[:, 1, 0], -torsion, rtol=0.01, atol=1e-3 * torsion.max())
