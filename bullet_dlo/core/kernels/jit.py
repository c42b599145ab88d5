"""The package's ``njit``: Numba's, with one pass that keeps reference counting out of inlined kernels.

Numba counts references to every array a variable holds: a NamedTuple variable holds all of its arrays (27 for the
model's :class:`~bullet_dlo.core.model.KernelArrays`, 30 for the contact rows). Inlining a kernel
(``inline="always"``) binds each of its arguments to a new variable, a copy of the caller's (``m.1 = m``), and each
copy costs an atomic increment and decrement of every array it holds. Numba's pruning of such pairs gives up as
soon as a loop or a call sits between them, so in the Newton loop the copies of ``m``, the workspace and the
contacts cost more than the arithmetic: 57 % of the core time loop's CPU time was spent on the two atomic
instructions (``perf``, the study cable at n = 10, 2026-12-03), and ``total_forces`` at n = 10 took 1.12 us in a
compiled loop against 0.26 us with the arrays passed directly.

:class:`ForwardCopies` removes those copies before typing: a variable assigned once, from a named variable that is
itself assigned once, is replaced by that variable wherever it is used. Both then name the same object at every use
(SSA form: a use is dominated by its definition, so the source cannot have been reassigned between), so the
results are bit-identical; only the counting goes (tests/core/test_jit.py).
"""
from __future__ import annotations

import numba
from numba.core import ir
from numba.core.compiler import CompilerBase, DefaultPassBuilder
from numba.core.compiler_machinery import FunctionPass, register_pass
from numba.core.ir_utils import build_definitions, replace_vars
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


class ForwardingCompiler(CompilerBase):
    """Numba's nopython pipeline with :class:`ForwardCopies` once inlining and SSA have run."""

    def define_pipelines(self):
        pm = DefaultPassBuilder.define_nopython_pipeline(self.state)
        names = [p[0] for p in pm.passes]
        pm.add_pass_after(ForwardCopies, ReconstructSSA if ReconstructSSA in names else InlineInlinables)
        pm.finalize()
        return [pm]


def njit(*args, **options):
    """``numba.njit`` compiling with :class:`ForwardingCompiler` (as ``@njit`` or ``@njit(cache=True, ...)``)."""
    options.setdefault("pipeline_class", ForwardingCompiler)
    return numba.njit(*args, **options)
