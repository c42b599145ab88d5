"""The strip under quadratic air drag: both strip models against the modal closed form, and ``validate beam
--drag-coefficient fit`` on the beam_handling recordings (skipped when they are absent)."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bullet_dlo.core.engine import simulate
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.statics import solve_static
from bullet_dlo.reality.beam import Numerics, Strip, strip_spec
from bullet_dlo.reality.vibration import drag_damping_ratio


def _tip_decay(strip_model: str, drag_coefficient: float) -> tuple[np.ndarray, np.ndarray]:
    """Peak times [s] and tip amplitudes [m] of the horizontal strip released from its sag under 1.5 g
    (weak plane vertical), without gravity afterwards so that the tip oscillates about the straight line."""
    numerics = Numerics(strip_model=strip_model, n_masses=12, dt=1e-3 if strip_model == "planes" else 2e-4)
    spec = strip_spec(Strip(), numerics, {"drag_coefficient": drag_coefficient})
    heavy = CableModel.straight(spec, start=(0, 0, 0), direction=(1, 0, 0), ends=("clamped", "free"),
                                gravity=(0, 0, -1.5 * 9.81))
    model = CableModel.straight(spec, start=(0, 0, 0), direction=(1, 0, 0), ends=("clamped", "free"),
                                gravity=(0, 0, 0))
    state = solve_static(heavy).state()
    res = simulate(model, "bdf2", numerics.dt, 2.0, state=state, record_every=1, max_records=10**6)
    assert res.stable
    z, t = np.abs(res.x[:, -1, 2]), res.t
    idx = [i for i in range(1, len(z) - 1) if z[i] >= z[i - 1] and z[i] > z[i + 1]]
    return t[idx], z[idx]


@pytest.mark.parametrize("strip_model", ["planes", "rectangle"])
def test_strip_drag_damping_matches_the_modal_closed_form(strip_model):
    """Both strip models damp the first mode as quadratic drag on the face does: the amplitude decays as
    1/A = 1/A0 + zeta(A) omega t / A, zeta(A) = 2 rho_air C_d kappa A / (3 pi rho_s t) (drag_damping_ratio;
    the planes' weak run takes the law with the strip's width, the rectangle its face normal)."""
    cd = 40.0  # large, so that 2 s show the decay clearly (the law is linear in C_d)
    times, peaks = _tip_decay(strip_model, cd)
    slope = np.polyfit(times, 1.0 / peaks, 1)[0]
    omega = 2 * math.pi * 2.97
    closed = drag_damping_ratio(cd, 1.0, Strip(), rho_air=1.204) * omega  # d(1/A)/dt = zeta(A) omega / A
    assert slope == pytest.approx(closed, rel=0.03)  # measured: -1.1 % (planes), -0.7 % (rectangle)
    times0, peaks0 = _tip_decay(strip_model, 0.0)
    assert abs(np.polyfit(times0, 1.0 / peaks0, 1)[0]) < 0.02 * closed  # without drag no decay (BDF2's is tiny)


@pytest.mark.bullet
def test_validate_beam_with_fitted_drag(tmp_path, z_split):
    """Fit damping_rate and C_d on ocp_Z_15cm (amplitude windows of its decay), predict ocp_Z_35cm (held
    out): frequency within 2 %, damping ratio within 30 % (the goals reached; the peak-to-peak's 15 % is not,
    see docs/guides/validate.md). n 10 and the filter given, to stay within CI time."""
    from bullet_dlo.cli.main import main

    folders = z_split
    out = tmp_path / "beam.json"
    code = main(["validate", "beam", str(folders["fit"]), str(folders["predict"]), "--json", str(out), "-q",
                 "--n-masses", "10", "--duration", "7.5", "--filter-cutoff", "4.26", "--filter-delay", "0.0065",
                 "--no-numerics-check", "--no-plots", "--drag-coefficient", "fit"])
    assert code == 0
    summary = json.loads(out.read_text())
    params = summary["parameters"]
    assert params["drag_coefficient"] >= 0.0 and params["damping_rate"] >= 0.0
    assert params["drag_fit"]["windows"]["ocp_Z_15cm_0.42s_1"]  # fitted on the fit file's decay windows
    entry = summary["files"]["ocp_Z_35cm_0.61s_1"]
    assert entry["ratio"]["frequency_hz"] == pytest.approx(1.0, abs=0.02)
    assert entry["ratio"]["damping_ratio"] == pytest.approx(1.0, abs=0.3)
    assert entry["measured"]["p2p_at_end"] > 0 and entry["predicted"]["p2p_at_end"] > 0


@pytest.mark.bullet
@pytest.mark.parametrize("args, word", [(["--drag-coefficient", "foo"], "--drag-coefficient"),
                                        (["--drag-coefficient", "2000"], "--drag-coefficient"),
                                        (["--drag-coefficient", "fit", "--damping", "internal_damping"], "damping_rate")])
def test_validate_beam_bad_drag_is_one_line_exit_2(tmp_path, capsys, args, word):
    from bullet_dlo.cli.main import main

    code = main(["validate", "beam", str(tmp_path), str(tmp_path), "--json", str(tmp_path / "o.json"), *args])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and word in err
