"""Stand-in episodes for the old-tare warning (issue 27): grasp-frame quaternions, no physics.

Episode 0: recorded with payload compensation, gripper turned 0.5 rad; 1: old tare, no turn;
2: old tare, turned 0.5 rad about the cable (x) axis; 3: old tare, turned 0.005 rad (below the
warning's threshold); 4: compensated and with the Newton-Euler transmitted wrench, turned 0.5 rad.
Rows are 0.1 s apart: 0.5 rad is 1.25 rad/s, 0.005 rad 0.0125 rad/s. Importable by name in spawned workers (they get the coordinator's sys.path).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.data.storage import episode_result, write_episode

TURNS = {0: 0.5, 1: 0.0, 2: 0.5, 3: 0.005, 4: 0.5}  # [rad] about world x, by episode
COMPENSATED = {0, 4}
TRANSMITTED = {4}  # recorded with sensor_transmitted (since issue 27's Newton-Euler wrench)


def old_tare_episode(spec_dict: dict, index: int, out_dir: str) -> dict:
    spec = CaptureSpec.from_dict(spec_dict)
    grasp = Rotation.from_euler("y", np.pi)  # top grasp: approach axis (z) pointing down
    quats = [(Rotation.from_rotvec([a, 0.0, 0.0]) * grasp).as_quat()
             for a in np.linspace(0.0, TURNS[index], 5)]
    ee_quat = np.stack([np.stack([grasp.as_quat(), q]) for q in quats])  # (5, 2, 4): the right arm turns
    params = {"episode_value": float(index)}
    decision = {"action": "none", "substeps": 1}
    metrics = {"hf_energy": 0.0, "peak_to_mean": 1.0, "sensor_model_rms": 0.0}
    attrs = {"params": params, "decision": decision, "metrics": metrics, "episode": index, "stable": True,
             "time_to_instability": -1.0, "spec_digest": spec.digest()}
    if index in COMPENSATED:
        attrs["sensor_compensation"] = "urdf"
    if index in TRANSMITTED:
        attrs["sensor_transmitted"] = "newton_euler"
    name = write_episode(out_dir, index, {"t": np.arange(5) * 0.1, "ee_quat": ee_quat}, attrs)
    return episode_result(index, name, True, None, None, params, decision, metrics)
