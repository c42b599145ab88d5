"""Cached kernels call the kernels below them by symbol (``bullet_dlo/_numba_link.py``): a caller's cache entry holds
its own machine code, not its callees' again, and loading it loads its callees first.

Each case runs in fresh processes on a small module of cached kernels outside the package (``top`` calls ``mid`` and
``leaf``, ``mid`` calls ``leaf``; ``outer`` calls ``inner``, which calls ``leaf``), linked as the package links its
own."""
from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np

# leaf is long enough that LLVM does not inline it: its callers call it
TERMS = "\n    ".join(f"    s += np.exp(-abs(a[{k} % a.shape[0]] - {k / 7:.3f})) * np.arctan(s + {k})"
                       for k in range(40))
KERNELS = textwrap.dedent('''
    import numpy as np
    from numba import njit

    @njit(cache=True)
    def leaf(a, i):
        s = 0.0
        for k in range(a.shape[0]):
            s += np.sin(a[k] * i) * np.cos(a[k] + i) + np.sqrt(abs(a[k]) + 1.0)
            for j in range(k):
                s += np.tanh(a[j] - a[k]) / (1.0 + j)
    %s
        if s > 1e300:
            raise ValueError("too large")
        return s

    @njit(cache=True)
    def mid(a):
        t = 0.0
        for i in range(10):
            t += leaf(a, i)
        return t

    @njit(cache=True)
    def top(a):
        return mid(a) + leaf(a, 3)

    @njit(cache=True)
    def inner(a):
        return leaf(a, 2)

    @njit(cache=True)
    def outer(a):
        return 2.0 * inner(a)
''' % TERMS)

RUN = textwrap.dedent('''
    import json, sys
    import numpy as np
    from numba.core.dispatcher import Dispatcher
    import bullet_dlo  # noqa: F401  (installs the linking)
    from bullet_dlo import _numba_link
    import toy

    for name in ("leaf", "mid", "top", "inner", "outer"):  # link these as the package's kernels are linked
        d = getattr(toy, name)
        d.compile = (lambda d: lambda sig: _numba_link.compile_linked(d, sig, tuple(sig), Dispatcher.compile))(d)
    a = np.linspace(-1.0, 2.0, 9)
    value = float(getattr(toy, sys.argv[1])(a))
    stats = {n: [sum(getattr(toy, n).stats.cache_hits.values()), sum(getattr(toy, n).stats.cache_misses.values())]
             for n in ("leaf", "mid", "top", "inner", "outer")}
    print(json.dumps({"value": value, "stats": stats}))
''')


def _run(folder, kernel: str = "top") -> dict:
    res = subprocess.run([sys.executable, "-c", RUN, kernel], cwd=folder, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    return json.loads(res.stdout.strip().splitlines()[-1])


def _expected() -> float:
    namespace: dict = {}
    exec(KERNELS.replace("@njit(cache=True)", ""), namespace)  # the kernels run by Python
    a = np.linspace(-1.0, 2.0, 9)
    leaf = namespace["leaf"]
    return sum(leaf(a, i) for i in range(10)) + leaf(a, 3)


def test_a_cached_caller_loads_its_callees_and_computes_the_same(tmp_path):
    (tmp_path / "toy.py").write_text(KERNELS)
    first = _run(tmp_path)  # compiles all three and caches them
    # leaf compiles for int64 and for the literal 3
    assert first["stats"] == {"leaf": [0, 2], "mid": [0, 1], "top": [0, 1], "inner": [0, 0], "outer": [0, 0]}
    again = _run(tmp_path)  # only top is called: its callees are loaded from the cache before it
    assert again["stats"] == {"leaf": [2, 0], "mid": [1, 0], "top": [1, 0], "inner": [0, 0], "outer": [0, 0]}
    assert again["value"] == first["value"]
    assert abs(first["value"] - _expected()) <= 1e-12 * abs(_expected())


def test_a_caller_of_a_rebuilt_callee_is_rebuilt_not_run(tmp_path):
    """The callee ``mid`` is compiled again (its cache entry lost): the cached ``top`` calls the symbol of mid's
    former build, which no process has any more. It is built again against the new one."""
    (tmp_path / "toy.py").write_text(KERNELS)
    first = _run(tmp_path)
    for entry in (tmp_path / "__pycache__").glob("toy.mid-*"):
        entry.unlink()
    rebuilt = _run(tmp_path)
    assert rebuilt["stats"]["mid"] == [0, 1] and rebuilt["stats"]["top"] == [0, 1]
    assert rebuilt["value"] == first["value"]
    third = _run(tmp_path)  # and the rebuilt caller is the one cached
    assert third["stats"] == {"leaf": [2, 0], "mid": [1, 0], "top": [1, 0], "inner": [0, 0], "outer": [0, 0]}
    assert third["value"] == first["value"]


def test_a_caller_built_on_cached_callees_loads_what_they_call(tmp_path):
    """``inner`` is built and cached alone; then ``outer`` is built on it (loaded from the cache, and inlined:
    ``outer`` then calls ``leaf`` itself). A third process that loads ``outer`` must load ``leaf`` first: LLVM
    stopped the process ("Symbol not found") while a library loaded from the cache passed on nothing of what its
    kernel calls."""
    (tmp_path / "toy.py").write_text(KERNELS)
    _run(tmp_path, "inner")
    built = _run(tmp_path, "outer")
    assert built["stats"]["inner"] == [1, 0] and built["stats"]["outer"] == [0, 1]
    loaded = _run(tmp_path, "outer")
    assert loaded["stats"]["outer"] == [1, 0] and loaded["stats"]["leaf"] == [1, 0]
    assert loaded["value"] == built["value"]
    namespace: dict = {}
    exec(KERNELS.replace("@njit(cache=True)", ""), namespace)
    expected = 2.0 * namespace["leaf"](np.linspace(-1.0, 2.0, 9), 2)
    assert abs(loaded["value"] - expected) <= 1e-12 * abs(expected)


def test_a_users_kernel_cached_beside_the_package_loads_without_it(tmp_path):
    """A user's cached kernel compiled in a process that imported the package keeps Numba's cache format: a process
    that does not import the package loads it (the package's own format made Numba raise there)."""
    (tmp_path / "user.py").write_text(textwrap.dedent('''
        from numba import njit

        @njit(cache=True)
        def f(x):
            return 2.0 * x + 1.0
    '''))
    run = "import json, sys, user; print(json.dumps([user.f(3.0), sum(user.f.stats.cache_hits.values())]))"
    with_package = subprocess.run([sys.executable, "-c", "import bullet_dlo; " + run], cwd=tmp_path,
                                  capture_output=True, text=True, timeout=300)
    assert with_package.returncode == 0, with_package.stderr[-2000:]
    assert json.loads(with_package.stdout.strip().splitlines()[-1]) == [7.0, 0]
    without = subprocess.run([sys.executable, "-c", run], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert without.returncode == 0, without.stderr[-2000:]
    assert json.loads(without.stdout.strip().splitlines()[-1]) == [7.0, 1]  # loaded from the cache


def test_a_stale_build_is_built_again_without_reading_the_cache():
    """``compile_linked`` on a build whose load raised ``StaleCallee``: the retry reads nothing from the cache, saves
    through it, and leaves the dispatcher's cache as it was (the path a user's cached kernel takes; the package's own
    is run for real above). Numba's compile is stood in for by one that loads, raises when what it loaded is stale,
    and otherwise builds and saves."""
    from bullet_dlo import _numba_link

    events = []

    class Cache:
        def load_overload(self, sig, target_context):
            return "stale build"

        def save_overload(self, sig, cres):
            events.append(("save", cres))

    class Dispatcher:
        _cache = Cache()
        overloads: dict = {}

    def compile_unlocked(dispatcher, sig):
        loaded = dispatcher._cache.load_overload(sig, None)
        events.append(("load", loaded))
        if loaded is not None:
            raise _numba_link.StaleCallee("a callee was built again")
        dispatcher._cache.save_overload(sig, "new build")
        return "entry point"

    disp = Dispatcher()
    cache = disp._cache
    assert _numba_link.compile_linked(disp, (), (), compile_unlocked, mark_build=False) == "entry point"
    assert events == [("load", "stale build"), ("load", None), ("save", "new build")]
    assert disp._cache is cache
