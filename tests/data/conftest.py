"""What the export tests share: two short policy rollouts of TensionTracking-v0 (scripted policy, 8 control
steps each, recorded at 60 Hz), made once per test module."""
from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="module")
def rolled(tmp_path_factory) -> Path:
    from bullet_dlo.envs.rollouts import record_rollouts

    out = tmp_path_factory.mktemp("rollouts") / "roll"
    record_rollouts("bullet_dlo/TensionTracking-v0", "scripted", out, 2, record_rate=60.0,
                    env_kwargs={"settle_time": 0.05, "max_episode_steps": 8}, progress=False)
    return out
