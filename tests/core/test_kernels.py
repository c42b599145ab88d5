"""The kernels against closed forms: held-end samples, every stepper under uniform gravity,
the mechanical energy, and the Numba cache's view of which modules hold kernels."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bullet_dlo._numba_cache import PACKAGE, kernel_sources
from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.integrators import INTEGRATORS
from bullet_dlo.core.kernels.forces import internal_energy, mechanical_energy
from bullet_dlo.core.kernels.holders import empty_samples, sample_holders
from bullet_dlo.core.model import CableModel, CableState
from bullet_dlo.core.spec import CableSpec


def test_held_samples_follow_minimum_jerk_move():
    disp, rot, start, dur = np.array([0.1, -0.05, 0.02]), np.array([0.0, 0.4, 0.3]), 0.2, 0.5
    model = CableModel.straight(CableSpec.lv2017(n_masses=5), motion=[Move("last", tuple(disp), start, dur,
                                                                            tuple(rot))])
    plan, samples = model.holder_plan(), empty_samples()
    h = 0.01
    for t in (0.0, start + 0.3 * dur, start + dur):
        sample_holders(plan, t, h, samples)
        for k, tk in enumerate((t, t + h / 2, t + h)):
            tau = np.clip((tk - start) / dur, 0.0, 1.0)
            s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
            ds = (30 * tau**2 - 60 * tau**3 + 30 * tau**4) / dur if 0 < tau < 1 else 0.0
            assert np.allclose(samples.pos[k, 1], model.x0[-1] + s * disp, atol=1e-15)
            assert np.allclose(samples.vel[k, 1], ds * disp, atol=1e-14)
            assert np.allclose(samples.dir[k, 1], Rotation.from_rotvec(s * rot).apply(model.last.direction))
            assert np.allclose(samples.pos[k, 0], model.x0[0]) and np.allclose(samples.vel[k, 0], 0.0)
    # acceleration: derivative of the sampled velocity
    eps = 1e-6
    sample_holders(plan, start + 0.3 * dur + eps, 0.0, samples)
    v_plus = samples.vel[0, 1].copy()
    sample_holders(plan, start + 0.3 * dur - eps, 0.0, samples)
    v_minus = samples.vel[0, 1].copy()
    sample_holders(plan, start + 0.3 * dur, 0.0, samples)
    assert np.allclose(samples.acc[0, 1], (v_plus - v_minus) / (2 * eps), rtol=1e-6)


def falling_reference(name: str, g: np.ndarray, h: float, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Displacement and velocity of a body under constant acceleration g after ``steps`` steps of ``name``."""
    x, v = np.zeros(3), np.zeros(3)
    x_prev = v_prev = None
    for k in range(steps):
        if name == "explicit_euler":
            x, v = x + h * v, v + h * g
        elif name in ("symplectic_euler", "implicit_euler") or (name == "bdf2" and k == 0):
            x_old, v_old = x, v
            v = v + h * g
            x = x + h * v
            x_prev, v_prev = x_old, v_old
        elif name == "bdf2":  # x' = (4x - x_prev)/3 + 2h/3 v', v' = (4v - v_prev)/3 + 2h/3 g
            v_new = (4 * v - v_prev) / 3 + 2 * h / 3 * g
            x_new = (4 * x - x_prev) / 3 + 2 * h / 3 * v_new
            x_prev, v_prev, x, v = x, v, x_new, v_new
        else:  # rk4, implicit midpoint: exact for constant acceleration
            x, v = x + h * v + 0.5 * h * h * g, v + h * g
    return x, v


@pytest.mark.parametrize("name", list(INTEGRATORS))
def test_every_stepper_drops_a_free_cable_like_a_point_mass(name):
    """A straight, undamped, free cable in uniform gravity has no internal forces: each node
    follows the method's own constant-acceleration recurrence (BDF2 from its history)."""
    spec = CableSpec.lv2017(n_masses=6, damping=0.0)
    g = np.array([0.0, 0.3, -9.81])
    model = CableModel.straight(spec, ends=("free", "free"), gravity=g)
    h, steps = 1e-3, 7
    res = simulate(model, name, h, steps * h)
    dx, dv = falling_reference(name, g, h, steps)
    assert res.stable and res.steps == steps
    assert np.allclose(res.final_state.x - model.x0, dx, rtol=1e-9, atol=1e-13)
    assert np.allclose(res.final_state.v, dv, rtol=1e-9, atol=1e-13)
    assert np.allclose(res.end_forces, 0.0)  # free ends: nothing holds the cable


def test_mechanical_energy_is_kinetic_plus_elastic_plus_gravitational(rng):
    spec = CableSpec.lv2017(n_masses=8)
    model = CableModel.straight(spec, ends=("clamped", "pinned"))
    a, dirs = model.kernel_arrays(), model.holder_plan().start_dir
    state = CableState(model.x0 + rng.normal(scale=3e-3, size=model.x0.shape), rng.normal(size=model.x0.shape))
    kinetic = 0.5 * np.sum(a.mass[:, None] * state.v**2)
    gravitational = -np.sum(a.mass[:, None] * a.gravity[None, :] * state.x)
    elastic = internal_energy(a, state.x, dirs)
    assert elastic > 0
    assert mechanical_energy(a, state.x, state.v, dirs) == pytest.approx(kinetic + elastic + gravitational, rel=1e-13)


def test_numba_cache_hashes_every_kernel_module_and_the_types_they_take():
    hashed = {p.relative_to(PACKAGE).as_posix() for p in kernel_sources()}
    expected = {f"core/kernels/{name}.py" for name in ("forces", "banded", "holders", "steppers", "monitor", "loop")}
    expected |= {"core/model.py", "bullet/kernels.py"}
    assert expected <= hashed
    assert all(p.is_relative_to(PACKAGE) and p.suffix == ".py" for p in kernel_sources())
