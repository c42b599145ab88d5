"""A stand-in episode for capture bookkeeping tests: no physics, controlled by marker files.

``fake_episode(spec_dict, index, out)`` writes a small but real episode file (so a lost manifest
line can be rebuilt from it) and returns its record. Marker files in ``out`` make it misbehave:
``kill-once-<i>`` (removed, then the worker SIGKILLs itself), ``kill-always-<i>``, ``slow``
(sleep that many seconds first), ``full-<i>`` (writing episode i fails as on a full disk). It writes ``pid-<i>`` with its worker's pid before anything else.
Importable by name in spawned workers (they get the coordinator's sys.path).
"""
from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import numpy as np

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.data.storage import episode_result, write_episode


def fake_episode(spec_dict: dict, index: int, out_dir: str) -> dict:
    out = Path(out_dir)
    (out / f"pid-{index}").write_text(str(os.getpid()))
    slow = out / "slow"
    if slow.exists():
        time.sleep(float(slow.read_text()))
    once = out / f"kill-once-{index}"
    if once.exists():
        once.unlink()
        os.kill(os.getpid(), signal.SIGKILL)
    if (out / f"kill-always-{index}").exists():
        os.kill(os.getpid(), signal.SIGKILL)
    if (out / f"full-{index}").exists():
        import errno

        from bullet_dlo.data.safeio import StorageError

        raise StorageError(out / f"episode_{index:06d}.h5", OSError(errno.ENOSPC, os.strerror(errno.ENOSPC)))
    spec = CaptureSpec.from_dict(spec_dict)
    params = {"episode_value": float(index)}
    decision = {"action": "none", "substeps": 1}
    metrics = {"hf_energy": 0.0, "peak_to_mean": 1.0, "sensor_model_rms": 0.0}
    attrs = {"params": params, "decision": decision, "metrics": metrics, "episode": index, "stable": True,
             "time_to_instability": -1.0, "spec_digest": spec.digest()}
    name = write_episode(out, index, {"t": np.arange(3) * 0.1}, attrs)
    return episode_result(index, name, True, None, None, params, decision, metrics)
