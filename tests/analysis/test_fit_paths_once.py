"""A fit builds each recording's held-end paths once, not once per model run (they took a quarter of a short run's
time), and a recording with other poses gets its own paths."""
from __future__ import annotations

import numpy as np

from bullet_dlo.analysis import fit
from bullet_dlo.analysis.fit import FitOptions, Recording, fit_cable, synthetic_recording
from bullet_dlo.core.boundary import Sine
from bullet_dlo.core.spec import CableSpec

TRUE = CableSpec.lv2017(n_masses=6, damping_rate=2.0)
MOTION = [Sine("last", (0.0, 0.0, 0.02), 2.0, ramp=0.1)]


def test_a_fit_builds_each_recordings_paths_once(monkeypatch):
    built = []
    build = fit.recorded_holders
    monkeypatch.setattr(fit, "recorded_holders", lambda rec, rate: (built.append(id(rec)), build(rec, rate))[1])
    rec = synthetic_recording(TRUE, MOTION, 0.4, rate=200.0)
    res = fit_cable(rec, TRUE, ["damping_rate"], FitOptions(max_evaluations=6, profile_points=0))
    assert res.evaluations >= 3  # the model ran several times
    assert built == [id(rec)]
    moved = Recording(rec.t, rec.grasp_pos + np.array([0.0, 0.0, 0.01]), rec.grasp_quat, rec.force)
    first, _ = fit.holder_paths(moved, FitOptions().knot_rate)
    assert len(built) == 2 and np.allclose(first.position, rec.grasp_pos[0, 0] + [0.0, 0.0, 0.01])
