"""Compile time is said and never counted as run time (issue 25 item 4): the notice before a command that
compiles, the cold-cache test behind it, and the engine's zero-step call that loads the kernels before its
timer starts without changing the run."""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from bullet_dlo._numba_cache import cache_folder, kernels_cold
from bullet_dlo.cli.main import compile_notice
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec


def test_a_cache_without_kernel_index_files_is_cold(tmp_path):
    (tmp_path / "core" / "kernels").mkdir(parents=True)
    (tmp_path / "core" / "kernels" / "loop.py").write_text("@njit\ndef run_loop(): ...\n")
    cache = cache_folder(tmp_path) / "core" / "kernels"
    cache.mkdir(parents=True)
    (cache / "forces.stretch-12.py311.nbi").write_bytes(b"")
    assert kernels_cold(tmp_path)  # other kernels cached, the time loop not: its first run compiles
    (cache / "loop.run_loop-37.py311.nbi").write_bytes(b"")
    assert not kernels_cold(tmp_path)
    (tmp_path / "core" / "kernels" / "loop.py").write_text("@njit\ndef run_loop(): return 1\n")
    assert kernels_cold(tmp_path)  # an edited kernel: a new folder, nothing in it yet


def _compile_a_fresh_kernel() -> None:
    from numba import njit

    njit(lambda a: a + 1)(1.0)  # a new function: never in any cache, so Numba compiles it


def test_the_notice_is_one_stderr_line_at_the_first_compile_unless_quiet(monkeypatch, capsys):
    monkeypatch.setattr("bullet_dlo._numba_cache.kernels_cold", lambda: True)
    with compile_notice(argparse.Namespace(command="simulate", quiet=False)):
        assert capsys.readouterr().err == ""  # nothing yet: bad input is refused before any kernel compiles
        _compile_a_fresh_kernel()
        _compile_a_fresh_kernel()
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "compiling the numerical kernels once" in err[0]  # once, at the first compile
    _compile_a_fresh_kernel()  # after the command: nothing
    for args in (argparse.Namespace(command="simulate", quiet=True), argparse.Namespace(command="examples", quiet=False)):
        with compile_notice(args):
            _compile_a_fresh_kernel()
    monkeypatch.setattr("bullet_dlo._numba_cache.kernels_cold", lambda: False)
    with compile_notice(argparse.Namespace(command="grasp", quiet=False)):
        _compile_a_fresh_kernel()
    assert capsys.readouterr().err == ""


def test_bad_input_on_a_cold_cache_is_one_line(monkeypatch, capsys):
    from bullet_dlo.cli.main import main

    monkeypatch.setattr("bullet_dlo._numba_cache.kernels_cold", lambda: True)
    scene = Path(__file__).resolve().parents[2] / "demos" / "scenes" / "lv_study.yaml"
    assert main(["simulate", str(scene), "--dt", "-1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and "dt" in err[0], err


def test_the_loading_call_changes_nothing_and_is_reported_apart():
    model = CableModel.straight(CableSpec.lv2017(n_masses=6, damping_rate=1.0))
    a, b = (simulate(model, "bdf2", 1e-3, 0.05) for _ in range(2))
    assert np.array_equal(a.x, b.x) and np.array_equal(a.end_forces, b.end_forces)
    assert a.compile_time_s >= 0.0 and b.compile_time_s >= 0.0 and a.wall_time_s > 0.0
    assert a.x.shape[0] == 51 and a.steps == 50  # the zero-step call records no extra row
