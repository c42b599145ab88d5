"""Discrete cable model (immutable arrays) and its time-varying state.

Following warp.sim and MuJoCo: a :class:`CableModel` holds everything that does not change
during a run (masses, springs, how the ends are held), a :class:`CableState` holds what
does (positions, velocities, time). Integrators read the model and advance the state.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple, Sequence

import numpy as np

from bullet_dlo.core.boundary import EndHolder, Motion, holder_plan
from bullet_dlo.core.kernels.holders import HolderPlan
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError, check_vector3

STANDARD_GRAVITY = (0.0, 0.0, -9.81)


class ModelArrays(NamedTuple):
    """The model as the Numba kernels take it (SI units); a new force term adds its arrays here.

    mass: point masses [kg], (n,); damp: viscous drag coefficients [N s/m], (n,);
    k_stretch: segment spring constants [N/m], (n-1,); rest_length: segment rest lengths [m], (n-1,);
    k_bend: bending constants [N m/rad^2], (n,) (index 0 / n-1 are the clamp springs, 0 if
    that end is not clamped); gravity: gravitational acceleration [m/s^2], (3,);
    f_ext: constant external forces [N], (n, 3); held: which nodes are kinematic, (n,) bool;
    c_stretch: Kelvin-Voigt segment dampers k_s tau [N s/m], (n-1,);
    c_bend: Kelvin-Voigt bending dampers k_b tau [N m s/rad^2], (n,) (clamp dampers as k_bend).
    """

    mass: np.ndarray
    damp: np.ndarray
    k_stretch: np.ndarray
    rest_length: np.ndarray
    k_bend: np.ndarray
    gravity: np.ndarray
    f_ext: np.ndarray
    held: np.ndarray
    c_stretch: np.ndarray
    c_bend: np.ndarray


@dataclass(frozen=True)
class CableModel:
    """A discretised cable with its end conditions.

    Build with :meth:`straight`; use :attr:`arrays` in kernels.
    """

    spec: CableSpec
    first: EndHolder
    last: EndHolder
    gravity: np.ndarray
    arrays: ModelArrays
    x0: np.ndarray  # initial node positions [m], (n, 3)

    @property
    def n(self) -> int:
        return self.spec.n_masses

    @classmethod
    def straight(
        cls,
        spec: CableSpec,
        start: Sequence[float] = (0.0, 0.0, 0.5),
        direction: Sequence[float] = (1.0, 0.0, 0.0),
        ends: tuple[str, str] = ("clamped", "clamped"),
        motion: Sequence[Motion] = (),
        gravity: Sequence[float] = STANDARD_GRAVITY,
    ) -> "CableModel":
        """A cable laid straight at rest length from ``start`` along ``direction``.

        Args:
            spec: cable parameters.
            start: position of node 0 [m].
            direction: direction from node 0 to node n-1 (normalised).
            ends: mode of the first and last end (``free``/``pinned``/``clamped``); a clamped
                end holds the initial tangent ``direction``.
            motion: prescribed moves of held ends.
            gravity: gravitational acceleration [m/s^2].
        """
        start_v = check_vector3("layout start", start)
        dir_v = check_vector3("layout direction", direction, unit=True)
        grav = check_vector3("gravity", gravity)
        if len(ends) != 2:
            raise ParameterError("ends must give two modes: (first, last)")
        n = spec.n_masses
        x0 = start_v + np.outer(np.arange(n) * spec.rest_length, dir_v)
        moves = tuple(motion)
        first = EndHolder(ends[0], x0[0].copy(), dir_v.copy(), tuple(m for m in moves if m.end == "first"))
        last = EndHolder(ends[1], x0[-1].copy(), dir_v.copy(), tuple(m for m in moves if m.end == "last"))
        return cls(spec, first, last, grav, build_arrays(spec, first.mode, last.mode, grav), x0)

    # ----- helpers used by the engines ---------------------------------------------------
    def initial_state(self) -> "CableState":
        """State at rest in the initial layout, t = 0."""
        return CableState(self.x0.copy(), np.zeros_like(self.x0), 0.0)

    def holder_plan(self) -> HolderPlan:
        """Start poses and motion tables of both ends, as the kernels take them."""
        return holder_plan(self.first, self.last)


def build_arrays(spec: CableSpec, first_mode: str, last_mode: str, gravity: np.ndarray) -> ModelArrays:
    """Kernel arrays for ``spec`` with end modes ``free``/``pinned``/``clamped`` and no external forces."""
    n = spec.n_masses
    k_bend = np.full(n, spec.k_bend)
    k_bend[0] = spec.k_bend_clamp if first_mode == "clamped" else 0.0
    k_bend[-1] = spec.k_bend_clamp if last_mode == "clamped" else 0.0
    held = np.zeros(n, dtype=np.bool_)
    held[0] = first_mode != "free"
    held[-1] = held[-1] or last_mode != "free"
    return ModelArrays(
        mass=spec.point_masses(),
        damp=spec.damping_coefficients(),
        k_stretch=np.full(n - 1, spec.k_stretch),
        rest_length=np.full(n - 1, spec.rest_length),
        k_bend=k_bend,
        gravity=np.asarray(gravity, dtype=float),
        f_ext=np.zeros((n, 3)),
        held=held,
        c_stretch=np.full(n - 1, spec.stretch_damping),
        c_bend=k_bend * spec.internal_damping,
    )


@dataclass
class CableState:
    """Time-varying state: positions x [m] (n, 3), velocities v [m/s] (n, 3), time t [s]."""

    x: np.ndarray
    v: np.ndarray
    t: float = 0.0

    def copy(self) -> "CableState":
        return CableState(self.x.copy(), self.v.copy(), self.t)
