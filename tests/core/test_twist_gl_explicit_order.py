"""Gauss-Legendre and the explicit methods keep their order with a twisting cable (issue 22).

Before, these methods advanced the positions with the twist held, then the twist by an implicit-Euler
sub-step (staggered): first order in the twist and, through it, in the positions (Gauss-Legendre 1.1-1.4,
RK4 1.0-1.2 on the scene below). Now Gauss-Legendre solves the stage twist rates in its collocation system
and RK4 carries the twist angles and rates through its stages (``twist_coupled.coupled_gauss_legendre``,
``explicit_twist``). Errors against the same method at a fine step: positions x, material axes m1 and the
torque about the clamp's axis."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.integrators import NewtonOptions
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec


def _model(internal_damping: float) -> CableModel:
    """The soft strip of ``test_twist_coupled.py`` (rectangle 10 x 1 mm, E 2 GPa, 0.3 m, n = 9), clamped-free,
    its clamp rolled 90 degrees and moved 5 cm sideways, 2 cm up over 0.5 s."""
    spec = CableSpec(length=0.3, diameter=0.001, mass=0.024, youngs_modulus=2e9, section="rectangle", width=0.01,
                     thickness=0.001, n_masses=9, damping_rate=2.0, internal_damping=internal_damping)
    return CableModel.straight(spec, ends=("clamped", "free"), start=(0, 0, 0), roll=(0.3, 0.0),
                               motion=[Move("first", rotation=(math.pi / 2, 0, 0), displacement=(0, 0.05, 0.02),
                                            duration=0.5)])


def _errors(model: CableModel, method: str, duration: float, steps: tuple[int, ...], ref_steps: int) -> np.ndarray:
    """Errors (x [m], m1, axial torque [N m]) at ``duration`` of each step count against ``ref_steps``, (k, 3)."""
    def final(count):
        res = simulate(model, method, duration / count, duration, newton=NewtonOptions(tol=1e-11, max_iter=50))
        assert res.stable
        tw = res.final_state.twist
        m1 = np.cos(tw.theta)[:, None] * tw.ref + np.sin(tw.theta)[:, None] * np.cross(tw.tan, tw.ref)
        return res.x[-1], m1, res.end_moments[0, 0]  # (the clamp's axis stays x)
    xr, mr, tr = final(ref_steps)
    return np.array([[np.abs(x - xr).max(), np.abs(m1 - mr).max(), abs(tq - tr)]
                     for x, m1, tq in (final(c) for c in steps)])


@pytest.mark.parametrize("method, duration, steps, ref_steps, damping", [
    ("gauss_legendre", 0.5, (100, 200), 400, 1e-3),  # dt 5 -> 2.5 ms, Kelvin-Voigt twist dampers on
    ("rk4", 0.01, (100, 200), 800, 0.0),  # dt 0.1 -> 0.05 ms (explicit: no internal damping, its stiff limit)
])
def test_fourth_order_methods_keep_order_four_with_a_twisting_cable(method, duration, steps, ref_steps, damping):
    """Observed: Gauss-Legendre 4.6-5.3 (x, m1), RK4 3.7-4.3 (x, m1, torque); staggered both were 1.0-1.4."""
    err = _errors(_model(damping), method, duration, steps, ref_steps)
    orders = np.log2(err[0] / err[1])
    assert np.all(orders[:2] > 3.5), orders
    if method == "rk4":
        assert orders[2] > 3.5, orders
