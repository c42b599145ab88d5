"""The strip on the compliant arm (``validate beam --arm compliant|loop``, :mod:`bullet_dlo.reality.beam_arm`)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import butter, lsim, sosfiltfilt

from bullet_dlo.core.validate import ParameterError
from bullet_dlo.reality.beam import BeamRecording, EstimateFilter, Numerics, Strip, predict_torques
from bullet_dlo.reality.beam_arm import (ArmImpedance, ArmLoop, identify_arm, predict_torques_compliant,
                                         strip_torque_real)

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "beam_handling"
K_TRUE = np.array([1800.0, 2000.0, 1500.0, 1400.0, 1000.0, 600.0, 500.0])
D_TRUE = np.array([60.0, 50.0, 55.0, 50.0, 25.0, 10.0, 8.0])


def rest_to_rest(t: np.ndarray, q0: np.ndarray, dq: np.ndarray, t0: float, duration: float) -> tuple[np.ndarray, ...]:
    """Minimum-jerk joint path [rad] and rates [rad/s] from q0 by dq over [t0, t0 + duration]."""
    s = np.clip((t - t0) / duration, 0.0, 1.0)[:, None]
    q = q0 + dq * (10 * s**3 - 15 * s**4 + 6 * s**5)
    dqt = dq * (30 * s**2 - 60 * s**3 + 30 * s**4) / duration
    return q, dqt


def synthetic(name: str, t: np.ndarray, q: np.ndarray, q_d: np.ndarray, dq: np.ndarray, dq_d: np.ndarray,
              tau_j: np.ndarray, tau_ext: np.ndarray) -> BeamRecording:
    return BeamRecording(t=t, q=q, q_d=q_d, dq=dq, dq_d=dq_d, tau_J=tau_j, tau_ext_hat_filtered=tau_ext, name=name)


def test_identify_arm_recovers_a_joint_impedance_and_holds_unidentifiable_joints_rigid():
    """tau_J = -K e - D de/dt on joints 0-4 (e: random band-limited tracking errors after a motion); joints 5-6 carry
    torque noise unrelated to e: K, D come back within 1 %, and 5-6 are held rigid (R^2 ~ 0)."""
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 7.5, 1e-3)
    q_d, dq_d = rest_to_rest(t, np.zeros(7), np.full(7, 0.2), 0.2, 0.5)
    sos = butter(2, (2.0, 5.0), btype="bandpass", fs=1000.0, output="sos")
    e = sosfiltfilt(sos, rng.normal(0.0, 1e-3, (len(t), 7)), axis=0)
    de = np.gradient(e, 1e-3, axis=0)
    tau = -K_TRUE * e - D_TRUE * de
    tau[:, 5:] = sosfiltfilt(sos, rng.normal(0.0, 0.5, (len(t), 2)), axis=0)
    rec = synthetic("syn", t, q_d + e, q_d, dq_d + de, dq_d, tau + 3.0, np.zeros_like(tau))
    imp = identify_arm([rec])
    np.testing.assert_allclose(imp.stiffness[:5], K_TRUE[:5], rtol=0.01)
    np.testing.assert_allclose(imp.damping[:5], D_TRUE[:5], rtol=0.01)
    assert imp.compliant.tolist() == [True] * 5 + [False] * 2
    assert np.all(imp.r2[:5] > 0.99) and np.all(imp.r2[5:] < 0.1)
    tau[:, 5:] = -K_TRUE[5:] * e[:, 5:] - D_TRUE[5:] * de[:, 5:]  # identifiable wrist: still held rigid
    imp = identify_arm([synthetic("syn", t, q_d + e, q_d, dq_d + de, dq_d, tau, np.zeros_like(tau))])
    np.testing.assert_allclose(imp.stiffness, K_TRUE, rtol=0.01)
    assert imp.compliant.tolist() == [True] * 5 + [False] * 2
    with pytest.raises(ParameterError, match="stiffness > 0"):
        ArmImpedance(-K_TRUE, D_TRUE, np.ones(7), np.ones(7, dtype=bool))


def test_arm_loop_rings_at_the_closed_form_frequency_without_numerical_damping():
    """One compliant joint (inertia I, stiffness K, damping D) released from a static deflection under a held
    torque: Newmark's response against the closed-form damped oscillator over 2 s."""
    inertia, k, d, f0 = 0.8, 1500.0, 4.0, 2.0
    imp = ArmImpedance(np.r_[k, np.ones(6)], np.r_[d, np.zeros(6)], np.ones(7), np.r_[True, np.zeros(6, dtype=bool)])
    h = 1e-3
    arm = ArmLoop(np.full((1, 7, 7), inertia), imp, h)
    arm.q[:] = f0 / k  # at rest, deflected by the torque f0; the torque is removed at t = 0
    arm.a[:] = -f0 / inertia  # the acceleration that goes with it (Newmark carries it)
    ts = np.arange(1, 2001) * h
    out = []
    for i in range(len(ts)):
        arm.step(i * h, np.zeros(7))
        out.append(arm.q[0])
    wn = math.sqrt(k / inertia)
    zeta = d / (2 * math.sqrt(k * inertia))
    wd = wn * math.sqrt(1 - zeta**2)
    exact = f0 / k * np.exp(-zeta * wn * ts) * (np.cos(wd * ts) + zeta * wn / wd * np.sin(wd * ts))
    # trapezoidal rule: no amplitude error, phase error (wn h)^2 / 12 per radian (1.6e-3 over 2 s at 6.9 Hz)
    np.testing.assert_allclose(out, exact, atol=0.002 * f0 / k)
    assert full_is_padded(arm)


def full_is_padded(arm: ArmLoop) -> bool:
    full = arm.full(np.array([7.0]))
    return full[0] == 7.0 and not np.any(full[1:])


def test_strip_torque_real_undoes_the_estimate_filter():
    """A band-limited torque through Franka's filter (low-pass + delay) and back: within 2 % RMS in 1.5-8 Hz."""
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 6.0, 1e-3)
    q_d, dq_d = rest_to_rest(t, np.zeros(7), np.full(7, 0.1), 0.5, 0.5)
    sos = butter(2, (1.5, 8.0), btype="bandpass", fs=1000.0, output="sos")
    tau = sosfiltfilt(sos, rng.normal(0.0, 1.0, (len(t), 7)), axis=0)
    tau[:500] = 0.0
    est = EstimateFilter(4.2, 0.0065)
    rec = synthetic("f", t, q_d, q_d, dq_d, dq_d, np.zeros_like(tau), est.apply(tau, 1000.0))
    back = strip_torque_real(rec, est)
    inner = slice(1000, 5000)
    err = np.sqrt(np.mean((back[inner] - tau[inner]) ** 2)) / np.sqrt(np.mean(tau[inner] ** 2))
    assert err < 0.02
    raw = np.sqrt(np.mean((rec.tau_ext_hat_filtered[inner] - tau[inner]) ** 2)) / np.sqrt(np.mean(tau[inner] ** 2))
    assert raw > 0.3  # the filter itself is far from the identity: the check has teeth


@pytest.fixture(scope="module")
def panda():
    pytest.importorskip("pybullet")
    from bullet_dlo.reality.panda import Panda

    with Panda() as p:
        yield p


def swing(duration: float = 2.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A 0.15 rad joint-0 swing of the Panda in 0.35 s from the beam_handling start pose: t, q, dq."""
    t = np.arange(0.0, duration, 1e-3)
    q0 = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.785])
    dq = np.zeros(7)
    dq[0] = 0.15
    q, dqt = rest_to_rest(t, q0, dq, 0.1, 0.35)
    return t, q, dqt


@pytest.mark.parametrize("strip_model", ["planes", "rectangle"])
def test_substitution_keeps_the_measured_path_when_the_model_strip_is_the_real_one(panda, strip_model):
    """A recording made by the model itself (its rigid-path torques through Franka's filter as the estimate): the
    substituted arm barely moves (the model's torque equals the 'real' one), while the same arm with no real torque to
    substitute (the strip's load acting on it alone) deflects 10x more: sign, lag and filter inversion agree. Both
    strip models in the loop: the planes' weak run (their strong run prescribed, its inertia in the arm's) and the
    rectangle whole, its clamp and section axis turned by the arm's deviation (the swing turns the flange 8.6 deg,
    which the rectangle follows and the planes do not; each is checked against its own rigid-path prediction)."""
    t, q, dq = swing()
    est = EstimateFilter(4.2, 0.0065)
    numerics = Numerics(strip_model=strip_model, n_masses=8)
    damping = {"damping_rate": 0.3}
    base = synthetic("self", t, q, q, dq, dq, np.zeros_like(q), np.zeros_like(q))
    rigid = predict_torques(base, panda, Strip(), damping, numerics, est)
    k = len(rigid.t)
    tau_ext = np.zeros_like(q)
    tau_ext[:k] = rigid.torques_filtered
    tau_ext[k:] = rigid.torques_filtered[-1]
    imp = ArmImpedance(K_TRUE, D_TRUE, np.ones(7), np.arange(7) < 5)
    real = synthetic("self", t, q, q, dq, dq, np.zeros_like(q), tau_ext)
    sub = predict_torques_compliant(real, panda, imp, Strip(), damping, numerics, est)
    alone = predict_torques_compliant(base, panda, imp, Strip(), damping, numerics, est)
    moved_sub = np.abs(sub.arm_deviation).max()
    moved_alone = np.abs(alone.arm_deviation).max()
    assert moved_alone > 1e-5  # the strip's load really deflects the arm (rad)
    assert moved_sub < 0.1 * moved_alone
    # and the substituted prediction is the rigid one (within a few % of the torque swing)
    n = min(k, len(sub.t))
    swing_ = np.ptp(rigid.torques[:n, 0])
    assert np.max(np.abs(sub.torques[:n, 0] - rigid.torques[:n, 0])) < 0.05 * swing_


def test_compliant_arm_keeps_the_amplitude_law_on_the_planes_and_the_wrist_rigid(panda):
    t, q, dq = swing(0.5)
    rec = synthetic("x", t, q, q, dq, dq, np.zeros_like(q), np.zeros_like(q))
    imp = ArmImpedance(K_TRUE, D_TRUE, np.ones(7), np.arange(7) < 5)
    with pytest.raises(ParameterError, match="--amplitude-damping sets the planes"):
        predict_torques_compliant(rec, panda, imp, numerics=Numerics(strip_model="rectangle"), amplitude_damping=0.3)
    with pytest.raises(ParameterError, match="wrist joints 5 and 6 rigid"):
        predict_torques_compliant(rec, panda, ArmImpedance(K_TRUE, D_TRUE, np.ones(7), np.ones(7, dtype=bool)))


@pytest.mark.skipif(not DATA.is_dir(), reason=f"beam_handling recordings not found at {DATA} (../shared/data)")
def test_identified_arm_reproduces_the_measured_tracking_error(panda):
    """Real data: the arm model (URDF inertia, K and D identified on two X recordings) driven by the real strip's
    torque (the estimate, filter undone) gives the measured tracking error q - q_d of joints 0, 2 and 4 after the
    Xdown_15cm motion (band 1.5-8 Hz): gain within 15 %, correlation above 0.9."""
    from bullet_dlo.reality.beam import read_beam_csv
    from bullet_dlo.reality.vibration import motion_span

    recs = [read_beam_csv(DATA / f"ocp_{n}.csv") for n in ("Xdown_15cm_0.35s_1", "Xup_25cm_0.44s_1")]
    imp = identify_arm(recs)
    assert imp.compliant[[0, 2, 4]].all() and not imp.compliant[6]
    rec = recs[0]
    _, end = motion_span(rec.dq_d)
    est = EstimateFilter(4.2, 0.0065)
    seg = slice(end + 300, end + 6000)
    tau = strip_torque_real(rec, est)
    sos = butter(4, (1.5, 8.0), btype="bandpass", fs=1000.0, output="sos")
    idx = np.flatnonzero(imp.compliant)
    mass = panda.mass_matrix(rec.q[end + 500])[np.ix_(idx, idx)]
    mi = np.linalg.inv(mass)
    nc = len(idx)
    a = np.block([[np.zeros((nc, nc)), np.eye(nc)],
                  [-mi @ np.diag(imp.stiffness[idx]), -mi @ np.diag(imp.damping[idx])]])
    b = np.vstack([np.zeros((nc, nc)), -mi])
    u = sosfiltfilt(sos, tau[:, idx], axis=0)[seg]
    _, y, _ = lsim((a, b, np.hstack([np.eye(nc), np.zeros((nc, nc))]), np.zeros((nc, nc))), u,
                   np.arange(len(u)) * 1e-3)
    e = sosfiltfilt(sos, rec.q - rec.q_d, axis=0)[seg][:, idx]
    for j in (0, 2, 4):
        c = list(idx).index(j)
        gain = float(y[:, c] @ e[:, c] / (y[:, c] @ y[:, c]))
        assert 0.85 < gain < 1.15, (j, gain)
        assert np.corrcoef(y[:, c], e[:, c])[0, 1] > 0.9


def test_a_stiff_arm_in_the_loop_is_the_rigid_prescribed_path(panda):
    """The full loop from q_d with a 1e7 N m/rad arm (deviations ~1e-7 rad) gives the torques of the clamp prescribed
    on the q_d path (:func:`predict_torques`, one simulate call per plane): the hand-stepped weak-plane run (held-end
    samples, BDF2 history, clamp loads) and the prescribed strong plane are the same model."""
    t, q, dq = swing(1.2)
    est = EstimateFilter(4.2, 0.0065)
    numerics = Numerics(strip_model="planes", n_masses=8)  # the loop's model (the swing turns the flange 8.6 deg)
    damping = {"damping_rate": 0.3}
    rec = synthetic("stiff", t, q + 0.01, q, dq, dq, np.zeros_like(q), np.zeros_like(q))  # q far off: not used
    stiff = ArmImpedance(np.full(7, 1e7), np.full(7, 1e3), np.ones(7), np.arange(7) < 5)
    loop = predict_torques_compliant(rec, panda, stiff, Strip(), damping, numerics, est, drive="desired")
    rigid = predict_torques(synthetic("stiff", t, q, q, dq, dq, np.zeros_like(q), np.zeros_like(q)), panda, Strip(),
                            damping, numerics, est)
    n = min(len(loop.t), len(rigid.t))
    assert np.abs(loop.arm_deviation).max() < 1e-5
    for j in range(5):
        scale = np.ptp(rigid.torques[:n, j])
        assert np.max(np.abs(loop.torques[:n, j] - rigid.torques[:n, j])) < 0.01 * scale + 1e-4, j


def beam_translation_integral(strip: Strip, omega: float) -> float:
    """Integral [m^2] over the clamped-free Euler-Bernoulli strip (weak plane) of its deflection w(x) when its clamp
    translates harmonically at omega [rad/s] with unit amplitude (w(0) = 1, w'(0) = 0, free tip): the strip's force
    on the clamp is omega^2 rho A times it (momentum balance)."""
    ei = strip.youngs_modulus * strip.second_moment("weak")
    rho_a, length = strip.mass / strip.length, strip.length
    b = (rho_a * omega**2 / ei) ** 0.25

    def basis(x: float | np.ndarray, d: int) -> np.ndarray:
        c, s, ch, sh = np.cos(b * x), np.sin(b * x), np.cosh(b * x), np.sinh(b * x)
        return [np.array([c, s, ch, sh]), b * np.array([-s, c, sh, ch]), b**2 * np.array([-c, -s, ch, sh]),
                b**3 * np.array([s, -c, sh, ch])][d]

    coef = np.linalg.solve(np.array([basis(0.0, 0), basis(0.0, 1), basis(length, 2), basis(length, 3)]),
                           [1.0, 0.0, 0.0, 0.0])
    x = np.linspace(0.0, length, 4001)
    return float(np.trapezoid(coef @ basis(x, 0), x))


@pytest.mark.parametrize("strip_model", ["rectangle", "planes"])
def test_the_strip_on_a_compliant_joint_rings_at_the_closed_form_coupled_frequency(panda, strip_model):
    """Joint 3 alone compliant (K 1000 N m/rad, undamped), the strip undamped and weightless: the strip's mode on
    the compliant joint against the same strip on a rigid arm, both from the loop; closed form: the joint's
    inertia (URDF, plus the strip's rigid strong-plane mass) on its spring, loaded by the Euler-Bernoulli strip
    whose clamp translates along its normal, K - w^2 I - w^2 rho A c^2 int w_u(w) = 0 (c: the clamp's normal speed
    per joint rate; joint 3 turns the clamp about the strip axis, not about its width). The shift (-1.1 %) within
    0.1 % of the frequency, with both strip models in the loop (the rectangle's strong-plane mass in its own clamp
    load and its section rolled with the clamp, the planes' in the arm's mass matrix)."""
    from scipy.optimize import brentq

    from bullet_dlo.reality.beam import Mounting
    from bullet_dlo.reality.vibration import fit_damped_sine

    strip, k, j = Strip(), 1000.0, 3
    q0 = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.785])
    _, rot = panda.flange_pose(q0)
    jac, mass = panda.jacobian(q0), panda.mass_matrix(q0)
    axis, width, normal = Mounting().axes(rot)
    c_n, c_w = normal @ jac[:3, j], width @ jac[:3, j]
    assert abs(np.cross(axis, normal) @ jac[3:, j]) < 1e-3 and abs(axis @ jac[:3, j]) < 1e-3  # translation only
    inertia = mass[j, j] + strip.mass * c_w**2
    rho_a = strip.mass / strip.length

    def characteristic(f: float) -> float:
        om = 2 * math.pi * f
        return k - om**2 * inertia - om**2 * rho_a * c_n**2 * beam_translation_integral(strip, om)

    ei = strip.youngs_modulus * strip.second_moment("weak")
    f_free = 1.8751**2 / (2 * math.pi) * math.sqrt(ei / (rho_a * strip.length**4))
    f_coupled = brentq(characteristic, 0.9 * f_free, 0.9999 * f_free)
    expected = f_coupled / f_free
    assert 0.985 < expected < 0.992  # a shift of about 1 %

    t = np.arange(0.0, 5.0, 1e-3)
    dq = np.zeros(7)
    dq[j] = 0.01
    q_d, dq_d = rest_to_rest(t, q0, dq, 0.1, 0.2)
    rec = synthetic("cf", t, q_d, q_d, dq_d, dq_d, np.zeros_like(q_d), np.zeros_like(q_d))
    sos = butter(4, (1.5, 3.5), btype="bandpass", fs=1000.0, output="sos")  # the arm's own mode (5.4 Hz) left out
    freq = {}
    for name, stiffness in (("compliant", k), ("rigid", 1e7)):
        imp = ArmImpedance(np.where(np.arange(7) == j, stiffness, 1.0), np.zeros(7), np.ones(7), np.arange(7) == j)
        pred = predict_torques_compliant(rec, panda, imp, strip, {}, Numerics(strip_model, n_masses=20),
                                         EstimateFilter(), drive="desired", gravity=(0.0, 0.0, 0.0))
        y = sosfiltfilt(sos, pred.torques[:, j])
        w = (pred.t > 1.0) & (pred.t < 4.8)
        freq[name] = fit_damped_sine(pred.t[w], y[w])[0]
    assert freq["compliant"] / freq["rigid"] == pytest.approx(expected, abs=1e-3)
