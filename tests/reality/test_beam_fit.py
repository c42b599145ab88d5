"""A beam_handling recording as ``fit``'s Recording (issue 21 item 1): the strip clamped at the flange and
following it, its tip free, Franka's filtered external-torque estimate as the residual (-J^T of the clamp load
moved to the flange, through the estimate filter, as changes since the first sample)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bullet_dlo.analysis.fit import FitOptions, model_run
from bullet_dlo.analysis.fit_recording import ModelRun, low_pass_delayed, predicted
from bullet_dlo.reality import beam
from bullet_dlo.reality.beam_validate import measure
from bullet_dlo.reality.vibration import residual_vibration

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "beam_handling"
FILE = DATA / "ocp_Z_25cm_0.50s_1.csv"


def test_low_pass_after_a_delay_has_the_closed_form_step_response():
    """A unit step at t = 0.1 s through a 5 Hz first-order low-pass after 20 ms: zero until 0.12 s, then
    1 - exp(-2 pi 5 (t - 0.12)), exact at the samples (the discretisation is exact for a held input)."""
    t = np.arange(0.0, 1.0, 1e-3)
    y = (t >= 0.1 - 1e-12).astype(float)[:, None]
    out = low_pass_delayed(y, t, 5.0, 0.02)[:, 0]
    later = t >= 0.12 - 1e-12
    assert np.all(out[~later] == 0.0)
    expect = 1.0 - np.exp(-2 * math.pi * 5.0 * (t[later] - 0.12 + 1e-3))
    assert np.allclose(out[later], expect, atol=1e-12)
    assert np.array_equal(beam.EstimateFilter(5.0, 0.02).apply(y, 1000.0), low_pass_delayed(y, t, 5.0, 0.02))


@pytest.mark.bullet
@pytest.mark.skipif(not FILE.is_file(), reason=f"beam_handling data not found at {DATA} (../shared/data)")
def test_the_recordings_linear_map_is_minus_jt_of_the_flange_wrench_and_the_strip_rings_at_the_measured_frequency():
    """The map applied to a clamp load equals -J^T of that load moved to the flange origin (checked against the
    Panda's own Jacobian); and the rectangle-section strip with a material frame, run by fit's machinery from
    the measured joints with nominal steel, rings at the measured residual-vibration frequency within 2 %
    (no fitting)."""
    from bullet_dlo.reality.panda import Panda, external_torques

    rec = beam.read_beam_csv(FILE)
    with Panda() as panda:
        r = beam.fit_recording(rec, panda, step=4)
        i = len(r.t) // 3
        q = beam.sosfiltfilt(beam.butter(4, beam.Numerics().q_cutoff_hz, fs=rec.rate, output="sos"), rec.q, axis=0)[4 * i]
        fpos, frot = panda.flange_pose(q)
        jac = panda.jacobian(q)
    f, m = np.array([1.0, -2.0, 3.0]), np.array([0.1, 0.2, -0.3])
    arm = r.grasp_pos[i, 0] - fpos
    expect = external_torques(jac, np.r_[f, m + np.cross(arm, f)])
    assert np.allclose(r.linear_map[i] @ np.r_[f, m, np.zeros(6)], expect, atol=1e-9)
    assert r.held == ("clamped", "free") and r.section_frame and r.length == beam.Strip().length
    spec = beam.Strip().rectangle_spec(10, damping_rate=0.24)
    run = model_run(spec, r, FitOptions(integrator="bdf2", dt=1e-3, start="static", knot_rate=250.0))
    assert isinstance(run, ModelRun)
    meas = measure(rec)
    pred = residual_vibration(r.t, predicted(r, "linear", run)[:, meas.joint], meas.t_end)
    assert abs(pred.frequency_hz / meas.vibration.frequency_hz - 1.0) < 0.02, (pred, meas.vibration)
