"""The energy detector without gravity (issue 21): its scale is physical and a turning clamp's work is counted.

Before: the energy balance counted only end force x held-end displacement, and the scale was
M |g| L + the start state's energy + 1e-12 J. A clamp that turns does work through its moment
alone, so with gravity off (scale ~1e-12 J) a valid run was stopped at the first energy check
(step 10) as "energy growth". Now the moment's work joins the balance and EI / L joins the scale.
"""
from __future__ import annotations

import numpy as np
import pytest

from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import DetectorOptions, simulate, start_detector
from bullet_dlo.core.integrators import NewtonOptions, get_integrator, make_stepper
from bullet_dlo.core.kernels.forces import mechanical_energy
from bullet_dlo.core.kernels.holders import empty_samples, sample_holders
from bullet_dlo.core.kernels.loop import make_records, run_loop, start_loop
from bullet_dlo.core.kernels.steppers import make_workspace
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.stability import critical_dt

pytestmark = pytest.mark.core
SPEC = CableSpec(length=0.5, diameter=0.01, mass=0.05, youngs_modulus=1e6, n_masses=20)
TURN = (Move("last", rotation=(0.0, 0.0, 1.0), duration=0.5),)  # the last clamp turns 1 rad about z


def _model(spec=SPEC, motion=TURN):
    return CableModel.straight(spec, gravity=(0.0, 0.0, 0.0), motion=motion)


@pytest.mark.parametrize("integrator", ["implicit_euler", "bdf2", "implicit_midpoint"])
def test_zero_gravity_turning_clamp_runs_to_the_end(integrator):
    """Was stopped at step 10 as energy growth; a turning clamp is a valid run."""
    res = simulate(_model(), integrator, 1e-3, 1.0)
    assert res.stable and res.steps == 1000, (res.reason, res.steps)


def test_energy_balance_closes_with_the_clamp_moment_work():
    """Undamped, energy-conserving midpoint: E(T) - E(0) - W within 2 % of sum |dW|, W counting the moment's
    work (without it W is ~0 here: the turning clamp's only work is through its moment)."""
    model = _model()
    m, plan, dt, steps = model.kernel_arrays(), model.holder_plan(), 2e-4, 5000
    st = model.initial_state()
    samples = empty_samples()
    sample_holders(plan, 0.0, dt, samples)
    det = start_detector(DetectorOptions(), model, m, st.x, st.v, samples)
    stepper = make_stepper(get_integrator("implicit_midpoint"), dt, NewtonOptions())
    x, v = st.x.copy(), st.v.copy()
    loop = start_loop(det)
    status = run_loop(stepper, m, plan, x, v, 0.0, steps, steps, det, make_workspace(model.n),
                      make_records(steps + 3, model.n, 1), loop)
    assert loop.counts[0] == steps and status == 0
    sample_holders(plan, steps * dt, 0.0, samples)
    created = mechanical_energy(m, x, v, samples.dir[0]) - det.e0 - det.work[0]
    floor = SPEC.bending_rigidity / SPEC.length
    moved = det.scale[0] - floor  # sum |dW| (the start state has no energy)
    assert det.work[0] > 0.5 * moved > 0  # the clamp put energy in
    assert abs(created) < 0.02 * moved, (created, det.work[0], moved)


def test_zero_gravity_scale_is_physical_and_independent_of_n():
    """Scale at a straight rest start without gravity: EI / L [J], the same at any n (was 1e-12 J)."""
    scales = []
    for n in (10, 40):
        spec = SPEC.with_(n_masses=n)
        model = _model(spec)
        st = model.initial_state()
        samples = empty_samples()
        sample_holders(model.holder_plan(), 0.0, 1e-3, samples)
        scales.append(start_detector(DetectorOptions(), model, model.kernel_arrays(), st.x, st.v, samples).scale[0])
    assert np.allclose(scales, SPEC.bending_rigidity / SPEC.length, rtol=1e-12)


def test_zero_gravity_blow_up_is_still_caught_as_energy_growth():
    """Symplectic Euler at 3x its critical step without gravity: stopped, and early."""
    model = _model(motion=())
    x0 = model.initial_state()
    rng = np.random.default_rng(0)
    x0.x[1:-1] += 1e-4 * rng.standard_normal((model.n - 2, 3))
    h = 3.0 * critical_dt(model, "symplectic_euler")
    res = simulate(model, "symplectic_euler", h, 2000 * h, state=x0)
    assert not res.stable and res.steps < 2000
    assert res.reason in ("energy growth beyond the work done on the cable", "segment strain beyond bound")
