"""Lateral-torsional buckling (issue 22): a cantilever strip, tall in the load plane (the tip load P along its
width, the stiff axis), buckles sideways with twist when P reaches

    P_c = 4.013 sqrt(E I_weak G J) / L^2

(Prandtl 1899 / Michell 1899 for a load at the centroid of the free end; Timoshenko & Gere, Theory of Elastic
Stability, sec. 6.3, gamma_1 = 4.013 for E I_weak / E I_strong -> 0). The section chosen (b/h = 20) makes
the prebuckling deflection's correction 1 / sqrt((1 - E I_weak / E I_strong)(1 - G J / E I_strong)) - 1 =
+0.3 %, inside the tolerance. Found as the load at which the loaded equilibrium's stiffness (positions,
with the twist angles in equilibrium at every position: the static condensation) loses definiteness, by
bisection; the dead tip load adds no stiffness."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.core.engine import simulate
from bullet_dlo.core.kernels.twist import twist_ready, twist_solve, update_frames
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.statics import solve_static
from condensed import lowest_condensed_stiffness

GAMMA = 4.013  # P_c L^2 / sqrt(E I_weak G J), tip load at the centroid, no warping stiffness


def strip(n: int) -> CableSpec:
    """A steel strip 0.5 m x 20 mm x 1 mm (width along y, thickness along z when laid along x)."""
    return CableSpec(length=0.5, diameter=0.001, mass=7850 * 0.5 * 0.02 * 0.001, youngs_modulus=2e11,
                     section="rectangle", width=0.02, thickness=0.001, n_masses=n)


def closed_form(spec: CableSpec) -> float:
    """P_c [N] of the strip cantilever."""
    ei_weak = min(spec.bending_rigidities)
    return GAMMA * math.sqrt(ei_weak * spec.torsional_rigidity) / spec.length**2


def loaded_stiffness(spec: CableSpec, load: float) -> tuple[float, float]:
    """Lowest eigenvalue [N/m] of the condensed stiffness at the equilibrium under the tip load [N] along the
    width (y), and that equilibrium's tip deflection along the thickness (z) [m] (0: unbuckled)."""
    model = CableModel.straight(spec, ends=("clamped", "free"), start=(0, 0, 0), gravity=(0, 0, 0))
    n = spec.n_masses
    m = model.kernel_arrays()
    dirs = model.holder_plan().start_dir
    twist_ready(m, model.x0, dirs)  # builds the material frame (straight, untwisted)
    f_ext = np.zeros((n, 3))
    f_ext[-1, 1] = load
    res = solve_static(model, f_ext=f_ext)
    assert res.converged
    x0 = res.x
    update_frames(m, x0, dirs)  # frames transported to the loaded state (where the DER gradients are exact)
    twist_solve(m, x0, dirs, 1.0, False, m.tw_mref)
    return lowest_condensed_stiffness(m, x0, dirs, slice(1, None), 1e-7 * spec.length), float(x0[-1, 2])


def critical_load(n: int, tol: float = 1e-6) -> float:
    """P_c / closed form of the n-mass strip, by bisection on the load (to ``tol``)."""
    spec = strip(n)
    pc = closed_form(spec)
    lo, hi = 0.9, 1.1
    low, side = loaded_stiffness(spec, lo * pc)
    assert low > 0 > loaded_stiffness(spec, hi * pc)[0]
    assert abs(side) < 1e-12  # the loaded strip stays in its plane until it buckles
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if loaded_stiffness(spec, mid * pc)[0] > 0 else (lo, mid)
    return 0.5 * (lo + hi)


def test_cantilever_strip_buckles_sideways_at_the_lateral_torsional_load():
    """Measured P_c / (4.013 sqrt(E I_weak G J) / L^2): 1.00759 (n = 11), 1.00469 (21), 1.00387 (41),
    1.00365 (81); successive differences shrink 3.52x, 3.73x (order 1.8, 1.9: second order), towards
    1.0036, the prebuckling correction's +0.3 % (which the 3 % tolerance of the issue contains)."""
    ratios = {n: critical_load(n) for n in (11, 21, 41)}
    for n, r in ratios.items():
        assert abs(r - 1.0) < 0.03 if n == 11 else abs(r - 1.0) < 0.01, (n, r)
    d_coarse, d_fine = ratios[11] - ratios[21], ratios[21] - ratios[41]
    order = math.log(d_coarse / d_fine) / math.log(2.0)
    assert 1.6 < order < 2.2, (ratios, order)
    limit = ratios[41] - d_fine / (2.0**order - 1.0)  # Richardson
    assert limit == pytest.approx(1.0 + 0.003, abs=0.002), limit


@pytest.mark.parametrize("load", [0.97, 1.03])
def test_the_time_stepper_buckles_only_above_the_threshold(load):
    """The staggered implicit step (positions, then the twist sub-step) from the loaded equilibrium with a
    lateral imperfection (a tip load 1e-4 P_c along the thickness, linear deflection d0): 3 % below P_c the
    strip settles near its plane (measured 11 d0, twist 0.002 rad at t = 3 s); 3 % above it leaves it,
    bending sideways with twist (measured 790 d0, twist 0.15 rad): the threshold of the dynamics is within
    +-3 % of the closed form, like the stiffness's."""
    spec = strip(21).with_(damping_rate=2.0)
    pc = closed_form(spec)
    model = CableModel.straight(spec, ends=("clamped", "free"), start=(0, 0, 0), gravity=(0, 0, 0))
    f = np.zeros((spec.n_masses, 3))
    f[-1, 1], f[-1, 2] = load * pc, 1e-4 * pc
    state = solve_static(model, f_ext=f).state()
    d0 = 1e-4 * pc * spec.length**3 / (3 * min(spec.bending_rigidities))
    res = simulate(model, "implicit_euler", 1e-3, 3.0, state=state, f_ext=f)
    assert res.stable
    side, twist = abs(res.x[-1, -1, 2]) / d0, abs(res.final_state.twist.theta[-1])
    if load < 1:
        assert side < 30 and twist < 0.01, (side, twist)
    else:
        assert side > 300 and twist > 0.05, (side, twist)
