"""Issue 26: a Ctrl-C while ``bullet-dlo`` loads its libraries (about a second of NumPy, SciPy and Numba
imports) printed their import traceback; a Ctrl-C during a command other than capture and rollouts
printed the command's. Both are one line now, with exit code 130 (interrupted)."""
from __future__ import annotations

import importlib
import subprocess
import sys

from bullet_dlo import _interrupt
from bullet_dlo.cli.main import main


def test_an_interrupt_while_loading_is_one_line_and_exit_130():
    # the command line's process (argv[0] names it), interrupted right after the package loaded
    code = "import sys; sys.argv[0] = '/usr/local/bin/bullet-dlo'; import bullet_dlo; raise KeyboardInterrupt"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode in (130, -2), proc  # killed by SIGINT, as Python reports an uncaught interrupt
    assert proc.stderr.strip().splitlines() == [_interrupt.MESSAGE], proc.stderr
    # a library user's process keeps Python's own report
    plain = subprocess.run([sys.executable, "-c", "import bullet_dlo; raise KeyboardInterrupt"],
                           capture_output=True, text=True, timeout=120)
    assert "Traceback" in plain.stderr


def test_an_interrupt_during_a_command_is_one_line_and_exit_130(monkeypatch, capsys, tmp_path):
    cli_main = importlib.import_module("bullet_dlo.cli.main")  # the module (bullet_dlo.cli.main is also a function)

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli_main, "check_outputs", interrupted)  # runs inside the command's try, for any command
    scene = tmp_path / "s.yaml"
    scene.write_text("cable: {preset: lv2017, n_masses: 5}\nduration: 0.01\n")
    assert main(["simulate", str(scene)]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("interrupted (Ctrl-C)"), err
