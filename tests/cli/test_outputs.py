"""Every command that writes numbers writes the picture beside them and ends with one ``outputs:`` line;
``--plot`` names it, ``--no-plot`` leaves it out; a reader that closes the pipe stops the command quietly."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bullet_dlo.cli.main import main

ROOT = Path(__file__).resolve().parents[2]
HANGING = ROOT / "demos" / "scenes" / "hanging.yaml"
STIFF = ROOT / "demos" / "scenes" / "stiff_60hz.yaml"


def picture(path: Path) -> np.ndarray:
    import imageio.v3 as iio

    img = iio.imread(path)
    assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 300
    return img


def last_line(capsys) -> str:
    return capsys.readouterr().out.strip().splitlines()[-1]


def test_simulate_writes_its_picture_beside_the_json(tmp_path, capsys):
    assert main(["simulate", str(HANGING), "--duration", "0.05", "--json", str(tmp_path / "h.json"), "-q"]) == 0
    assert last_line(capsys) == f"outputs: {tmp_path / 'h.json'}, {tmp_path / 'h.png'}"
    img = picture(tmp_path / "h.png")
    assert img[..., :3].std() > 10  # not blank
    assert main(["simulate", str(HANGING), "--duration", "0.05", "--npz", str(tmp_path / "n.npz"), "--no-plot",
                 "-q"]) == 0
    assert not (tmp_path / "n.png").exists() and last_line(capsys) == f"outputs: {tmp_path / 'n.npz'}"
    assert main(["simulate", str(HANGING), "--duration", "0.05", "--plot", str(tmp_path / "p" / "x.png"), "-q"]) == 0
    picture(tmp_path / "p" / "x.png")


def test_stability_and_convergence_write_their_charts(tmp_path, capsys):
    assert main(["stability", str(STIFF), "--plot", str(tmp_path / "s.png"), "-q"]) == 0
    assert last_line(capsys) == f"outputs: {tmp_path / 's.png'}"
    picture(tmp_path / "s.png")
    assert main(["convergence", "--masses", "5", "10", "--json", str(tmp_path / "c.json"), "-q"]) == 0
    picture(tmp_path / "c.png")


def test_a_bad_plot_name_is_one_line_and_exit_2(tmp_path, capsys):
    assert main(["simulate", str(HANGING), "--duration", "0.05", "--plot", str(tmp_path / "x.jpg"), "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--plot must end in .png" in err[0]


@pytest.mark.bullet
def test_grasp_writes_the_wrist_force_plot_and_times_its_first_step_apart(tmp_path, capsys):
    assert main(["grasp", "--duration", "0.1", "--json", str(tmp_path / "g.json"), "-q"]) == 0
    out = capsys.readouterr().out
    assert out.strip().splitlines()[-1] == f"outputs: {tmp_path / 'g.json'}, {tmp_path / 'g.png'}"
    data = json.loads((tmp_path / "g.json").read_text())
    assert data["first_step_s"] > 0.0 and data["wall_time_s"] > 0.0
    assert f"{data['steps'] - 1} steps in" in out and "after a first step of" in out
    picture(tmp_path / "g.png")


def test_a_closed_pipe_ends_quietly():
    """``bullet-dlo stability ... | head -1``: exit 141 (SIGPIPE's), no traceback on stderr."""
    proc = subprocess.run(f"{sys.executable} -m bullet_dlo.cli stability {STIFF} --no-plot | head -1",
                          shell=True, capture_output=True, text=True, timeout=300, executable="/bin/bash")
    assert proc.stdout.count("\n") == 1 and "stiff_60hz" in proc.stdout
    assert "Traceback" not in proc.stderr and "Error" not in proc.stderr, proc.stderr
