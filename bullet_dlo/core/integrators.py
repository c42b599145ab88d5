"""Time integrators behind one interface: the method registry and the Newton settings.

Every method advances (x, v) by one fixed step h given the model arrays, the held-end
samples at t, t+h/2 and t+h, and optional external forces. Methods:

=====================  =====  ========================================================
name                   order  character
=====================  =====  ========================================================
``explicit_euler``     1      forward Euler; adds energy, needs damping *and* tiny steps
``symplectic_euler``   1      v then x (Gazebo, Isaac Sim, Lv, Bullet); stable for h < ~2/omega_max
``rk4``                4      classic Runge-Kutta; stable for h < ~2.8/omega_max
``implicit_euler``     1      linearly implicit backward Euler, one banded O(n) solve; L-stable,
                              damps stiff (and, at large h, slow) modes
``bdf2``               2      backward differentiation, Newton on a banded system; L-stable,
                              damps stiff modes but keeps the slow dynamics
``implicit_midpoint``  2      symplectic and A-stable, Newton; no numerical damping at all
``gauss_legendre``     4      2-stage Gauss-Legendre collocation: symplectic, A-stable, no numerical
                              damping, 4th-order phase; Newton on the coupled two-stage system
                              (:mod:`bullet_dlo.core.kernels.gauss_legendre`)
=====================  =====  ========================================================

Held nodes are kinematic: after every step they sit exactly at the prescribed pose. The step
kernels are :mod:`bullet_dlo.core.kernels.steppers`; :func:`make_stepper` binds a method, a
step and Newton settings into the :class:`~bullet_dlo.core.kernels.steppers.Stepper` they take.
"""
from __future__ import annotations

from dataclasses import dataclass

from bullet_dlo.core.enums import IntegratorName, name_of
from bullet_dlo.core.kernels.steppers import (
    BDF2,
    EXPLICIT_EULER,
    GAUSS_LEGENDRE,
    IMPLICIT_EULER,
    IMPLICIT_MIDPOINT,
    RK4,
    SYMPLECTIC_EULER,
    Stepper,
)
from bullet_dlo.core.kernels.twist_coupled import EXACT_AUTO
from bullet_dlo.core.validate import check_bool, check_in_range, check_int, check_positive

MAX_NEWTON_ITER = EXACT_AUTO - 1
MAX_ITER = 8
"""Newton iterations per step at most, the implicit methods' default (``NewtonOptions.max_iter`` None)."""
MAX_ITER_GAUSS_LEGENDRE = 32
"""The same for ``gauss_legendre``: its collocation system (both stages at once) converges more slowly at long
steps (the study's cable pushed 30 % in at 60 Hz: 12.9 iterations a step, 32 of 40 solves failed with 8 and the run
was stopped, 6 of 90 with 16, none with 20; ``python demos/twist_newton.py --scenes pushed --turns 0 --frameless
--dts 0.016667 --max-iter 8 16 20``). 32 since 2026-12-08: the step's first iteration takes the transformed
one-Jacobian matrix (kernels/gauss_legendre.py), which the hardest steps pay with one more iteration, and the
default tolerance is 1e-9 (16.1 iterations a step there; two solves failed with 24). A failed solve keeps an
unconverged iterate; the cap costs only steps that need it."""
EXACT_FROM = EXACT_AUTO  # NewtonOptions.exact_from's default: the automatic choice (twist_coupled.EXACT_AUTO)


@dataclass(frozen=True)
class Integrator:
    """A time integration method: name, kernel code, order of accuracy, explicit or not."""

    name: str
    code: int
    order: int
    explicit: bool


INTEGRATORS: dict[str, Integrator] = {
    i.name: i
    for i in (
        Integrator("explicit_euler", EXPLICIT_EULER, 1, True),
        Integrator("symplectic_euler", SYMPLECTIC_EULER, 1, True),
        Integrator("rk4", RK4, 4, True),
        Integrator("implicit_euler", IMPLICIT_EULER, 1, False),
        Integrator("bdf2", BDF2, 2, False),
        Integrator("implicit_midpoint", IMPLICIT_MIDPOINT, 2, False),
        Integrator("gauss_legendre", GAUSS_LEGENDRE, 4, False),
    )
}


def get_integrator(name: str) -> Integrator:
    """Look up an integrator by name; unknown names raise ParameterError listing the choices."""
    if isinstance(name, Integrator):
        return name
    return INTEGRATORS[name_of("integrator", name, IntegratorName, lower=True)]


@dataclass(frozen=True)
class NewtonOptions:
    """Newton settings for implicit methods.

    max_iter: Newton iterations per step at most (``max_iter=1`` makes ``implicit_euler`` the
    pure linearly implicit method); None picks the method's default, :data:`MAX_ITER` (8), and
    :data:`MAX_ITER_GAUSS_LEGENDRE` (32) for ``gauss_legendre``, whose stage system converges more slowly at
    long steps; tol: convergence when the momentum residual is below
    tol [-] * (momentum change of the step + gravity impulse) plus the round-off floor. None picks
    the method's default: 1e-3 for ``implicit_euler`` (its first-order error dwarfs a finer
    solve, so a second iteration runs only when the linearisation visibly failed), 1e-6
    for the second-order methods and 1e-9 for ``gauss_legendre`` (its simplified Newton iteration converges
    linearly and stops just under the tolerance, and its 4th-order error at short steps is below what 1e-6
    solves: a swinging cantilever's error at 0.5 ms was 5.7e-9 m against 6.3e-12 m solved to 1e-9);
    definite: filter the compressive stretch Hessian so the system stays positive definite; exact_from: the Newton iteration (1-based) from which the implicit step of a
    cable with a material frame takes the exact Jacobian of its residual (earlier iterations: the symmetric
    Gauss-Newton matrix, cheaper per iteration; see :mod:`~bullet_dlo.core.kernels.twist_coupled`), in
    [1, 1001]; 1001 (the default) chooses: the exact Jacobian from the first iteration for anisotropic sections
    (rectangles: the Gauss-Newton matrix leaves out their bending's curvature terms, and a flat strip's steps fail
    and blow up with it), the Gauss-Newton matrix for round and tube sections (cheaper per iteration, and as
    fast to converge unless the cable is twisted by turns). With any value, an iteration that takes a full
    Gauss-Newton step and leaves more than a quarter of the residual switches the rest of the step to the exact
    Jacobian (``twist_coupled.CONTRACTION``); reuse_matrix: the implicit step out of contact (with or without a
    material frame) factors its Newton matrix once a step and takes the same factors (a chord iteration) while each
    iteration leaves at most a tenth of the residual (``steppers.CHORD_CONTRACTION``), and starts BDF2's Newton from
    the velocities extrapolated from the last two steps (the solution is the same to the tolerance; a frameless step
    1.5-1.7x faster from n = 20 on, a twisting one 1.3-1.6x, a rectangle 1.5-2.3x, docs/concepts/model.md); the
    frameless step also keeps its factors for the steps after while they serve (a settled cable builds none;
    ``steppers._kept``, ``steppers.QUIET_START``); False builds and factors the matrix every iteration from the last
    velocities, as before 2026-12-06.
    """

    max_iter: int | None = None
    tol: float | None = None
    definite: bool = True
    exact_from: int = EXACT_FROM
    reuse_matrix: bool = True

    def __post_init__(self) -> None:
        # checked here, in Python: a non-bool ``definite`` would make Numba compile a new kernel specialisation
        set_ = object.__setattr__
        if self.max_iter is not None:
            set_(self, "max_iter", check_int("newton.max_iter", self.max_iter, 1, MAX_NEWTON_ITER))
        if self.tol is not None:
            set_(self, "tol", check_in_range("newton.tol", self.tol, 1e-16, 1.0))
        set_(self, "definite", check_bool("newton.definite", self.definite))
        set_(self, "exact_from", check_int("newton.exact_from", self.exact_from, 1, MAX_NEWTON_ITER + 1))
        set_(self, "reuse_matrix", check_bool("newton.reuse_matrix", self.reuse_matrix))

    def iterations(self, integrator: str) -> int:
        """The Newton iteration cap per step used for ``integrator``."""
        if self.max_iter is not None:
            return self.max_iter
        return MAX_ITER_GAUSS_LEGENDRE if get_integrator(integrator).name == "gauss_legendre" else MAX_ITER

    def tolerance(self, integrator: str) -> float:
        """The residual tolerance used for ``integrator``."""
        if self.tol is not None:
            return self.tol
        name = get_integrator(integrator).name
        return 1e-3 if name == "implicit_euler" else (1e-9 if name == "gauss_legendre" else 1e-6)


def make_stepper(integrator: str | Integrator, h: float, newton: NewtonOptions = NewtonOptions()) -> Stepper:
    """The step kernels' settings for ``integrator`` at step h [s] (validated)."""
    method = get_integrator(integrator)
    return Stepper(
        method=int(method.code),
        h=float(check_positive("dt", h)),
        max_iter=int(check_int("newton max_iter", newton.iterations(method.name), 1)),
        tol=float(check_positive("newton tol", newton.tolerance(method.name))),
        definite=bool(newton.definite),
        exact_from=int(newton.exact_from),
        reuse=bool(newton.reuse_matrix),
    )
