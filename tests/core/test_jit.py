"""The package's ``njit`` (core/kernels/jit.py): inlined kernels without reference counting, results unchanged.

``total_forces`` is inlined with the model's 27 arrays; with Numba's own pipeline each call in a compiled loop paid
an atomic increment and decrement per array of each inlined copy of the tuple (86 per call at n = 10, 1.12 us
against 0.26 us without, 2026-12-03). The package's pipeline forwards those copies: no copy of the tuple is counted
in the loop, and every force and Jacobian entry is the same bit for bit.
"""
from __future__ import annotations

import numba
import numpy as np

from bullet_dlo import _numba_cache
from bullet_dlo.core.kernels import forces as F
from bullet_dlo.core.kernels.jit import ForwardingCompiler, njit
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec
from llvm_loops import loop_increfs


def _forces_loop(m, x, v, dirs, out, jac, reps):
    s = 0.0
    for _ in range(reps):
        F.total_forces(m, x, v, dirs, out)
        F.force_jacobian(m, x, dirs, True, jac)
        F.add_damping_jacobian(m, x, dirs, 0.5, jac)
        s += out[1, 2] + jac[1, 2, 0, 0]
    return s


def _bent(spec: CableSpec) -> tuple:
    """Kernel arguments of a clamped-free cable bent out of its straight line (every spring loaded)."""
    model = CableModel.straight(spec, ends=("clamped", "free"))
    a = model.kernel_arrays(model.control())
    n = model.x0.shape[0]
    x = model.x0.copy()
    x[:, 2] += 0.02 * np.sin(np.linspace(0.0, 3.0, n)) ** 2
    v = 0.1 * np.cos(np.arange(3 * n, dtype=float)).reshape(n, 3)
    return a, x, v, model.holder_plan().start_dir


def test_inlined_model_kernels_compile_without_reference_counting_and_give_the_same_bits():
    ours = njit(_forces_loop)
    numbas = numba.njit(_forces_loop)
    assert ours._compiler.pipeline_class is ForwardingCompiler
    for kw in ({}, {"internal_damping": 1e-3}):  # with the Kelvin-Voigt dampers: their branch taken
        a, x, v, dirs = _bent(CableSpec.lv2017(n_masses=10, **kw))
        results = []
        for fn in (ours, numbas):
            out, jac = np.zeros_like(x), np.zeros((x.shape[0], 5, 3, 3))
            fn(a, x, v, dirs, out, jac, 2)
            results.append((out, jac))
        assert np.array_equal(results[0][0], results[1][0]) and np.array_equal(results[0][1], results[1][1])
        assert np.abs(results[0][0]).max() > 0.0 and np.abs(results[0][1]).max() > 0.0
    # left: one count per array read from the tuple and passed to a kernel that is not inlined (11); one copy of
    # the tuple would be 27 (Numba's pipeline: 100-200)
    count = loop_increfs(ours)
    assert count < len(a), f"{count} reference-count increments in the loop: a copy of the model's tuple is counted"


def test_forwarding_follows_chains_of_copies_and_keeps_reassigned_variables():
    def chains(a, k):
        b = a  # forwarded: b and c are a
        c = b
        d = a[0]
        for i in range(k):  # d is assigned twice: kept (a reassigned variable is never forwarded)
            d = d + c[i]
        e = d
        return e + b[1]

    a = np.arange(1.0, 6.0)
    assert njit(chains)(a, 4) == chains(a, 4) == 1.0 + 10.0 + 2.0


def test_the_compiler_is_hashed_with_the_kernels():
    """A change to the compiler's passes starts a new cache folder, as a change to a kernel does."""
    assert _numba_cache.PACKAGE / _numba_cache.JIT in _numba_cache.kernel_sources()
