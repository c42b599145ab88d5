"""The package's ``njit``: Numba's, compiled so that passing arrays and tuples of arrays costs nothing.

Numba counts references to every array a variable holds, a NamedTuple variable all of its arrays (27 for the
model's :class:`~bullet_dlo.core.model.KernelArrays`, 30 for the contact rows), with an atomic increment where the
variable is bound and a decrement where it ends. Its pruning of such pairs gives up as soon as a loop or a call sits
between them, which in a kernel is almost always. Two bindings made nearly every count in the time loop: a kernel's
arguments, bound to variables on entry, and an inlined kernel's arguments (``inline="always"``), bound to copies of
the caller's variables (``m.1 = m``). 57 % of the core time loop's CPU time went to the two atomic instructions
(``perf``, the study cable at n = 10, implicit Euler, 2026-12-03).

:class:`KernelCompiler` is Numba's nopython pipeline with two changes, neither of which changes a computed bit:

* :class:`ForwardCopies` (before typing): a variable assigned once from a named variable that is itself assigned once
  is replaced by that variable wherever it is used. In SSA form a use is dominated by its definition, so both name the
  same object at every use; the inlined kernel's copies and their counts go.
* :class:`BorrowingLower` (lowering): a variable bound once to an argument borrows the caller's reference instead of
  taking its own. The caller holds every argument until the call returns (Python's convention, and Numba's for calls
  between kernels), and everything that keeps an object beyond the call (a return, a tuple, a container) counts
  its own reference, so nothing else changes. So does a variable bound once to a borrowed variable or to a field of
  a borrowed tuple (``ws.x_stage``, ``c.grip.active``): a tuple cannot drop its fields, so they live as long as it.
  A StructRef's fields can be replaced during the call, so only a StructRef type that says no kernel sets them
  (``fields_fixed = True``: the coupled step's packed arguments) lends its fields too.

Measured on the study cable's core time loop (n = 10, implicit Euler, thread CPU time per step): 14.6 us with
Numba's pipeline, 13.0 us with the copies forwarded, 6.5 us with the arguments borrowed as well; the results are
bit-identical (tests/core/test_jit.py; ``demos/fingerprints.py``). Both use Numba's documented pass-manager hooks
(``compiler_machinery``, ``NativeLowering.lowering_class``); tested with Numba 0.68.
"""
from __future__ import annotations

import numba
from numba.core import ir, types
from numba.core.compiler import CompilerBase, DefaultPassBuilder
from numba.core.compiler_machinery import FunctionPass, register_pass
from numba.core.ir_utils import build_definitions, replace_vars
from numba.core.lowering import Lower
from numba.core.runtime.context import NRTContext
from numba.core.typed_passes import NativeLowering
from numba.core.untyped_passes import InlineInlinables, ReconstructSSA


def _single_copies(blocks: dict) -> dict[str, ir.Var]:
    """{target name: source variable} of the assignments ``a = b`` where a and b are named variables (not Numba's
    ``$`` temporaries) that are each assigned exactly once."""
    count: dict[str, int] = {}
    for block in blocks.values():
        for stmt in block.body:
            if isinstance(stmt, ir.Assign):
                count[stmt.target.name] = count.get(stmt.target.name, 0) + 1
    copies = {}
    for block in blocks.values():
        for stmt in block.body:
            if (isinstance(stmt, ir.Assign) and isinstance(stmt.value, ir.Var)
                    and not stmt.target.name.startswith("$") and not stmt.value.name.startswith("$")
                    and count[stmt.target.name] == 1 and count.get(stmt.value.name, 0) == 1):
                copies[stmt.target.name] = stmt.value
    return copies


@register_pass(mutates_CFG=False, analysis_only=False)
class ForwardCopies(FunctionPass):
    """Replace single-assignment copies of variables by their source (see the module docstring)."""

    _name = "bullet_dlo_forward_copies"

    def __init__(self):
        FunctionPass.__init__(self)

    def run_pass(self, state) -> bool:
        blocks = state.func_ir.blocks
        copies = _single_copies(blocks)
        if not copies:
            return False

        def source(var: ir.Var) -> ir.Var:  # follow chains (a = b, b = c): each link is a single assignment
            for _ in range(len(copies)):
                if var.name not in copies:
                    break
                var = copies[var.name]
            return var

        for block in blocks.values():
            block.body = [s for s in block.body if not (isinstance(s, ir.Assign) and s.target.name in copies)]
        replace_vars(blocks, {name: source(var) for name, var in copies.items()})
        state.func_ir._definitions = build_definitions(blocks)
        return True


def _no_refop(typ, val) -> None:
    """Stands in for Lower.incref / Lower.decref while a borrowed variable is bound or ends."""


def _no_nrt_refop(self, builder, typ, value) -> None:
    """Stands in for NRTContext.incref while a borrowed field is read."""


class BorrowingLower(Lower):
    """Numba's lowering, with the arguments borrowed from the caller: a variable bound once to an argument is not
    counted at its binding nor at its end (the caller holds the objects for the whole call), and neither is a
    variable bound once to a borrowed variable or to a field of a borrowed tuple (a tuple cannot drop its fields) or
    of a borrowed StructRef whose type has ``fields_fixed`` (no kernel sets its fields)."""

    def pre_lower(self):
        super().pre_lower()
        values: dict[str, list] = {}
        for block in self.func_ir.blocks.values():
            for stmt in block.body:
                if isinstance(stmt, ir.Assign):
                    values.setdefault(stmt.target.name, []).append(stmt.value)
        self._borrowed: set[str] = set()
        if self.generator_info:
            return
        grown = True
        while grown:  # a field of a field of an argument: as many passes as the deepest chain
            grown = False
            for name, vals in values.items():
                if name not in self._borrowed and len(vals) == 1 and self._borrows(vals[0]):
                    self._borrowed.add(name)
                    grown = True

    def _borrows(self, value) -> bool:
        """Whether ``value`` is an argument, a borrowed variable, or a field of a borrowed tuple."""
        if isinstance(value, ir.Arg):
            return True
        if isinstance(value, ir.Var):
            return value.name in self._borrowed
        if not (isinstance(value, ir.Expr) and value.op in ("getattr", "static_getitem")
                and value.value.name in self._borrowed):
            return False
        owner = self.typeof(value.value.name)
        if isinstance(owner, types.StructRef):  # mutable: only where its type says no kernel sets a field
            return value.op == "getattr" and getattr(owner, "fields_fixed", False)
        return isinstance(owner, types.BaseTuple) and (value.op == "getattr" or isinstance(value.index, (int, str)))

    def lower_assign(self, ty, inst):
        if inst.target.name not in self._borrowed:
            return super().lower_assign(ty, inst)
        # the binding's count: Lower.incref for an argument or a variable, the field read's own (NRTContext)
        self.incref = _no_refop
        counting = NRTContext.incref
        NRTContext.incref = _no_nrt_refop  # (compilation holds Numba's global lock: nothing else lowers meanwhile)
        try:
            return super().lower_assign(ty, inst)
        finally:
            del self.incref
            NRTContext.incref = counting

    def delvar(self, name):
        if name in self._borrowed:
            self.decref = _no_refop
            try:
                return super().delvar(name)
            finally:
                del self.decref
        return super().delvar(name)


@register_pass(mutates_CFG=True, analysis_only=False)
class BorrowingLowering(NativeLowering):
    """Numba's lowering pass with :class:`BorrowingLower`."""

    _name = "bullet_dlo_borrowing_lowering"

    @property
    def lowering_class(self):
        return BorrowingLower


class KernelCompiler(CompilerBase):
    """Numba's nopython pipeline with :class:`ForwardCopies` after inlining and SSA, and :class:`BorrowingLower`."""

    def define_pipelines(self):
        pm = DefaultPassBuilder.define_nopython_pipeline(self.state)
        names = [p[0] for p in pm.passes]
        pm.add_pass_after(ForwardCopies, ReconstructSSA if ReconstructSSA in names else InlineInlinables)
        pm.passes = [(BorrowingLowering, d) if p is NativeLowering else (p, d) for p, d in pm.passes]
        pm.finalize()
        return [pm]


def njit(*args, **options):
    """``numba.njit`` compiling with :class:`KernelCompiler` (as ``@njit`` or ``@njit(cache=True, ...)``)."""
    options.setdefault("pipeline_class", KernelCompiler)
    return numba.njit(*args, **options)
