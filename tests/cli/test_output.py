"""What the command line prints: --quiet leaves only results and errors; progress goes to stderr; --help
explains every option; paper-table computes only the tables asked for."""
from __future__ import annotations

import argparse
import re
import subprocess
import sys

from bullet_dlo.cli.main import build_parser, main

SCENE = """
cable: {preset: lv2017, n_masses: 8}
layout: {start: [0, 0, 0.3], direction: [1, 0, 0]}
ends: {first: clamped, last: free}
dt: 0.004166666666666667
duration: 0.3
"""


def run_cli(*args: str, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bullet_dlo.cli", *args], capture_output=True, text=True,
                          timeout=300, cwd=cwd)


def test_quiet_render_prints_exactly_its_results(tmp_path):
    scene = tmp_path / "s.yaml"
    scene.write_text(SCENE)
    args = ["render", str(scene), "--out", str(tmp_path / "r"), "--width", "160", "--height", "120", "--fps", "10"]
    loud = run_cli(*args)
    assert loud.returncode == 0, loud.stderr
    assert "pybullet build time" in loud.stdout + loud.stderr  # what --quiet has to remove, from C code
    assert "rendering" in loud.stderr  # the progress bar
    quiet = run_cli("--quiet", *args)
    assert quiet.returncode == 0
    assert quiet.stderr == ""
    lines = quiet.stdout.splitlines()
    assert len(lines) == 2, quiet.stdout
    assert re.fullmatch(r"renderer: (egl|tiny) \(.+\); 4 frames, mp4 \(h264\) in \d+\.\d s", lines[0])
    assert lines[1] == f"outputs written to {(tmp_path / 'r').resolve()}"


def test_quiet_keeps_errors(tmp_path):
    res = run_cli("simulate", str(tmp_path / "missing.yaml"), "-q")
    assert res.returncode == 2 and res.stdout == ""
    assert res.stderr.startswith("error: ") and len(res.stderr.splitlines()) == 1


def test_quiet_output_drops_c_level_writes_even_buffered_ones():
    code = ("import ctypes, os\n"
            "from bullet_dlo.cli.quiet import quiet_output\n"
            "with quiet_output():\n"
            "    os.write(1, b'fd1 noise\\n'); os.write(2, b'fd2 noise\\n')\n"
            "    ctypes.CDLL(None).printf(b'buffered C noise\\n')\n"
            "    print('result')\n"
            "print('after')\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr
    assert res.stdout == "result\nafter\n" and res.stderr == ""


def test_progress_on_stderr_unless_quiet(capsys):
    assert main(["convergence", "--masses", "5", "10"]) == 0
    captured = capsys.readouterr()
    assert "convergence" in captured.err and "| 10 | +1.234 % |" in captured.out  # (L/(n-1))^2/L^2 = 1/81
    assert main(["convergence", "--masses", "5", "10", "--quiet"]) == 0
    captured = capsys.readouterr()
    assert captured.err == "" and "| 10 | +1.234 % |" in captured.out


def test_every_option_of_every_command_is_explained():
    def walk(parser: argparse.ArgumentParser, path: str):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, child in action.choices.items():
                    yield from walk(child, f"{path} {name}")
            elif not isinstance(action, argparse._HelpAction):
                yield path, action

    actions = list(walk(build_parser(), "bullet-dlo"))
    assert len(actions) > 60
    missing = [f"{path} {a.option_strings or a.dest}" for path, a in actions if not (a.help and len(a.help) > 8)]
    assert missing == []


def test_paper_table_computes_only_the_tables_asked_for(tmp_path):
    md = tmp_path / "rates.md"
    assert main(["paper-table", "--tables", "rates", "--moduli", "12.6", "--masses", "6", "--rate-duration", "0.1",
                 "--markdown", str(md), "-q"]) == 0
    text = md.read_text()
    assert "robot-simulator rates" in text and "study's time steps" not in text
    rows = [line.split("|") for line in text.splitlines() if line.startswith("| 12.6")]
    assert [r[3].strip() for r in rows] == ["0.001", "0.0167"]  # 1 kHz and 60 Hz only
    # symplectic Euler's limit is 1.58 ms here: stable at 1 kHz, unstable at 60 Hz; implicit methods stable at both
    assert rows[0][6].strip() == "stable" and rows[1][6].strip().startswith("unstable@")
    assert all(cell.strip() == "stable" for r in rows for cell in r[7:10])
    assert run_cli("paper-table", "--tables", "base,nope").returncode == 2
