"""The kernels every integrator reaches are compiled once: one signature each in Numba's cache.

Numba compiles a kernel called from compiled code once per argument type, and a constant argument has its own
type: ``f(x, 0)`` and ``f(x, 1)`` (``Literal[int](0)``, ``Literal[int](1)``), ``f(x, True)`` and ``f(x, flag)``
are separate compilations, each with everything the kernel calls linked in and emitted again. Such splits made
the coupled twisting step's Newton matrix compile five times, its residual and clamp rate three, RK4's stage four
(2026-12-01, cold cache: 573 s of CPU for the core part of ``tests/warm_kernels.py``, 479 s without them). This
test runs every integrator on a twisting cable, then reads each kernel's cache index, which holds every signature
compiled for the present sources by any process, and names the arguments whose types differ.
"""
from __future__ import annotations

import os

import pytest

from bullet_dlo.core.boundary import Move, Waypoints
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.kernels import holders, steppers, twist_coupled
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec

INTEGRATORS = ("explicit_euler", "symplectic_euler", "rk4", "implicit_euler", "bdf2", "implicit_midpoint",
               "gauss_legendre")
KERNELS = (twist_coupled._newton_matrix, twist_coupled._residual, twist_coupled._clamp_rate,
           twist_coupled._explicit_forces, twist_coupled._finish, steppers._rk4_stage,
           holders.sample_end, holders.held_pose, holders._end_at_rest, holders._rest_end, holders.quintic)


def _signatures(kernel) -> list[tuple]:
    """The argument types of every signature in ``kernel``'s cache index (Numba's index: {(signature, target,
    source hashes): file})."""
    return [key[0] for key in kernel._cache._cache_file._load_index()]


def _differing(signatures: list[tuple], names: tuple[str, ...]) -> list[str]:
    """'name: type | type' for each argument position whose types differ between the signatures."""
    return [f"{names[i]}: {' | '.join(sorted({str(s[i]) for s in signatures}))}"
            for i in range(len(signatures[0])) if len({s[i] for s in signatures}) > 1]


@pytest.mark.skipif(os.environ.get("NUMBA_DISABLE_JIT", "0") != "0", reason="NUMBA_DISABLE_JIT: nothing is compiled")
def test_every_integrators_kernels_have_one_signature():
    path = Waypoints("first", (0.0, 1e-3, 2e-3), ((0, 0, 0), (0, 0, 1e-3), (0, 1e-3, 0)),
                     rotations=((0, 0, 0), (0.1, 0, 0), (0.1, 0.1, 0)))  # quintic segments (holders.quintic)
    moves = [Move("last", (0.0, 0.01, 0.005), 0.0, 0.01, rotation=(0.3, 0.0, 0.0)), path]
    model = CableModel.straight(CableSpec.lv2017(n_masses=6, twist=True), ends=("clamped", "clamped"), motion=moves)
    for integrator in INTEGRATORS:
        assert simulate(model, integrator, 1e-4, 2e-3, max_records=3).stable or integrator == "explicit_euler"
    indexed = [kernel for kernel in KERNELS if _signatures(kernel)]
    # a callee's index is missing only where its caller was loaded from the cache and the callee's own index was
    # dropped (deleted, or its source file touched since): nothing to count there, but something must be
    assert indexed, "none of the kernels has a cache index after every integrator ran"
    for kernel in indexed:
        sigs = _signatures(kernel)
        names = kernel.py_func.__code__.co_varnames
        assert len(sigs) == 1, f"{kernel.py_func.__name__} compiled {len(sigs)} times; {_differing(sigs, names)}"
