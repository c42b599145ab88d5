"""The compiled time loop run in pieces (so that a Ctrl-C stops a long run promptly, issue 26) gives the
one-call run bit for bit: every piece starts where the last one stopped (BDF2's history, the recorded rows,
the detector's balance, the end forces, the step count the holders' times come from)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.core import engine
from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec

pytestmark = pytest.mark.core


def _strip() -> CableModel:
    """A twisting strip (material frame), its clamp rolled and moved: twist state, holder samples and records."""
    spec = CableSpec(length=0.3, diameter=0.001, mass=0.024, youngs_modulus=2e9, section="rectangle", width=0.01,
                     thickness=0.001, n_masses=7, damping_rate=2.0, internal_damping=1e-3)
    return CableModel.straight(spec, ends=("clamped", "free"), start=(0, 0, 0), roll=(0.3, 0.0),
                               motion=[Move("first", rotation=(math.pi / 2, 0, 0), displacement=(0, 0.05, 0.02),
                                            duration=0.1)])


def _stiff() -> CableModel:
    """The study's stiffest cable (Lv, E 1002.6 MPa, n 10), its last clamp moved 5 mm up."""
    spec = CableSpec.lv2017(youngs_modulus=1002.6e6, n_masses=10, damping=0.01)
    motion = [Move("last", (0.0, 0.0, 0.005), 0.02, 0.05)]
    return CableModel.straight(spec, (0.0, 0.0, 0.5), (1.0, 0.0, 0.0), ("clamped", "clamped"), motion)


def _run(monkeypatch, first_piece: int, piece_s: float, *args, **kwargs):
    """The run and the number of calls of the compiled loop it took."""
    monkeypatch.setattr(engine, "FIRST_PIECE", first_piece)
    monkeypatch.setattr(engine, "PIECE_S", piece_s)
    calls = []
    loop = engine.run_loop
    monkeypatch.setattr(engine, "run_loop", lambda *a: calls.append(a[7]) or loop(*a))
    return simulate(*args, **kwargs), len(calls)


@pytest.mark.parametrize("case", ["bdf2", "gauss_legendre", "explicit_euler"])
def test_a_run_in_one_step_pieces_equals_the_run_in_one_call(monkeypatch, case):
    """Pieces of one step each (PIECE_S 0) against one call: the twisting strip with BDF2 (its history) and
    Gauss-Legendre; the study's stiffest cable with explicit Euler, which goes unstable at step 4660."""
    args = (_strip(), case, 1e-3, 0.06) if case != "explicit_euler" else (_stiff(), case, 5e-6, 0.04)
    kwargs = dict(record_every=7, detector=engine.DetectorOptions(check_every=3, energy_every=5))
    one, one_calls = _run(monkeypatch, 10**9, 1e9, *args, **kwargs)
    many, many_calls = _run(monkeypatch, 1, 0.0, *args, **kwargs)
    assert one_calls == 2 and many_calls == one.steps + 1  # a call that loads the kernel, then the steps
    assert one.steps > 20 and many.steps == one.steps and many.stable == one.stable
    assert many.time_to_instability == one.time_to_instability and many.reason == one.reason
    assert (many.newton_iterations, many.newton_failures) == (one.newton_iterations, one.newton_failures)
    for name in ("t", "x", "v", "end_forces", "energy", "end_moments", "end_moment_history"):
        np.testing.assert_array_equal(getattr(many, name), getattr(one, name), err_msg=name)
    for name in ("theta", "omega"):
        np.testing.assert_array_equal(getattr(many.final_state.twist, name), getattr(one.final_state.twist, name))
    assert many.final_state.t == one.final_state.t
