"""Compile time is said and never counted as run time (issue 25 item 4): the notice before a command that
compiles, the cold-cache test behind it, and the engine's zero-step call that loads the kernels before its
timer starts without changing the run."""
from __future__ import annotations

import argparse

import numpy as np

from bullet_dlo._numba_cache import kernels_cold
from bullet_dlo.cli.main import compile_notice
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec


def test_a_cache_without_kernel_index_files_is_cold(tmp_path):
    cache = tmp_path / "core" / "kernels" / "__pycache__"
    cache.mkdir(parents=True)
    (cache / "forces.stretch-12.py311.nbi").write_bytes(b"")
    assert kernels_cold(tmp_path)  # other kernels cached, the time loop not: its first run compiles
    (cache / "loop.run_loop-37.py311.nbi").write_bytes(b"")
    assert not kernels_cold(tmp_path)


def test_the_notice_is_one_stderr_line_for_commands_that_compile_unless_quiet(monkeypatch, capsys):
    monkeypatch.setattr("bullet_dlo._numba_cache.kernels_cold", lambda: True)
    compile_notice(argparse.Namespace(command="simulate", quiet=False))
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "compiling the numerical kernels once" in err[0]
    compile_notice(argparse.Namespace(command="simulate", quiet=True))
    compile_notice(argparse.Namespace(command="examples", quiet=False))
    monkeypatch.setattr("bullet_dlo._numba_cache.kernels_cold", lambda: False)
    compile_notice(argparse.Namespace(command="grasp", quiet=False))
    assert capsys.readouterr().err == ""


def test_the_loading_call_changes_nothing_and_is_reported_apart():
    model = CableModel.straight(CableSpec.lv2017(n_masses=6, damping_rate=1.0))
    a, b = (simulate(model, "bdf2", 1e-3, 0.05) for _ in range(2))
    assert np.array_equal(a.x, b.x) and np.array_equal(a.end_forces, b.end_forces)
    assert a.compile_time_s >= 0.0 and b.compile_time_s >= 0.0 and a.wall_time_s > 0.0
    assert a.x.shape[0] == 51 and a.steps == 50  # the zero-step call records no extra row
