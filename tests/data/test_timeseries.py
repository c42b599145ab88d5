"""Recordings on disk (NPZ, HDF5, CSV) read back as written, and ``bullet-dlo fit`` on a CSV end to end."""
from __future__ import annotations

import json

import numpy as np
import pytest

from bullet_dlo.analysis.fit import synthetic_recording
from bullet_dlo.cli.main import main
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.data.recording import read_recording, write_csv, write_series

TRUE = CableSpec.lv2017(n_masses=6, damping_rate=2.0, internal_damping=0.01)


@pytest.fixture(scope="module")
def rec():
    return synthetic_recording(TRUE, [], 0.2, rate=100.0, noise=0.002, seed=3)


@pytest.mark.parametrize("suffix", [".npz", ".h5", ".csv"])
def test_series_files_read_back_as_written(tmp_path, rec, suffix):
    k = len(rec.t)
    arrays = {"t": rec.t, "ee_pos": rec.grasp_pos, "ee_quat": rec.grasp_quat,
              "wrench_world": np.concatenate([rec.force, np.zeros((k, 2, 3))], axis=2), "end_forces": rec.force + 1.0}
    path = write_series(tmp_path / f"series{suffix}", arrays, {"robot": "kuka", "cable": TRUE.to_dict()})
    back = read_recording(path)
    for name in ("t", "grasp_pos", "grasp_quat", "force"):
        assert np.allclose(getattr(back, name), getattr(rec, name), rtol=1e-9, atol=1e-12), name
    if suffix != ".csv":
        assert np.allclose(read_recording(path, "end_forces").force, rec.force + 1.0)


def test_bad_recording_files_are_one_line_errors(tmp_path, rec):
    with pytest.raises(ParameterError, match="series file must end in .npz, .h5, .hdf5, .csv"):
        write_series(tmp_path / "out.txt", {})
    (tmp_path / "short.csv").write_text("t,a\n0,1\n")
    with pytest.raises(ParameterError, match="must have 21 columns"):
        read_recording(tmp_path / "short.csv")
    np.savez(tmp_path / "partial.npz", t=rec.t)
    with pytest.raises(ParameterError, match="lacks column\\(s\\) ee_pos, ee_quat, wrench_world"):
        read_recording(tmp_path / "partial.npz")
    assert main(["fit", str(tmp_path / "missing.csv"), "--length", "0.3", "--diameter", "0.004", "--out",
                 str(tmp_path)]) == 2


def test_fit_cli_writes_json_and_plot_and_flags_damping_of_a_static_hold(tmp_path, rec, capsys):
    write_csv(tmp_path / "hold.csv", rec)
    code = main(["fit", str(tmp_path / "hold.csv"), "--length", "0.3", "--diameter", "0.004", "--n-masses", "6",
                 "--youngs-modulus", "1e8", "--max-evaluations", "20", "--out", str(tmp_path / "fit"), "-q"])
    assert code == 0
    summary = json.loads((tmp_path / "fit" / "fit.json").read_text())
    params = summary["parameters"]
    assert set(params) == {"youngs_modulus", "internal_damping", "damping_rate", "mass"}
    assert not params["damping_rate"]["identifiable"] and not params["internal_damping"]["identifiable"]
    assert abs(params["mass"]["value"] / TRUE.mass - 1) < 0.03  # from the weight
    assert (tmp_path / "fit" / "fit.png").stat().st_size > 10_000
    assert "damping_rate is not identifiable" in capsys.readouterr().out
