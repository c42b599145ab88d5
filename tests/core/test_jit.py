"""The package's ``njit`` (core/kernels/jit.py): kernels without reference counting, results and ownership unchanged.

``total_forces`` is inlined with the model's 27 arrays; with Numba's own pipeline each call in a compiled loop paid
an atomic increment and decrement per array of each inlined copy of the tuple (86 per call at n = 10, 1.12 us
against 0.26 us without, 2026-12-03). The package's pipeline forwards those copies: no copy of the tuple is counted
in the loop, and every force and Jacobian entry is the same bit for bit.
"""
from __future__ import annotations

import re
from typing import NamedTuple

import numba
import numpy as np
import pytest
from numba.core import types
from numba.core.runtime import _nrt_python, rtsys
from numba.experimental import structref

from bullet_dlo import _numba_cache
from bullet_dlo.core.kernels import forces as F
from bullet_dlo.core.kernels.jit import KernelCompiler, njit
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec
from llvm_loops import loop_increfs, own_function


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
    assert ours._compiler.pipeline_class is KernelCompiler
    for kw in ({}, {"internal_damping": 1e-3}):  # with the Kelvin-Voigt dampers: their branch taken
        a, x, v, dirs = _bent(CableSpec.lv2017(n_masses=10, **kw))
        results = []
        for fn in (ours, numbas):
            out, jac = np.zeros_like(x), np.zeros((x.shape[0], 5, 3, 3))
            fn(a, x, v, dirs, out, jac, 2)
            results.append((out, jac))
        assert np.array_equal(results[0][0], results[1][0]) and np.array_equal(results[0][1], results[1][1])
        assert np.abs(results[0][0]).max() > 0.0 and np.abs(results[0][1]).max() > 0.0
    count = loop_increfs(ours)  # (Numba's pipeline: 92; forwarding the copies alone: 11, the fields passed on)
    assert count == 0, f"{count} reference-count increments in the loop: a copy or a field of a tuple is counted"


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


def test_a_kernel_borrows_its_arguments():
    """The spring forces (a loop and inlined helpers over six arrays): Numba's pipeline counts the arrays on entry
    and exit of every call (4 left after its pruning); the package's counts none."""
    ours = njit(error_model="numpy")(F._spring_forces.py_func)
    a, x, _, dirs = _bent(CableSpec.lv2017(n_masses=10))
    out = np.zeros_like(x)
    ours(a.k_stretch, a.rest_length, a.k_bend, x, dirs, out)
    assert np.abs(out).max() > 0.0
    assert own_function(ours).count("call void @NRT_incref") == 0


@njit
def _same(a):
    return a


@njit
def _pair(a, b):
    return a, b[0]


@njit
def _checked(a, limit):
    if a[0] > limit:
        raise ValueError("a[0] above the limit")
    return a[0]


class _Arrays(NamedTuple):
    first: np.ndarray
    inner: tuple


@njit
def _fields(p):
    q = p.inner  # a field of a field, read, returned and passed on
    return _same(p.first), q[0], _pair(q[1], p.first)


@njit
def _passes(a, k):
    s = 0.0
    for i in range(k):
        b = _same(a)  # an argument returned
        t = _pair(b, a)  # and kept in a tuple
        c = np.full(3, float(i))  # an array made here, passed on and returned
        f, g, (h, e) = _fields(_Arrays(c, (a, c)))  # a tuple made here, its fields borrowed by the callee
        s += t[0][0] + t[1] + _same(c)[1] + _checked(c, 1e9) + f[0] + g[0] + h[2] + e
    return s, _same(a), _pair(np.ones(2), a), _fields(_Arrays(np.zeros(2), (a, a)))


def test_borrowed_arguments_keep_every_reference_count_balanced():
    """Arguments returned, kept in tuples, made inside and passed on, read from (nested) tuple fields, and raised
    past: every allocation is freed once (Numba's allocation statistics), and the caller's array keeps its owners."""
    was_on = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()  # (NUMBA_NRT_STATS=1 does it at start-up)
    a = np.arange(1.0, 4.0)
    owners = __import__("sys").getrefcount(a)
    before = rtsys.get_allocation_stats()
    for _ in range(50):
        s, same, (ones, first), (zeros, inner, (inner_c, zero)) = _passes(a, 20)
        assert s == 20 * 1.0 + 20 * 1.0 + 2 * sum(range(20)) + 3 * sum(range(20)) + 20 * 1.0 and first == 1.0
        assert np.array_equal(same, a) and np.array_equal(ones, np.ones(2)) and np.array_equal(zeros, np.zeros(2))
        assert np.array_equal(inner, a) and np.array_equal(inner_c, a) and zero == 0.0
        with pytest.raises(ValueError, match="above the limit"):
            _checked(a, 0.5)
    del s, same, ones, first, zeros, inner, inner_c, zero
    after = rtsys.get_allocation_stats()
    if not was_on:
        _nrt_python.memsys_disable_stats()
    allocated, freed = after.mi_alloc - before.mi_alloc, after.mi_free - before.mi_free
    assert allocated > 1000 and allocated == freed  # (20 arrays a call, each freed once)
    assert __import__("sys").getrefcount(a) == owners


def test_every_kernel_of_the_package_compiles_with_its_compiler():
    """A kernel decorated with Numba's own njit would compile, pass every test and pay the counting again."""
    plain = [str(src.relative_to(_numba_cache.PACKAGE)) for src in _numba_cache.PACKAGE.rglob("*.py")
             if re.search(r"^\s*from numba import[^\n]*\bnjit\b|\bnumba\.njit\(|^\s*import numba\.njit", src.read_text(),
                          re.M) and src != _numba_cache.PACKAGE / _numba_cache.JIT]
    assert plain == [], f"import njit from bullet_dlo.core.kernels.jit in {plain}"


@structref.register
class _PackType(types.StructRef):
    fields_fixed = True  # no kernel below sets a field: they are lent like a tuple's

    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


@structref.register
class _OpenPackType(types.StructRef):  # fields may be set: read with their own counts
    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class _Pack(structref.StructRefProxy):
    pass


class _OpenPack(structref.StructRefProxy):
    pass


structref.define_proxy(_Pack, _PackType, ["first", "inner"])
structref.define_proxy(_OpenPack, _OpenPackType, ["first", "inner"])


@njit
def _pack_fields(p, k):
    s = 0.0
    for i in range(k):
        f, g = _same(p.first), p.inner[1]  # fields read, passed on, returned
        s += f[0] + g[i % 2] + _fields(_Arrays(p.first, p.inner))[1][0]
    return s, p.first, _pair(p.inner[0], p.first)


@njit
def _replace_field(p, a):
    old = p.first  # read with its own count: setting the field below drops the pack's reference to it
    p.first = a
    return old[0] + p.first[0]


def test_structref_fields_are_lent_only_where_their_type_fixes_them():
    """A pack whose type says no kernel sets its fields lends them like a tuple's; any other pack's field keeps its
    own count, so replacing it during the call leaves the old array alive while it is used. Both keep every
    allocation freed exactly once."""
    was_on = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()
    a, b = np.arange(1.0, 4.0), np.array([10.0, 20.0])
    before = rtsys.get_allocation_stats()
    for _ in range(20):
        fixed, open_ = _make_pack(np.full(3, 2.0), (a, b)), _make_open_pack(np.full(3, 2.0), (a, b))
        s, first, (inner0, f0) = _pack_fields(fixed, 10)
        assert s == 10 * 2.0 + 5 * (10.0 + 20.0) + 10 * 1.0 and first[0] == 2.0 and inner0[0] == 1.0 and f0 == 2.0
        assert _replace_field(open_, a) == 2.0 + 1.0  # the old field read after it was replaced
        del fixed, open_, s, first, inner0, f0
    after = rtsys.get_allocation_stats()
    if not was_on:
        _nrt_python.memsys_disable_stats()
    allocated, freed = after.mi_alloc - before.mi_alloc, after.mi_free - before.mi_free
    assert allocated > 40 and allocated == freed


@njit
def _make_pack(first, inner):
    return _Pack(first, inner)


@njit
def _make_open_pack(first, inner):
    return _OpenPack(first, inner)

