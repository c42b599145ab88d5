"""beam_handling: reader, vibration metrics, Panda kinematics and torque mapping, ``validate beam``."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from bullet_dlo.core.validate import ParameterError
from bullet_dlo.reality.beam import COLUMNS, EstimateFilter, Numerics, Strip, free_vibration, read_beam_csv
from bullet_dlo.reality.vibration import fit_damped_sine, motion_span, residual_vibration


def write_csv(path: Path, rows: np.ndarray, header: tuple[str, ...] = COLUMNS) -> Path:
    path.write_text(", ".join(header) + "\n" + "\n".join(",".join(f"{v:.9g}" for v in r) for r in rows) + "\n")
    return path


def test_reader_units_and_columns(tmp_path):
    k = 5
    rows = np.zeros((k, len(COLUMNS)))
    rows[:, 0] = 1000 + np.arange(k)  # libfranka tick counter, 1 ms
    for g, group in enumerate(("q", "q_d", "dq", "dq_d", "tau_J", "tau_ext_hat_filtered")):
        rows[:, 2 + 7 * g:9 + 7 * g] = (g + 1) * 0.1 + np.arange(7) * 0.01
    rec = read_beam_csv(write_csv(tmp_path / "m.csv", rows))
    assert rec.name == "m"
    np.testing.assert_allclose(rec.t, np.arange(k) * 1e-3)  # seconds from the first tick
    np.testing.assert_allclose(rec.q[0], 0.1 + np.arange(7) * 0.01)
    np.testing.assert_allclose(rec.tau_ext_hat_filtered[-1], 0.6 + np.arange(7) * 0.01)
    assert rec.rate == pytest.approx(1000.0)
    with pytest.raises(ParameterError, match=r"missing column\(s\) tau_J\[3\]"):
        read_beam_csv(write_csv(tmp_path / "bad.csv", rows[:, :-1], tuple(c for c in COLUMNS if c != "tau_J[3]")))
    # damaged rows: a text cell, a short row, a byte that is not UTF-8: one ParameterError each, no traceback
    good = write_csv(tmp_path / "good.csv", rows).read_text().splitlines()
    text = good[:3] + [good[3].rsplit(",", 1)[0] + ",abc"] + good[4:]
    short = good[:3] + [",".join(good[3].split(",")[:20])] + good[4:]
    for name, lines in (("text", text), ("short", short)):
        path = tmp_path / f"{name}.csv"
        path.write_text("\n".join(lines) + "\n")
        with pytest.raises(ParameterError, match=f"{name}.csv: every row after the header must hold {len(COLUMNS)} "):
            read_beam_csv(path)
    dup = tmp_path / "dup.csv"
    dup.write_text("\n".join([good[0] + ", q[3]"] + [line + ",0" for line in good[1:]]) + "\n")
    with pytest.raises(ParameterError, match=r"dup.csv: column\(s\) q\[3\] named more than once"):
        read_beam_csv(dup)
    wild = rows.copy()
    wild[:, 2] = 1e6  # q[0] [rad]: degrees or a counter, not radians
    with pytest.raises(ParameterError, match="a joint angle of 1e\\+06 rad, beyond"):
        read_beam_csv(write_csv(tmp_path / "wild.csv", wild))
    latin = tmp_path / "latin.csv"
    latin.write_bytes(("\n".join(good) + "\n").replace("duration", "dur\xe9e,duration", 1).encode("latin-1"))
    with pytest.raises(ParameterError, match="latin.csv: not UTF-8 text"):
        read_beam_csv(latin)


def test_vibration_metrics_on_a_closed_form_damped_sine():
    rng = np.random.default_rng(1)
    t = np.arange(0.0, 10.0, 1e-3)
    dq_d = np.zeros((len(t), 7))
    dq_d[100:500, 2] = 0.3  # the motion: samples 100-499
    start, end = motion_span(dq_d)
    assert (start, end) == (100, 500)
    f, zeta, amp = 2.93, 0.012, 0.8
    wn = 2 * math.pi * f / math.sqrt(1 - zeta**2)
    s = np.clip(t - t[end], 0.0, None)
    clean = amp * np.exp(-zeta * wn * s) * np.sin(2 * math.pi * f * s + 0.4)
    y = clean + 0.05 + rng.normal(0.0, 0.01, len(t))
    v = residual_vibration(t, y, t[end])
    assert v.frequency_hz == pytest.approx(f, rel=1e-3)
    assert v.damping_ratio == pytest.approx(zeta, rel=0.03)
    w = (t >= t[end] + 1) & (t <= t[end] + 2)
    assert v.p2p_torque == pytest.approx(np.ptp(clean[w]), rel=0.03)
    f2, z2, a2, _ = fit_damped_sine(t[w], clean[w])
    assert a2 == pytest.approx(amp * math.exp(-zeta * wn * 1.0), rel=1e-3)


def test_estimate_filter_gain_and_phase():
    filt = EstimateFilter(4.7, 0.010)
    t = np.arange(0.0, 4.0, 1e-3)
    y = filt.apply(np.sin(2 * math.pi * 2.9 * t), 1000.0)
    h = filt.response(2.9)
    tail = t > 2.0  # past the start transient
    expected = abs(h) * np.sin(2 * math.pi * 2.9 * t[tail] + np.angle(h))
    assert np.max(np.abs(y[tail] - expected)) < 0.01 * abs(h)  # the discrete filter matches its continuous form


def test_bdf2_numerical_damping_far_below_physical():
    """The strip's damping ratio is 0.006-0.022; BDF2's must be negligible, implicit Euler's is not."""
    numerics = Numerics(n_masses=10, dt=1e-3)
    f, zeta = free_vibration(Strip(), numerics, duration=3.0)
    assert abs(zeta) < 6e-4
    assert 2.9 < f < 3.05  # first cantilever mode: 3.516 sqrt(EI / (rho A L^4)) / (2 pi) = 2.97 Hz (+ sag)
    _, zeta_euler = free_vibration(Strip(), Numerics(integrator="implicit_euler", n_masses=10, dt=1e-3), duration=3.0)
    assert zeta_euler > 0.005


@pytest.mark.bullet
def test_flange_jacobian_matches_finite_differences():
    from scipy.spatial.transform import Rotation

    from bullet_dlo.reality.panda import Panda

    q = np.array([-1.4, -0.6, 0.2, -2.0, 0.1, 1.5, 0.7])
    h = 1e-3  # central differences: O(h^2) error, and PyBullet poses are single precision
    with Panda() as panda:
        jac = panda.jacobian(q)
        fd = np.zeros((6, 7))
        for j in range(7):
            dq = np.zeros(7)
            dq[j] = h
            (pa, ra), (pb, rb) = panda.flange_pose(q + dq), panda.flange_pose(q - dq)
            fd[:3, j] = (pa - pb) / (2 * h)
            fd[3:, j] = Rotation.from_matrix(ra @ rb.T).as_rotvec() / (2 * h)
        p0, r0 = panda.flange_pose(np.array([-1.5708, -0.5236, 0, -2.0944, 0, 1.5708, 0.7854]))
    np.testing.assert_allclose(jac, fd, atol=3e-4)
    assert r0[:, 2] @ [0, 0, -1] > 0.999  # the recordings' Z pose: flange axis down


def held_torques(panda, q: np.ndarray, force: np.ndarray | None, arm: np.ndarray) -> np.ndarray:
    """Motor torques [N m] with which PyBullet's engine holds the arm at q while ``force`` [N] (world) acts at
    the point flange origin + ``arm`` [m] (position control, 400 steps to settle)."""
    p, c, body = panda._p, panda._cid, panda._arm
    for j in range(7):
        p.resetJointState(body, j, q[j], physicsClientId=c)
    for _ in range(400):
        p.setJointMotorControlArray(body, list(range(7)), p.POSITION_CONTROL, targetPositions=list(q),
                                    forces=[500.0] * 7, positionGains=[0.5] * 7, physicsClientId=c)
        if force is not None:
            origin = np.array(p.getLinkState(body, 7, computeForwardKinematics=True, physicsClientId=c)[4])
            p.applyExternalForce(body, 7, list(force), list(origin + arm), p.WORLD_FRAME, physicsClientId=c)
        p.stepSimulation(physicsClientId=c)
    return np.array([s[3] for s in p.getJointStates(body, range(7), physicsClientId=c)])


@pytest.mark.bullet
def test_external_torques_balance_a_static_load():
    """A force F at a point r from the flange origin: the extra motor torque with which the physics engine
    holds the arm (with minus without the force) is Franka's external torque -J^T w, w = (F, r x F)."""
    from bullet_dlo.reality.panda import Panda, external_torques, wrench_from_torques

    q = np.array([-1.5708, -0.5236, 0.1, -2.0944, 0.2, 1.5708, 0.7854])
    force, arm = np.array([1.0, -2.0, -7.0]), np.array([0.2, 0.1, -0.05])
    with Panda() as panda:
        held = held_torques(panda, q, force, arm) - held_torques(panda, q, None, arm)
        jac = panda.jacobian(q)
    wrench = np.r_[force, np.cross(arm, force)]
    tau = external_torques(jac, wrench)
    assert np.max(np.abs(tau)) > 1.0  # a load the joints feel
    np.testing.assert_allclose(held, tau, atol=2e-3 * np.max(np.abs(tau)))
    np.testing.assert_allclose(wrench_from_torques(jac, tau), wrench, atol=1e-8)


@pytest.mark.bullet
def test_validate_beam_on_the_recordings(tmp_path, z_split):
    """Fit on ocp_Z_15cm, predict ocp_Z_35cm (held out): frequency within 2 %, damping ratio within 30 %
    of the measured; n 10, 7.5 s simulated, the filter given (not identified) to stay within CI time."""
    from bullet_dlo.cli.main import main

    folders = z_split
    out = tmp_path / "out" / "beam.json"
    code = main(["validate", "beam", str(folders["fit"]), str(folders["predict"]), "--json", str(out), "-q",
                 "--n-masses", "10", "--duration", "7.5", "--filter-cutoff", "4.7", "--filter-delay", "0.0106",
                 "--no-numerics-check"])
    assert code == 0  # (no wall-clock bound here: a cold Numba cache or a second test process can triple it)
    summary = json.loads(out.read_text())
    entry = summary["files"]["ocp_Z_35cm_0.61s_1"]
    assert set(entry["predicted"]) >= {"frequency_hz", "damping_ratio", "p2p_torque", "sine_amplitude"}
    assert entry["joint"] in range(7)
    for side in ("measured", "predicted"):  # the mode's level: p2p / 2 is it plus whatever else is in the band
        assert 0.9 < entry[side]["p2p_torque"] / (2 * entry[side]["sine_amplitude"]) < 1.5
    assert entry["within_goal"]["sine_amplitude"] == (abs(entry["ratio"]["sine_amplitude"] - 1) <= 0.15)
    assert summary["goals"]["frequency_hz"] == {"within": int(entry["within_goal"]["frequency_hz"]), "of": 1,
                                                "tolerance": 0.02}
    assert entry["ratio"]["frequency_hz"] == pytest.approx(1.0, abs=0.02)
    assert entry["ratio"]["damping_ratio"] == pytest.approx(1.0, abs=0.3)
    assert 0.5 < entry["ratio"]["p2p_torque"] < 2.0
    assert entry["rms_torque_error"] < entry["rms_measured_deviation"]  # the prediction explains part of the signal
    assert summary["parameters"]["damping_rate"] > 0
    assert (out.parent / "beam.ocp_Z_35cm_0.61s_1.png").is_file()
    # the measured damping law, from the recordings alone: Z_15cm's and Z_35cm's decays grow with the amplitude
    law = summary["parameters"]["damping_law"]
    assert law["per_file"]["ocp_Z_15cm_0.42s_1"]["best_law"] == "drag"
    assert entry["measured"]["decay_law"]["best_law"] == "drag"
    assert law["shared"]["drag"]["params"]["c"] > 0.1  # [1/m]
    assert "amplitude_damping" not in summary["parameters"]  # the law stays out of the default model
    assert summary["limits"][2].startswith("the damping is amplitude dependent")
    # the rectangle (the default) runs on the compliant arm, one run per recording
    assert entry["strip_model"] == "rectangle" and entry["strip_model_reason"].startswith("asked for (the default)")
    assert summary["model"]["strip_models_run"] == {"planes": [], "rectangle": ["ocp_Z_35cm_0.61s_1"]}
    assert summary["arm"]["mode"] == "compliant"


@pytest.mark.bullet
def test_validate_beam_bad_input_is_one_line_exit_2(tmp_path, capsys):
    from bullet_dlo.cli.main import main

    (tmp_path / "empty").mkdir()
    assert main(["validate", "beam", str(tmp_path / "missing"), str(tmp_path), "--json", str(tmp_path / "o.json")]) == 2
    assert main(["validate", "beam", str(tmp_path / "empty"), str(tmp_path), "--json", str(tmp_path / "o.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "FIT_DIR" in err[0] and "no *.csv" in err[1]
    # a recording without motion: refused naming its folder (both folders are measured before the fit; a PREDICT_DIR
    # file failed after the whole fit, naming only the file)
    rows = np.zeros((20, len(COLUMNS)))
    rows[:, 0] = 1000 + np.arange(20)
    for folder in ("fit", "predict"):
        (tmp_path / folder).mkdir()
        write_csv(tmp_path / folder / "still.csv", rows)
    assert main(["validate", "beam", str(tmp_path / "fit"), str(tmp_path / "predict"), "--json",
                 str(tmp_path / "o.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: FIT_DIR: beam recording still:") and "no motion" in err[0]
