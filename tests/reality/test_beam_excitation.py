"""residual_excitation: what a rest-to-rest base motion leaves in a mode, against closed forms and an ODE solver."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from bullet_dlo.reality.vibration import residual_excitation

D, T = 0.3, 0.55  # [m], [s]: a cycloidal rest-to-rest move, x = D (t/T - sin(2 pi t/T) / (2 pi))


def cycloid(dt: float = 1e-4) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(0.0, T + dt / 2, dt)
    return t, D * (t / T - np.sin(2 * np.pi * t / T) / (2 * np.pi))


@pytest.mark.parametrize("f", [2.9, 3.0, 5.0])
def test_undamped_residual_matches_closed_form(f):
    t, x = cycloid()
    w, big_w = 2 * np.pi * f, 2 * np.pi / T
    closed = (2 * np.pi * D / T**2) * big_w * 2 * abs(np.sin(w * T / 2)) / abs(big_w**2 - w**2) / w
    assert residual_excitation(t, x, T, f) == pytest.approx(closed, rel=1e-4)


def test_motion_that_cancels_the_mode_leaves_nothing():
    t, x = cycloid()
    f = 2.0 / T  # omega T = 4 pi: the cycloid's acceleration has no content there
    assert residual_excitation(t, x, T, f) < 1e-9 * residual_excitation(t, x, T, 0.9 * f)


def test_damped_residual_matches_ode():
    t, x = cycloid()
    f, z = 2.9, 0.03
    w = 2 * np.pi * f
    wd = w * np.sqrt(1 - z * z)
    acc = lambda s: (2 * np.pi * D / T**2) * np.sin(2 * np.pi * s / T)
    sol = solve_ivp(lambda s, y: [y[1], -acc(s) - 2 * z * w * y[1] - w * w * y[0]], (0, T), [0, 0],
                    rtol=1e-10, atol=1e-12)
    u, v = sol.y[:, -1]
    assert residual_excitation(t, x, T, f, z) == pytest.approx(np.hypot(u, (v + z * w * u) / wd), rel=1e-4)
    assert residual_excitation(t, x, T, f, z) != pytest.approx(residual_excitation(t, x, T, f), rel=1e-2)


def test_bad_input():
    t, x = cycloid()
    with pytest.raises(ValueError, match="damping_ratio"):
        residual_excitation(t, x, T, 2.9, 1.5)
