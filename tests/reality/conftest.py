"""What the beam_handling tests share: where the recordings are, and the held-out split they validate on."""
from __future__ import annotations

from pathlib import Path

import pytest

BEAM_DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "beam_handling"


@pytest.fixture
def z_split(tmp_path) -> dict[str, Path]:
    """Folders "fit" (ocp_Z_15cm) and "predict" (ocp_Z_35cm, held out), each with its recording linked in place
    (never copied); skipped with the reason where the recordings are absent."""
    if not BEAM_DATA.is_dir():
        pytest.skip(f"beam_handling recordings not found at {BEAM_DATA} (see ../shared/data/README.md)")
    folders = {}
    for role, stem in (("fit", "ocp_Z_15cm_0.42s_1"), ("predict", "ocp_Z_35cm_0.61s_1")):
        folders[role] = tmp_path / role
        folders[role].mkdir()
        (folders[role] / f"{stem}.csv").symlink_to(BEAM_DATA / f"{stem}.csv")
    return folders
