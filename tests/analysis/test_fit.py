"""``fit_cable``: cable parameters recovered from synthetic wrist forces (core model, sensor noise on),
within their stated standard errors; a static hold reports the damping as not identifiable."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.analysis.fit import FitOptions, Recording, fit_cable, log_variances, synthetic_recording
from bullet_dlo.core.boundary import Sine
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError

TRUE = CableSpec.lv2017(n_masses=8, damping_rate=2.0, internal_damping=0.01)
START = TRUE.with_(youngs_modulus=8e7, mass=0.02, damping_rate=0.5, internal_damping=3e-3)  # the fit's guess
STRETCH_AND_BEND = [Sine("last", (0.0005, 0.0, 0.0), 2.0, start=0.1, ramp=0.2),  # +-0.5 mm along the cable
                    Sine("first", (0.0, 0.0, 0.02), 1.5, start=0.2, ramp=0.2, rotation=(0.0, 0.2, 0.0))]
NOISE = 0.005  # [N] per force component


def test_informative_motion_recovers_every_parameter_within_its_standard_error():
    rec = synthetic_recording(TRUE, STRETCH_AND_BEND, 1.5, rate=200.0, noise=NOISE, seed=1)
    res = fit_cable(rec, START)
    assert res.success and not res.warnings
    assert set(res.values) == {"youngs_modulus", "internal_damping", "damping_rate", "mass"}
    for name, value in res.values.items():
        truth = getattr(TRUE, name)
        assert abs(value - truth) <= 3.0 * res.standard_errors[name], name  # the stated uncertainty holds
        limit = 0.03 if name in ("youngs_modulus", "mass") else 0.10
        assert abs(value / truth - 1.0) < limit, name
        assert res.identifiable[name]
    assert res.sigma == pytest.approx(NOISE, rel=0.1)  # the residual is the sensor noise, nothing else
    assert res.condition < 100.0


def test_static_hold_reports_the_damping_as_not_identifiable():
    rec = synthetic_recording(TRUE, [], 0.5, rate=200.0, noise=NOISE, seed=2)
    res = fit_cable(rec, START)
    for name in ("internal_damping", "damping_rate"):
        assert not res.identifiable[name]
        assert any(w.startswith(f"{name} is not identifiable") for w in res.warnings)
    for name in ("youngs_modulus", "mass"):  # the sag still gives stiffness and weight
        assert res.identifiable[name]
        assert abs(res.values[name] - getattr(TRUE, name)) <= 3.0 * res.standard_errors[name]
        assert res.relative_se[name] < 0.05
    assert not math.isfinite(res.condition) or res.condition > 1e8


def test_covariance_is_the_linear_regression_one_and_blind_directions_are_infinite():
    rng = np.random.default_rng(0)
    jac = rng.normal(size=(50, 2))
    var, cond = log_variances(jac, 0.25)
    assert np.allclose(var, 0.25 * np.diag(np.linalg.inv(jac.T @ jac)))
    assert cond == pytest.approx(np.linalg.cond((jac / np.linalg.norm(jac, axis=0)).T @ (jac / np.linalg.norm(jac, axis=0))))
    var, cond = log_variances(np.c_[jac, np.zeros(50)], 0.25)
    assert np.isinf(var[2]) and np.all(np.isfinite(var[:2])) and np.isinf(cond)


def test_bad_recordings_and_parameter_names_are_refused():
    t = np.linspace(0.0, 1.0, 5)
    with pytest.raises(ParameterError, match=r"recording force must be finite with shape \(5, 2, 3\)"):
        Recording(t, np.zeros((5, 2, 3)), np.tile([0, 0, 0, 1.0], (5, 2, 1)), np.zeros((5, 3)))
    rec = Recording(t, np.zeros((5, 2, 3)) + [[[-0.15, 0, 0.3], [0.15, 0, 0.3]]], np.tile([0, 0, 0, 1.0], (5, 2, 1)),
                    np.zeros((5, 2, 3)))
    with pytest.raises(ParameterError, match="fit parameters must be distinct names"):
        fit_cable(rec, TRUE, ["youngs_modulus", "length"])
    with pytest.raises(ParameterError, match="start must be one of auto, static, straight, recorded"):
        FitOptions(start="settled")


def test_a_linear_map_of_the_end_wrenches_is_a_residual_kind_of_its_own():
    """y = A w with A picking the left arm's force (what -J^T w does for joint torques): fitting it alone
    recovers the stiffness as the forces do."""
    rec = synthetic_recording(TRUE, STRETCH_AND_BEND[:1], 0.6, rate=200.0, noise=NOISE, seed=4)
    k = len(rec.t)
    pick = np.zeros((k, 3, 12))
    pick[:, :, :3] = np.eye(3)
    lin = Recording(rec.t, rec.grasp_pos, rec.grasp_quat, None, linear_map=pick, linear_obs=rec.force[:, 0])
    assert lin.kinds() == ["linear"]
    res = fit_cable(lin, TRUE, ["youngs_modulus"], FitOptions(max_evaluations=10, profile_points=0))
    lo, hi = res.intervals["youngs_modulus"]
    assert lo <= TRUE.youngs_modulus <= hi and hi / lo - 1 < 0.05
    assert res.to_dict()["per_recording"][0]["linear"]["rms"] == pytest.approx(NOISE, rel=0.2)
