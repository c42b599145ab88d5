"""Issue 27, item 3 for captures: every recorded wrist sample is checked against the load the cable
applied; an episode whose gripper turns fast enough for the reading to leave the model's load
(Bullet's joint reaction while the hand spins, see robots.dual_arm.observation.SENSOR_CHECK) is
flagged with the check's reason and its metrics; the same episode turned slowly about the vertical
is not."""
from __future__ import annotations

import pytest

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.data.episode import run_episode


def spec(rotation: list[float], duration: float) -> dict:
    return CaptureSpec.from_dict({
        "seed": 3, "episode": {"duration": duration + 0.3, "record_rate": 60},
        "sample": {"robot": {"dist": "fixed", "value": "panda"}, "n_masses": {"dist": "fixed", "value": 8},
                   "dt": {"dist": "fixed", "value": 0.004166666666666667}},
        "motion": [{"type": "move", "end": "last", "displacement": [0, 0, 0], "rotation": rotation,
                    "start": 0.1, "duration": duration}],
    }).to_dict()


@pytest.mark.parametrize("rotation, duration, flagged", [([1.2, 0, 0], 0.5, True), ([0, 0, 0.2], 1.0, False)])
def test_a_capture_flags_an_episode_whose_sensors_leave_the_model(tmp_path, rotation, duration, flagged):
    record = run_episode(spec(rotation, duration), 0, str(tmp_path))
    assert record["metrics"]["sensor_check_force"] >= 0.0
    if flagged:
        assert record["status"] == "flagged" and "wrist force differs from the cable's load" in record["reason"]
    else:
        assert record["status"] == "ok", record["reason"]
