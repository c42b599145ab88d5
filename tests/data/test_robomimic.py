"""``export robomimic``: rollouts in robomimic's HDF5 layout, checked against their episodes here and read by
robomimic's own ``SequenceDataset`` where a Python with robomimic is named (``BULLET_DLO_ROBOMIMIC_PYTHON``:
robomimic pulls torch, so it lives in its own venv, e.g. LeRobot's)."""
from __future__ import annotations

import json
import os
import subprocess

import numpy as np
import pytest

h5py = pytest.importorskip("h5py")

from bullet_dlo.cli.main import main  # noqa: E402
from bullet_dlo.data.reader import Dataset  # noqa: E402
from bullet_dlo.data.robomimic import export_robomimic  # noqa: E402

pytestmark = pytest.mark.bullet


def test_every_demo_equals_its_episode(rolled, tmp_path):
    res = export_robomimic(rolled, tmp_path / "r.hdf5")
    assert res.demos == 2 and res.samples == 16 and "wrench" in res.obs_keys
    ds = Dataset(rolled)
    with h5py.File(tmp_path / "r.hdf5") as f:
        assert f["data"].attrs["total"] == 16
        args = json.loads(f["data"].attrs["env_args"])
        assert args["env_name"] == "bullet_dlo/TensionTracking-v0" and args["type"] == 2
        assert [n.decode() for n in f["mask/train"][()]] == ["demo_0", "demo_1"]
        for i, record in enumerate(r for r in ds.records if r["status"] == "ok"):
            ep, demo = ds.load(record), f[f"data/demo_{i}"]
            n = demo.attrs["num_samples"]
            np.testing.assert_array_equal(demo["actions"][()], ep["action"])
            np.testing.assert_array_equal(demo["rewards"][()], ep["reward"])
            assert demo["dones"][()].tolist() == [0] * (n - 1) + [1]
            for key in res.obs_keys:
                full = ep[f"obs_{key}"].reshape(n + 1, -1)
                np.testing.assert_array_equal(demo[f"obs/{key}"][()], full[:-1])
                np.testing.assert_array_equal(demo[f"next_obs/{key}"][()], full[1:])
            assert json.loads(demo.attrs["bullet_dlo/params"])["youngs_modulus"] == ep["params"]["youngs_modulus"]


@pytest.mark.parametrize("case, words", [("capture", "needs the policy's actions"), ("exists", "exists"),
                                         ("suffix", "must end in .hdf5")])
def test_bad_input_is_one_line_and_exit_2(rolled, tmp_path, capsys, case, words):
    (tmp_path / "old.hdf5").write_bytes(b"x")
    cap = tmp_path / "cap"
    if case == "capture":  # a capture directory: the rollout's files with a capture spec
        import shutil

        shutil.copytree(rolled, cap)
        meta = json.loads((cap / "capture.json").read_text())
        meta["spec"].pop("rollout")
        from bullet_dlo.data.storage import spec_digest

        meta["digest"] = spec_digest(meta["spec"])  # a consistent capture.json (an edited one is refused)
        (cap / "capture.json").write_text(json.dumps(meta))
    target = {"capture": tmp_path / "a.hdf5", "exists": tmp_path / "old.hdf5", "suffix": tmp_path / "a.txt"}[case]
    source = cap if case == "capture" else rolled
    assert main(["export", "robomimic", str(source), str(target)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0], err
    assert not (tmp_path / "a.hdf5").exists()


ROBOMIMIC_PYTHON = os.environ.get("BULLET_DLO_ROBOMIMIC_PYTHON")
READ = """
import json, sys
import numpy as np
import robomimic.utils.obs_utils as ObsUtils
from robomimic.utils.dataset import SequenceDataset
keys = sys.argv[2].split(",")
ObsUtils.initialize_obs_utils_with_obs_specs({"obs": {"low_dim": keys, "rgb": []}})
ds = SequenceDataset(hdf5_path=sys.argv[1], obs_keys=keys, dataset_keys=("actions", "rewards", "dones"),
                     load_next_obs=True, frame_stack=1, seq_length=1, pad_frame_stack=True, pad_seq_length=True,
                     get_pad_mask=False, goal_mode=None, hdf5_cache_mode="all", hdf5_use_swmr=True,
                     hdf5_normalize_obs=False, filter_by_attribute=None)
items = [ds[i] for i in range(len(ds))]
np.savez(sys.argv[3], n=len(ds), actions=np.stack([it["actions"][0] for it in items]),
         **{"obs_" + k: np.stack([it["obs"][k][0] for it in items]) for k in keys})
"""


@pytest.mark.skipif(not ROBOMIMIC_PYTHON, reason="set BULLET_DLO_ROBOMIMIC_PYTHON to a Python with robomimic installed "
                    "(pip install robomimic pulls torch: its own venv; docs/guides/datasets.md says how)")
def test_robomimic_sequence_dataset_reads_every_sample(rolled, tmp_path):
    res = export_robomimic(rolled, tmp_path / "r.hdf5")
    (tmp_path / "read.py").write_text(READ)
    run = subprocess.run([ROBOMIMIC_PYTHON, str(tmp_path / "read.py"), str(tmp_path / "r.hdf5"), ",".join(res.obs_keys),
                          str(tmp_path / "got.npz")], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    got = np.load(tmp_path / "got.npz")
    assert int(got["n"]) == res.samples
    with h5py.File(tmp_path / "r.hdf5") as f:
        demos = [f[f"data/demo_{i}"] for i in range(res.demos)]
        np.testing.assert_allclose(got["actions"], np.concatenate([d["actions"][()] for d in demos]), rtol=0, atol=1e-6)
        for key in res.obs_keys:
            np.testing.assert_allclose(got["obs_" + key], np.concatenate([d[f"obs/{key}"][()] for d in demos]),
                                       rtol=0, atol=1e-6)
