"""Fork ends (issue 22): an end held in position and in roll about the holder's axis, its direction free (a fork
support; a ball joint whose roll is locked). Checked against closed forms: a fork's free direction (no bending
moment), every method's torsion at a rolled fork, and the lateral-torsional buckling of a strip between forks under
a midspan load. Greenhill's problem between forks is in ``test_greenhill.py``, pure torsion and a fork turned in a
run in ``test_twist.py``, a scene file with forks in ``tests/sim/test_fork_scene.py``."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from bullet_dlo.core.boundary import EndHolder, Move
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.enums import EndMode
from bullet_dlo.core.kernels.twist import twist_ready, twist_solve, update_frames
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.statics import solve_static
from bullet_dlo.core.validate import ParameterError
from condensed import lowest_condensed_stiffness


def test_fork_is_an_end_mode_that_holds_the_roll_and_not_the_direction():
    assert [m.holds_roll for m in EndMode] == [False, False, True, True]
    model = CableModel.straight(CableSpec.lv2017(n_masses=8, twist=True), ends=("fork", "pinned"))
    a = model.arrays
    assert a.k_bend[0] == 0.0 and a.held[0] and a.held[-1]  # no bending spring: the direction is free
    assert a.tw.k_twist[0] > 0.0 and a.tw.k_twist[-1] == 0.0  # the fork holds the twist, the pin does not
    with pytest.raises(ParameterError, match="free, pinned, fork, clamped"):
        EndHolder("forked", np.zeros(3), np.array([1.0, 0.0, 0.0]))


def test_a_fork_lets_the_direction_turn_freely():
    """Under gravity a cable between forks (not rolled) sags exactly as between pins: no bending moment at a
    fork, and no twist (the end moments are 0); between clamps it sags otherwise (the test can fail)."""
    spec = CableSpec.lv2017(n_masses=12, twist=True, damping_rate=20.0)

    def settle(ends):
        res = simulate(CableModel.straight(spec, ends=ends), "bdf2", 2e-3, 2.0)
        assert res.stable
        return res

    fork, pin, clamp = settle(("fork", "fork")), settle(("pinned", "pinned")), settle(("clamped", "clamped"))
    sag = pin.x[-1, :, 2].min() - pin.x[0, :, 2].min()
    assert sag < -1e-3  # the cable sags (6 mm)
    assert np.abs(fork.x[-1] - pin.x[-1]).max() < 1e-9 * abs(sag)
    assert np.abs(clamp.x[-1] - pin.x[-1]).max() > 0.05 * abs(sag)
    weight = spec.mass * 9.81
    assert np.abs(fork.end_moments).max() < 1e-9 * weight * spec.length
    assert np.abs(clamp.end_moments).max() > 0.01 * weight * spec.length


# ----- lateral-torsional buckling between forks -------------------------------------------------------------
GAMMA_MIDSPAN = 16.936  # P_c L^2 / sqrt(E I_weak G J): a midspan load at the centroid between forks


def strip(n: int) -> CableSpec:
    """A steel strip 0.5 m x 20 mm x 1 mm (width along y, thickness along z when laid along x)."""
    return CableSpec(length=0.5, diameter=0.001, mass=7850 * 0.5 * 0.02 * 0.001, youngs_modulus=2e11,
                     section="rectangle", width=0.02, thickness=0.001, n_masses=n)


def closed_form(spec: CableSpec) -> float:
    """P_c [N] of the strip between forks under a midspan load at its centroid."""
    return GAMMA_MIDSPAN * math.sqrt(min(spec.bending_rigidities) * spec.torsional_rigidity) / spec.length**2


def on_a_roller(spec: CableSpec, f_ext: np.ndarray) -> tuple[CableModel, np.ndarray]:
    """The model between forks whose last fork stands where the loaded strip pulls it neither way along the span,
    and the loaded equilibrium there [m], (n, 3). The textbook's beam rests on a roller at one end; between two
    immovable supports the sag stretches the strip, and the membrane tension stiffens it sideways (measured: the
    strip between immovable forks buckles at 1.74x the closed form at n = 11, its lateral stiffness with the twist
    held growing as the load squared)."""
    model = CableModel.straight(spec, ends=("fork", "fork"), start=(0, 0, 0), gravity=(0, 0, 0))
    n, ea, span = spec.n_masses, spec.axial_rigidity, spec.length
    for _ in range(4):  # the span force is linear in the span: each pass leaves about (sag / span)^2 of it
        x0 = np.outer(np.linspace(0.0, span, n), (1.0, 0.0, 0.0))
        model = replace(model, last=replace(model.last, position=x0[-1].copy()), x0=x0)
        res = solve_static(model, f_ext=f_ext)
        assert res.converged
        e = res.x[1] - res.x[0]
        pull = ea * (np.linalg.norm(e) / spec.rest_length - 1.0) * e[0] / np.linalg.norm(e)  # [N] along the span
        span -= pull * span / ea
    assert abs(pull) < 1e-4 * abs(f_ext).sum(), pull  # (the static solve's round-off: strain 1e-10)
    return model, res.x


def loaded_stiffness(spec: CableSpec, load: float) -> float:
    """Lowest eigenvalue [N/m] of the condensed stiffness (twist angles in equilibrium at every position) at the
    equilibrium under ``load`` [N] at the middle node along the width (y), the last fork on a roller."""
    n = spec.n_masses
    f_ext = np.zeros((n, 3))
    f_ext[n // 2, 1] = load
    model, x0 = on_a_roller(spec, f_ext)
    m = model.kernel_arrays()
    dirs = model.holder_plan().start_dir
    twist_ready(m, model.x0, dirs)
    assert np.abs(x0[:, 2]).max() < 1e-12  # in its plane until it buckles
    update_frames(m, x0, dirs)
    twist_solve(m, x0, dirs, 1.0, False, m.tw_mref)
    return lowest_condensed_stiffness(m, x0, dirs, slice(1, -1), 1e-7 * spec.length)


def critical_load(n: int, tol: float = 1e-5) -> float:
    """P_c / closed form of the n-mass strip between forks, by bisection on the load."""
    spec = strip(n)
    pc = closed_form(spec)
    lo, hi = 0.9, 1.1
    assert loaded_stiffness(spec, lo * pc) > 0 > loaded_stiffness(spec, hi * pc)
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if loaded_stiffness(spec, mid * pc) > 0 else (lo, mid)
    return 0.5 * (lo + hi)


def test_strip_between_forks_buckles_sideways_at_the_lateral_torsional_load():
    """Simply supported in bending and held in twist at both ends (forks, the last on a roller), a midspan load
    at the centroid along the width: P_c = 16.936 sqrt(E I_weak G J) / L^2 (Timoshenko & Gere, Theory of Elastic
    Stability, sec. 6.3: 16.94; here the root of C phi'' + (P x / 2)^2 / (E I_weak) phi = 0, phi(0) = 0,
    phi'(L/2) = 0). Measured P_c / closed form: 0.99741 (n = 11), 0.99961 (21), 1.00019 (41): second order.
    Without the forks' hold on the twist the strip would roll over under any load."""
    ratios = {n: critical_load(n) for n in (11, 21, 41)}
    assert abs(ratios[21] - 1.0) < 0.005, ratios
    d_coarse, d_fine = ratios[21] - ratios[11], ratios[41] - ratios[21]
    order = math.log(d_coarse / d_fine) / math.log(2.0)
    assert 1.7 < order < 2.3, (ratios, order)
    limit = ratios[41] + d_fine / (2.0**order - 1.0)  # Richardson
    assert limit == pytest.approx(1.0, abs=0.003), limit


@pytest.mark.parametrize("integrator, dt", [("gauss_legendre", 1e-3), ("symplectic_euler", 1e-5)])
def test_every_method_carries_a_fork_s_twist(integrator, dt):
    """Gauss-Legendre (the twist in its collocation system) and an explicit method (through its stages) read the
    same torsion at a rolled fork, under gravity, as the implicit steps: G J (pi/2) / L within 0.1 %; a fork's
    moment normal to the axis stays small against a clamp's, which also carries the sag's bending."""
    spec = CableSpec.lv2017(n_masses=11, twist=True, damping_rate=5.0, internal_damping=1e-3)
    roll = [Move("last", rotation=(math.pi / 2, 0, 0), duration=0.4)]
    expected = spec.torsional_rigidity * (math.pi / 2) / spec.length
    fork = simulate(CableModel.straight(spec, ends=("fork", "fork"), motion=roll), integrator, dt, 0.8)
    clamp = simulate(CableModel.straight(spec, ends=("clamped", "clamped"), motion=roll), integrator, dt, 0.8)
    assert fork.stable and clamp.stable
    assert fork.end_moments[0, 0] == pytest.approx(expected, rel=1e-3)
    assert fork.end_moments[1, 0] == pytest.approx(-expected, rel=1e-3)
    normal = np.linalg.norm(fork.end_moments[:, 1:], axis=1).max()
    assert normal < 0.1 * expected < np.linalg.norm(clamp.end_moments[:, 1:], axis=1).max()
