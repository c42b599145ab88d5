"""Issue 27, item 3 for captures: every recorded wrist sample is checked against the load the cable
applied; an episode whose gripper is driven into the table (a load on the hand the cable model does
not hold, robots.dual_arm.observation.SENSOR_CHECK) is flagged with the check's reason and its
metrics; a gripper turning 1.2 rad about the cable in 0.5 s is not (with Bullet's joint reaction it
read a cable weight off and was flagged)."""
from __future__ import annotations

import h5py
import pytest

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.data.episode import run_episode


def spec(rotation: list[float], duration: float, displacement=(0, 0, 0)) -> dict:
    return CaptureSpec.from_dict({
        "seed": 3, "episode": {"duration": duration + 0.3, "record_rate": 60},
        "sample": {"robot": {"dist": "fixed", "value": "panda"}, "n_masses": {"dist": "fixed", "value": 8},
                   "dt": {"dist": "fixed", "value": 0.004166666666666667}},
        "motion": [{"type": "move", "end": "last", "displacement": list(displacement), "rotation": rotation,
                    "start": 0.1, "duration": duration}],
    }).to_dict()


@pytest.mark.parametrize("rotation, duration, displacement, flagged",
                         [([1.2, 0, 0], 0.5, (0, 0, 0), False), ([0, 0, 0], 1.0, (-0.08, 0, -0.36), True)])
def test_a_capture_flags_an_episode_whose_sensors_leave_the_model(tmp_path, rotation, duration, displacement,
                                                                 flagged):
    record = run_episode(spec(rotation, duration, displacement), 0, str(tmp_path))
    assert record["metrics"]["sensor_check_force"] >= 0.0
    if flagged:
        assert record["status"] == "flagged" and "wrist force differs from the cable's load" in record["reason"]
    else:
        assert record["status"] == "ok", record["reason"]
        assert record["metrics"]["sensor_check_force"] < 1e-6
        (path,) = tmp_path.glob("*.h5")
        with h5py.File(path) as f:  # files without this attribute took Bullet's joint reaction
            assert f.attrs["sensor_transmitted"] == "newton_euler"
