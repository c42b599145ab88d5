"""One Bullet step's model kernel called with two arguments instead of thirteen: :class:`StepArgs`.

:func:`~bullet_dlo.bullet.kernels.sync_and_advance` takes twelve arguments that are the same objects every step (the
stepper, the model's arrays, the held ends' plan and measurements, the coupling, the scratch, the detector, the
contacts, the free bodies, the stall guard: about 150 arrays in NamedTuples; the contact step and the step without
contact) and one that changes (the :class:`~bullet_dlo.bullet.kernels.StepInput`). Numba unboxes every array of every
argument on each call (7.6 us a step at n = 10, more than a bare Bullet step of the cable's spheres);
:func:`pack_step_args` packs the twelve into one StructRef once (the arrays are shared, not copied) and
:func:`step_with` unpacks them inside compiled code (0.3 us). :class:`~bullet_dlo.bullet.solver.CableSolver` packs
anew whenever one of the objects is replaced (a rebuilt contact set, a restarted detector), so the kernel always sees
the objects a plain call would pass: the same kernel on the same data, the same bits.

The contact step (:func:`~bullet_dlo.core.kernels.contact.contact_step`) and the step without contact
(:func:`~bullet_dlo.core.kernels.steppers.advance`) are packed as first-class functions (their machine code's
addresses, :func:`first_class`), not linked into :func:`step_with`: a compiled caller links, optimises and emits its
callees' code again, which made ``step_with`` a 52 s compile of its own (thread CPU, everything below it in the
cache, 2026-12-07) and an 8.8 MB cache entry that every process stepping a cable loaded.
"""
from __future__ import annotations

from numba import typeof, types
from numba.experimental import structref

from bullet_dlo.bullet.contact_call import FixedFields
from bullet_dlo.bullet.kernels import sync_and_advance
from bullet_dlo.core.kernels.contact import contact_step
from bullet_dlo.core.kernels.jit import njit
from bullet_dlo.core.kernels.steppers import advance

try:  # (Numba's own helper for first-class function arguments; without it the solver calls the kernels plainly)
    from numba.experimental.function_type import _get_wrapper_address
except ImportError:  # pragma: no cover - a Numba that moved it
    _get_wrapper_address = None

FIELDS = ("stepper", "arrays", "plan", "holders", "coupling", "workspace", "detector", "contacts", "bodies", "guard",
          "contact_call", "advance_call")


class Address:
    """A compiled function's address, as Numba's first-class function arguments take it (their wrapper address
    protocol): looked up once, not at every call."""

    __slots__ = ("address",)

    def __init__(self, address: int) -> None:
        self.address = address

    def __wrapper_address__(self) -> int:
        return self.address


def first_class(kernel, arg_types: tuple) -> tuple:
    """``kernel``'s machine code for ``arg_types`` (Numba types; compiled or loaded from the cache now) as a
    first-class function: (its type, its :class:`Address`)."""
    kernel.compile(arg_types)
    sig = kernel.overloads[arg_types].signature
    return types.FunctionType(sig), Address(_get_wrapper_address(kernel, sig))


@structref.register
class StepArgsType(FixedFields):
    """Numba type of :class:`StepArgs` (fields: :data:`FIELDS`, typed as the objects packed)."""


class StepArgs(structref.StructRefProxy):
    """The twelve per-cable arguments of :func:`~bullet_dlo.bullet.kernels.sync_and_advance` (:data:`FIELDS`),
    packed."""


structref.define_proxy(StepArgs, StepArgsType, list(FIELDS))


@njit(cache=True)
def make_step_args(stepper, arrays, plan, holders, coupling, workspace, detector, contacts, bodies, guard,
                   contact_call, advance_call):
    """Pack the per-cable arguments (compiled and cached: the proxy's own constructor is compiled in every process)."""
    return StepArgs(stepper, arrays, plan, holders, coupling, workspace, detector, contacts, bodies, guard,
                    contact_call, advance_call)


def pack_step_args(held: tuple) -> tuple:
    """The per-cable arguments ``held`` (:data:`FIELDS` but the last two) packed with the contact step and the step
    without contact as first-class functions for their types: (:class:`StepArgs`, the functions' addresses, to be
    kept as long as the packed arguments are used)."""
    stepper, arrays, _, _, coupling, workspace, _, contacts, bodies, _ = held
    state = (typeof(stepper), typeof(arrays), typeof(coupling.x_new), typeof(coupling.v_new),
             typeof(coupling.samples), typeof(workspace), types.boolean)  # (as coupled_targets calls them)
    calls = (first_class(contact_step, state + (typeof(contacts), typeof(bodies))), first_class(advance, state))
    # (compiled for the functions' types and called as compiled: the dispatcher cannot type an address)
    pack = make_step_args.compile(tuple(map(typeof, held)) + tuple(c[0] for c in calls))
    addresses = tuple(c[1] for c in calls)
    return pack(*held, *addresses), addresses


@njit(cache=True, error_model="numpy")
def step_with(args, inp):
    """:func:`~bullet_dlo.bullet.kernels.sync_and_advance` on the packed arguments and the step's input."""
    return sync_and_advance(args.stepper, args.arrays, args.plan, args.holders, args.coupling, args.workspace,
                            args.detector, inp, args.contacts, args.bodies, args.guard, args.contact_call,
                            args.advance_call)
