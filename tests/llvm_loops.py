"""Reading a compiled kernel's LLVM code for reference counting in its loops (shared by tests in several folders,
imported as ``from llvm_loops import loop_increfs``; no PyBullet here, so the core tests can use it too).

Numba counts references to every array a variable holds (all of a NamedTuple's arrays for a tuple) and removes the
counts again where it can prove them paired; where a variable's last use sits inside a branch it cannot, and each
pass through the code pays an atomic increment and decrement per array (docs/results/speed.md, "Contact").
"""
from __future__ import annotations

import re


def own_function(wrapper) -> str:
    """The LLVM code of ``wrapper``'s own function (the kernels it calls without inlining are linked into the same
    module beside it; its CPython and cfunc wrappers too)."""
    (ir,) = wrapper.inspect_llvm().values()
    name = wrapper.py_func.__name__
    for fn in re.split(r"^define ", ir, flags=re.M)[1:]:
        head = re.search(r'@"?([^"(\s]+)', fn).group(1)  # the function's symbol
        if name in head and "cpython" not in head and "cfunc" not in head:
            return fn.split("\n}", 1)[0]
    raise AssertionError(f"{name} not found in its LLVM code")


def loop_increfs(wrapper) -> int:
    """NRT_incref calls inside loops (blocks on a cycle of the control-flow graph) of ``wrapper``'s own function in
    its LLVM code (the kernels it calls without inlining are not counted here)."""
    body = own_function(wrapper)
    blocks, succ, label = {}, {}, "entry"
    for line in body.splitlines()[1:]:
        m = re.match(r'^"?([\w.$\-]+)"?:', line)
        if m:
            label = m.group(1)
            continue
        blocks.setdefault(label, []).append(line)
        succ.setdefault(label, []).extend(re.findall(r'label %"?([\w.$\-]+)"?', line))

    def reaches(a: str, b: str) -> bool:
        seen, todo = set(), list(succ.get(a, []))
        while todo:
            q = todo.pop()
            if q == b:
                return True
            if q not in seen:
                seen.add(q)
                todo.extend(succ.get(q, []))
        return False

    return sum(line.count("call void @NRT_incref") for b, lines in blocks.items() if reaches(b, b) for line in lines)
