"""Policy rollouts in robomimic's HDF5 layout (one file), as robomimic's ``SequenceDataset`` reads it.

robomimic (0.3) keeps demonstrations in one HDF5 file::

    data/                      attrs: total (samples in all demos), env_args (JSON: env_name, type, env_kwargs)
    data/demo_<i>/             attrs: num_samples, bullet_dlo/params (the episode's randomised parameters, JSON)
        actions   (N, A)       the policy's action at each control step, in [-1, 1]
        rewards   (N,)         the step's reward
        dones     (N,)         1 at the episode's last step, else 0
        obs/<key> (N, ...)     the observation the action was taken on
        next_obs/<key> (N, ...) the observation after the step
    mask/train                 every demo's name (bytes)

The observation keys are the environment's own (:mod:`bullet_dlo.envs.dual_arm_env`): ``joint_q``
[rad], ``joint_qd`` [rad/s], ``gripper_pos`` [m], ``gripper_quat`` (x, y, z, w), ``wrench`` [N, N m]
(tared, world frame, left then right arm) and ``task``, each flattened per step (robomimic's
``low_dim`` modality wants (N, D)). Only rollouts can be written: a force capture has no actions,
which robomimic's dataset needs. ``env_args`` names the Gymnasium id (robomimic's ``EnvType.GYM_TYPE``,
2) so robomimic's ``EnvUtils`` can build it where this package is installed.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bullet_dlo.core.validate import ParameterError

GYM_TYPE = 2  # robomimic.envs.env_base.EnvType.GYM_TYPE
OBS_PREFIX = "obs_"


@dataclass(frozen=True)
class RobomimicResult:
    """A written file: its path, the demos and samples it holds, the observation keys, and the episodes left
    out (episode, status)."""

    out: Path
    demos: int
    samples: int
    obs_keys: tuple[str, ...]
    skipped: tuple[tuple[int, str], ...]


def export_robomimic(dataset_dir: str | Path, out_path: str | Path, *, include_flagged: bool = False) -> RobomimicResult:
    """Write the rollout directory ``dataset_dir`` as one robomimic HDF5 file ``out_path`` (new; see the module
    doc). ParameterError for bad input (not a rollout directory, an existing file, no episode to write)."""
    import h5py

    from bullet_dlo.data.reader import Dataset

    dataset_dir, out_path = Path(dataset_dir), Path(out_path)
    if not dataset_dir.is_dir():
        raise ParameterError(f"DATASET {dataset_dir} is not a directory")
    if out_path.suffix.lower() not in (".hdf5", ".h5"):
        raise ParameterError(f"OUT must end in .hdf5 or .h5, got {out_path.name!r}")
    if out_path.exists():
        raise ParameterError(f"OUT {out_path} exists: give a new file")
    ds = Dataset(dataset_dir)
    spec = ds.spec["spec"]
    if "rollout" not in spec:
        raise ParameterError(f"{dataset_dir} is a force capture: robomimic's layout needs the policy's actions, "
                             "which only rollouts have (bullet-dlo rollouts ...); use export lerobot for captures")
    statuses = ("ok", "flagged") if include_flagged else ("ok",)
    records = [r for r in ds.records if r["status"] in statuses]
    skipped = tuple((int(r["episode"]), str(r["status"])) for r in ds.records if r["status"] not in statuses)
    if not records:
        raise ParameterError(f"{dataset_dir} has no episode of status {' or '.join(statuses)} to export")
    env_id = spec["rollout"]["env_id"]
    out_path.parent.mkdir(parents=True, exist_ok=True)
    tmp = out_path.with_name(out_path.name + ".part")  # a killed export leaves no file that looks whole
    total, keys = 0, ()
    try:
        with h5py.File(tmp, "w") as f:
            data = f.create_group("data")
            names = []
            for i, record in enumerate(records):
                ep = ds.load(record)
                actions = np.asarray(ep["action"], dtype=np.float64)
                n = len(actions)
                obs = {k[len(OBS_PREFIX):]: np.asarray(v) for k, v in ep.items() if k.startswith(OBS_PREFIX)}
                if any(len(v) != n + 1 for v in obs.values()):
                    raise ParameterError(f"{record.get('file')}: expected {n + 1} observations for {n} actions")
                keys = tuple(sorted(obs))
                demo = data.create_group(f"demo_{i}")
                demo.attrs["num_samples"] = n
                demo.attrs["bullet_dlo/episode"] = int(record["episode"])
                demo.attrs["bullet_dlo/params"] = json.dumps(ep.get("params", {}), sort_keys=True, default=str)
                demo.create_dataset("actions", data=actions)
                demo.create_dataset("rewards", data=np.asarray(ep["reward"], dtype=np.float64))
                dones = np.zeros(n, dtype=np.int64)
                dones[-1] = 1
                demo.create_dataset("dones", data=dones)
                for group, rows in (("obs", slice(0, n)), ("next_obs", slice(1, n + 1))):
                    g = demo.create_group(group)
                    for key, value in obs.items():
                        g.create_dataset(key, data=value[rows].reshape(n, -1))
                names.append(f"demo_{i}")
                total += n
            data.attrs["total"] = total
            data.attrs["env_args"] = json.dumps({"env_name": env_id, "type": GYM_TYPE,
                                                 "env_kwargs": spec["rollout"].get("env_kwargs", {})}, default=str)
            f.create_group("mask").create_dataset("train", data=np.array(names, dtype="S"))
        tmp.replace(out_path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return RobomimicResult(out_path, len(records), total, keys, skipped)
