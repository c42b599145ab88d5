"""The beam_handling strip as one rectangle-section cable (``strip_model="rectangle"``) against closed forms
and against the planar pair; the quadratic-drag damping ratio against its closed form. No PyBullet, no data."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.core.engine import simulate
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.statics import solve_static
from bullet_dlo.reality.beam import Numerics, Strip, plane_runs, run_plane, run_rectangle
from bullet_dlo.reality.vibration import drag_damping_ratio, fit_damped_sine

AXIS, WIDTH = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
NORMAL = np.cross(AXIS, WIDTH)
GRAVITY = np.array([0.0, 0.0, -9.81])


def weightless_frequency(strip: Strip, n: int) -> float:
    """First frequency [Hz] of the rectangle-strip cantilever without gravity: released from its sag under
    gravity, the vertical clamp force fitted with a damped sine over 2 s (BDF2, 1 ms)."""
    spec = strip.rectangle_spec(n)
    sagged = CableModel.straight(spec, start=(0, 0, 0), direction=AXIS, ends=("clamped", "free"), gravity=GRAVITY)
    model = CableModel.straight(spec, start=(0, 0, 0), direction=AXIS, ends=("clamped", "free"), gravity=(0, 0, 0))
    state = solve_static(sagged).state()
    res = simulate(model, "bdf2", 1e-3, 2.0, state=state, record_every=1)
    assert res.stable
    return fit_damped_sine(res.t, res.end_forces[:, 0, 2])[0]


def test_rectangle_strip_first_frequency_is_the_clamped_free_plate_strip_in_its_weak_plane():
    """f1 = 1.8751^2 / (2 pi) sqrt(E I_weak / (rho A L^4)), I_weak = w t^3 / 12 (Euler-Bernoulli), approached
    at second order in n; the strong plane (6400x stiffer) does not enter."""
    s = Strip()
    area = s.width * s.thickness
    exact = 1.8751**2 / (2 * math.pi) * math.sqrt(s.youngs_modulus * s.width * s.thickness**3 / 12
                                                 / (s.density * area * s.length**4))
    f10, f20 = weightless_frequency(s, 10), weightless_frequency(s, 20)
    assert f20 == pytest.approx(exact, rel=3e-3)
    assert abs(f20 - exact) < 0.4 * abs(f10 - exact)  # second order: the error falls ~4x from n = 10 to 20


def min_jerk_path(direction: np.ndarray, distance: float, move_s: float = 0.4, step: float = 0.004
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Waypoint times [s], displacements [m] (a rest-to-rest minimum-jerk move of ``distance`` along
    ``direction`` over ``move_s``) and zero rotations, as :func:`run_rectangle` takes them."""
    times = np.arange(0.0, move_s + 0.1 + 1e-9, step)
    u = np.clip(times / move_s, 0.0, 1.0)
    disp = distance * (10 * u**3 - 15 * u**4 + 6 * u**5)[:, None] * direction
    return times, disp, np.zeros_like(disp)


def residual_p2p(t: np.ndarray, load: np.ndarray) -> np.ndarray:
    """Peak-to-peak of each column of ``load`` over t in [1, 2] s (after the 0.4 s move)."""
    w = (t >= 1.0) & (t <= 2.0)
    return np.ptp(load[w], axis=0)


def test_a_sideways_flange_move_excites_far_less_vibration_than_the_same_move_in_the_weak_plane():
    """The same 5 cm move of the clamp along the strip's normal (weak plane) and along its width (strong
    plane, 80x the frequency): the residual clamp force differs by more than 100x."""
    s, num, damping = Strip(), Numerics(strip_model="rectangle", n_masses=12, dt=1e-3), {"damping_rate": 0.24}
    loads = {}
    for name, direction in (("weak", NORMAL), ("strong", WIDTH)):
        times, disp, rot = min_jerk_path(direction, 0.05)
        t, force, *_ = run_rectangle(s, num, damping, np.zeros(3), (AXIS, WIDTH, NORMAL), times, disp, rot,
                                       GRAVITY, 2.0)
        loads[name] = float(np.linalg.norm(residual_p2p(t, force)))
    assert loads["weak"] > 0.5  # N: the strip rings
    assert loads["strong"] < 0.01 * loads["weak"]


def test_planar_pair_and_rectangle_agree_on_an_in_plane_motion():
    """A move in the weak plane with gravity in it: the coupling the rectangle adds has nothing to act on, so
    its clamp force and moment follow the planar pair's (each within 1 % of its peak-to-peak)."""
    s, damping = Strip(), {"damping_rate": 0.24}
    times, disp, rot = min_jerk_path(NORMAL, 0.1)
    t, f_rect, m_rect, *_ = run_rectangle(s, Numerics(strip_model="rectangle", n_masses=12, dt=1e-3), damping,
                                         np.zeros(3), (AXIS, WIDTH, NORMAL), times, disp, rot, GRAVITY, 1.5)
    f_pair = m_pair = 0.0
    for run in plane_runs(AXIS, WIDTH, NORMAL):
        t2, f, m, *_ = run_plane(s, run, Numerics(strip_model="planes", n_masses=12, dt=1e-3), damping, np.zeros(3),
                                AXIS, times, disp, rot, GRAVITY, 1.5)
        f_pair = f_pair + f @ run.force.T
        m_pair = m_pair + m @ run.moment.T
    np.testing.assert_allclose(t, t2)
    assert np.ptp(f_rect[:, 2]) > 1.0 and np.ptp(m_rect[:, 1]) > 0.3  # a real excitation
    for rect, pair in ((f_rect, f_pair), (m_rect, m_pair)):
        np.testing.assert_allclose(rect, pair, atol=0.01 * np.ptp(pair[:, [0, 1, 2]]))


def test_drag_damping_ratio_is_the_quadratic_drag_decay_of_the_modal_oscillator():
    """A mode q'' + c |q'| q' + w^2 q = 0 with c = rho_air C_d kappa / (2 rho_s t) (the strip's face drag
    1/2 rho_air C_d w |v| v per length projected on the tip-normalised cantilever mode, kappa =
    int |phi|^3 / int phi^2 = 0.739): its amplitude decays as 1/A(t) = 1/A0 + 4 c w t / (3 pi), i.e. an
    equivalent damping ratio zeta = 4 c A / (3 pi), linear in the amplitude A."""
    from scipy.integrate import solve_ivp

    s, cd, amp0 = Strip(), 8.0, 0.04
    omega = 2 * math.pi * 2.95
    zeta = drag_damping_ratio(cd, amp0, s)
    c = 3 * math.pi * zeta / (4 * amp0)  # [1/m] the modal drag constant the function implies
    assert c == pytest.approx(1.2 * cd * 0.7389 / (2 * s.density * s.thickness), rel=2e-3)
    sol = solve_ivp(lambda t, y: [y[1], -c * abs(y[1]) * y[1] - omega**2 * y[0]], (0.0, 6.0), [amp0, 0.0],
                    rtol=1e-10, atol=1e-12, dense_output=True)
    period = 2 * math.pi / omega
    peaks_t = np.arange(0, 18) * period  # the oscillator is (nearly) at a crest every period
    amps = np.array([max(sol.sol(np.linspace(tp - 0.1 * period, tp + 0.1 * period, 41))[0]) for tp in peaks_t])
    expected = 1 / (1 / amp0 + 4 * c * omega * peaks_t / (3 * math.pi))
    np.testing.assert_allclose(amps, expected, rtol=5e-3)
    assert amps[-1] < 0.8 * amp0  # the drag really acts over the window


def test_rectangle_default_step_is_converged_when_the_flange_rolls_while_the_strip_bends():
    """A 5 cm weak-plane move with a 3-degree roll of the clamp about the strip axis (the case in which a staggered,
    first-order twist step made a spurious strong-plane load: +24 % torque peak-to-peak at 1 ms on the recordings):
    at the rectangle's default step (1 ms, BDF2 with the twist in its Newton step) the residual clamp force and
    moment are those of a 4x smaller step, each component within 3 % (measured: 0.2-1.6 %)."""
    s, damping = Strip(), {"damping_rate": 0.24}
    default = Numerics(strip_model="rectangle", n_masses=12)
    assert default.dt == pytest.approx(1e-3)
    times, disp, _ = min_jerk_path(NORMAL, 0.05)
    rot = disp[:, 2:3] / 0.05 * math.radians(3.0) * AXIS  # the roll follows the move's profile
    runs = {}
    for dt in (default.dt, default.dt / 4):
        t, force, moment, *_ = run_rectangle(s, Numerics(strip_model="rectangle", n_masses=12, dt=dt), damping,
                                             np.zeros(3), (AXIS, WIDTH, NORMAL), times, disp, rot, GRAVITY, 2.0)
        runs[dt] = (residual_p2p(t, force), residual_p2p(t, moment))
    (f1, m1), (f4, m4) = runs[default.dt], runs[default.dt / 4]
    assert np.linalg.norm(f4) > 0.5  # N: the strip rings
    assert f4[1] > 0.05 * f4[2]  # the roll puts a real load into the width direction
    np.testing.assert_allclose(f1, f4, rtol=0.03, atol=1e-3 * np.max(f4))  # each component, the width one included
    np.testing.assert_allclose(m1, m4, rtol=0.03, atol=1e-3 * np.max(m4))
