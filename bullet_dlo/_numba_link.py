"""Link the package's cached kernels to each other by symbol, not by copy.

Numba links every kernel a kernel calls into its code as a private copy (``linkonce_odr``): the caller's module is
optimised and turned into machine code with all of its callees' code, and so is the caller's caller. The coupled
Bullet step's kernels emitted the time stepper (``advance``, 4.4 MB of machine code) again in every loop that calls
it, and the suite's cache held 118 MB. A cold start spent about a quarter of its compile time emitting machine code
(2026-12-07, 2-core AMD EPYC, ``cProfile`` of the core kernels' compile), much of it code that already existed.

Here a callee that is one of the package's cached kernels is linked ``available_externally`` instead: the caller's
optimiser still sees its body and inlines it where it would have (so the compiled code runs as fast), but a call it
does not inline calls the callee's own compiled code, which is not emitted again. Such a caller needs its callees
loaded in the process: the callee is recorded in the caller's ``reload_init`` (:class:`Callee`), which Numba runs
before it loads a kernel from the cache, and which loads the callee (from the cache, or compiles it). A cached callee
recompiled since the caller was built has another symbol (Numba names each build uniquely); the caller is then
built again (:class:`StaleCallee`, handled in :func:`compile_linked`).

Only kernels whose cache is the package's (``_numba_cache.DigestLocator``) and that can be found again by module and
name are linked so; everything else (Numba's own helpers, kernels made in functions) is copied as Numba does.
"""
from __future__ import annotations

import importlib
from typing import NamedTuple


class StaleCallee(RuntimeError):
    """A cached kernel was built against a callee build the cache no longer holds: it must be built again."""


class Callee(NamedTuple):
    """A kernel another kernel calls by symbol: loading the caller first loads this (Numba's ``reload_init``)."""

    module: str
    qualname: str
    args: tuple
    """Numba argument types of the callee's build."""
    symbol: str
    """The build's native function (``fndesc.mangled_name``), which the caller's machine code calls."""

    def dispatcher(self):
        """The callee's dispatcher (a module attribute), or None."""
        obj = importlib.import_module(self.module)
        for part in self.qualname.split("."):
            obj = getattr(obj, part, None)
        return obj

    def __call__(self) -> None:
        disp = self.dispatcher()
        if disp is None:
            raise StaleCallee(f"{self.module}.{self.qualname} is gone")
        disp.compile(self.args)
        built = disp.overloads[self.args].fndesc.mangled_name
        if built != self.symbol:
            raise StaleCallee(f"{self.qualname}: the caller calls {self.symbol}, the cache holds {built}")


def mark(dispatcher, args: tuple) -> None:
    """Mark the build of ``dispatcher`` for ``args`` (one of the package's cached kernels) as linked by symbol."""
    cres = dispatcher.overloads.get(args)
    if cres is None or getattr(cres, "objectmode", False) or hasattr(cres.library, "_linked_by_symbol"):
        return
    func = dispatcher.py_func
    ref = Callee(func.__module__, func.__qualname__, args, cres.fndesc.mangled_name)
    if "<locals>" in func.__qualname__ or ref.dispatcher() is not dispatcher:
        return
    cres.library._linked_by_symbol = ref
    # a library loaded from the cache starts with no reload_init of its own (Numba keeps it with the build): a caller
    # that inlines this kernel calls what this one calls, and inherits the kernels to load first from here
    cres.library._reload_init.update(cres.reload_init or ())


def compile_linked(dispatcher, sig, args: tuple, compile_unlocked, mark_build: bool = True):
    """``compile_unlocked(dispatcher, sig)``, the build then marked to be linked by symbol (module doc) if
    ``mark_build``. A cached build whose callees were built again since (:class:`StaleCallee`) is not loaded but
    built again, and the new build replaces it in the cache."""
    try:
        entry = compile_unlocked(dispatcher, sig)
    except StaleCallee:
        cache = dispatcher._cache
        dispatcher._cache = _SaveOnly(cache)
        try:
            entry = compile_unlocked(dispatcher, sig)
        finally:
            dispatcher._cache = cache
    if mark_build:
        mark(dispatcher, args)
    return entry


class _SaveOnly:
    """A dispatcher's cache that loads nothing (and saves as the cache it wraps)."""

    def __init__(self, cache):
        self._cache = cache

    def load_overload(self, sig, target_context):
        return None

    def __getattr__(self, name):
        return getattr(self._cache, name)


def _external_module(library, symbol: str):
    """The module that links ``library`` into a caller with its native function ``symbol`` available externally, or
    None where the module does not define it."""
    module = library._get_module_for_linking().clone()
    try:
        fn = module.get_function(symbol)
    except NameError:
        return None
    if fn.is_declaration:
        return None
    fn.linkage = "available_externally"
    return module


def _finalize(self) -> None:
    """``CPUCodeLibrary.finalize`` (Numba 0.68) linking marked callees by symbol (module doc)."""
    from numba.core.compiler_lock import require_global_compiler_lock

    require_global_compiler_lock()
    self._codegen._check_llvm_bugs()
    self._raise_if_finalized()
    seen = set()
    for library in self._linking_libraries:
        if library in seen:
            continue
        seen.add(library)
        self._reload_init.update(library._reload_init)  # (the parent inherits reload_init, as in Numba)
        ref = getattr(library, "_linked_by_symbol", None)
        external = None if ref is None else _external_module(library, ref.symbol)
        if external is None:
            self._final_module.link_in(library._get_module_for_linking(), preserve=True)
        else:
            self._final_module.link_in(external, preserve=True)
            self._reload_init.add(ref)
    self._optimize_final_module()
    # a callee inlined everywhere (its symbol no longer declared) need not be loaded before this library
    declared = {fn.name for fn in self._final_module.functions if fn.is_declaration}
    self._reload_init = {fn for fn in self._reload_init if not isinstance(fn, Callee) or fn.symbol in declared}
    self._final_module.verify()
    self._finalize_final_module()


PACKAGE_SYMBOLS = "_ZN10bullet_dlo"
"""How the native functions of the package's kernels begin (Numba's Itanium mangling of ``bullet_dlo.<...>``)."""


def _serialize_using_object_code(self):
    """``CPUCodeLibrary.serialize_using_object_code`` with the names the library defines beside its object code and
    its module for linking, so that loading it need not read the module (:func:`_unserialize`). Only for the
    package's kernels: another kernel cached in Numba's format (a user's) still loads where this package is not
    imported."""
    import llvmlite.binding as ll

    self._ensure_finalized()
    own = [fn.name for fn in self._final_module.functions  # (external: its own; copies of others are linkonce)
           if not fn.is_declaration and fn.linkage == ll.Linkage.external]
    if not any(name.startswith(PACKAGE_SYMBOLS) for name in own):
        return _NUMBA["serialize_using_object_code"](self)
    shared = self._get_module_for_linking()
    defined = tuple(sorted(value.name for values in (shared.functions, shared.global_variables) for value in values
                           if not value.is_declaration))
    return (self.name, "object", (self._get_compiled_object(), shared.as_bitcode(), defined))


def _unserialize(cls, codegen, state):
    """``CPUCodeLibrary._unserialize`` keeping a cached library's module for linking as bitcode until a kernel
    compiled in this process links it: a process that only loads kernels parses none (Numba parsed every loaded
    library's, 0.7 s of CPU in a process running a grasp, 2026-12-07)."""
    name, kind, data = state
    if kind != "object" or len(data) != 3:
        return _NUMBA["_unserialize"].__func__(cls, codegen, state)
    object_code, shared_bitcode, defined = data
    self = codegen.create_library(name)
    self.enable_object_caching()
    self._set_compiled_object(object_code)
    self._shared_bitcode = shared_bitcode
    self._finalize_final_module()
    self._codegen._engine._defined_symbols.update(defined)
    return self


def _get_module_for_linking(self):
    """``CPUCodeLibrary._get_module_for_linking``, parsing a cached library's bitcode when first asked."""
    bitcode = getattr(self, "_shared_bitcode", None)
    if bitcode is not None and self._shared_module is None:
        import llvmlite.binding as ll

        self._shared_module = ll.parse_bitcode(bitcode)
        self._shared_bitcode = None
    return _NUMBA["_get_module_for_linking"](self)


_NUMBA: dict = {}
"""Numba's replaced methods."""


def install() -> bool:
    """Replace four methods of Numba's ``CPUCodeLibrary`` (once per process): linking (``finalize``) and the cache's
    format (:func:`_serialize_using_object_code`, :func:`_unserialize`, :func:`_get_module_for_linking`). False
    (nothing replaced) with a Numba other than the one they were written for."""
    try:
        import numba
        from numba.core import codegen
    except ImportError:
        return False
    if not numba.__version__.startswith("0.68"):  # the replaced method is Numba 0.68's (tested with it)
        return False
    library = codegen.CPUCodeLibrary
    if not _NUMBA:
        _NUMBA.update(_unserialize=library.__dict__["_unserialize"],
                      _get_module_for_linking=library._get_module_for_linking,
                      serialize_using_object_code=library.serialize_using_object_code)
        library.finalize = _finalize
        library.serialize_using_object_code = _serialize_using_object_code
        library._unserialize = classmethod(_unserialize)
        library._get_module_for_linking = _get_module_for_linking
    return True
