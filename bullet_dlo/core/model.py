"""Discrete cable model (immutable arrays) and its time-varying state.

Following warp.sim and MuJoCo: a :class:`CableModel` holds everything that does not change
during a run (masses, springs, how the ends are held), a :class:`CableState` holds what
does (positions, velocities, time). Integrators read the model and advance the state.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple, Sequence

import numpy as np

from bullet_dlo.core.boundary import EndHolder, Motion, default_normal, holder_plan
from bullet_dlo.core.kernels.holders import HolderPlan
from bullet_dlo.core.kernels.twist import TwistArrays, make_twist, no_twist, twist_fields, twist_view
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError, check_vector3

STANDARD_GRAVITY = (0.0, 0.0, -9.81)
_NO_TWIST = no_twist()  # the empty frame of every cable without twist (never written: no kernel touches it)
_NO_DRAG = np.zeros(0)  # the empty drag law of every cable without quadratic drag (no kernel touches it)
_CROSS_FLOW = np.zeros(1, dtype=np.int64)
_NO_REST_SHAPE = np.zeros(0)  # no rest angles: a straight rest shape (no kernel touches it)


class ModelArrays(NamedTuple):
    """The model as the Numba kernels take it (SI units); a new force term adds its arrays here.

    mass: point masses [kg], (n,); damp: viscous drag coefficients [N s/m], (n,);
    k_stretch: segment spring constants [N/m], (n-1,); rest_length: segment rest lengths [m], (n-1,);
    k_bend: bending constants [N m/rad^2], (n,) (index 0 / n-1 are the clamp springs, 0 if
    that end is not clamped); gravity: gravitational acceleration [m/s^2], (3,);
    f_ext: constant external forces [N], (n, 3); held: which nodes are kinematic, (n,) bool;
    c_stretch: Kelvin-Voigt segment dampers k_s tau [N s/m], (n-1,);
    c_bend: Kelvin-Voigt bending dampers k_b tau [N m s/rad^2], (n,) (clamp dampers as k_bend).
    tw_*: the material frame (the fields of :class:`~bullet_dlo.core.kernels.twist.TwistArrays`,
    flat so that every field is an array): twist and anisotropic bending constants and the twist
    state; empty arrays (and untouched kernels) for a cable without twist. With a section that is not
    round ``k_bend`` holds the mean (k1 + k2)/2.
    drag_k: quadratic fluid drag constants 1/2 rho_f C_d w l0 [kg/m] per segment, (n-1,), empty without
    the law; drag_face: (1,) int, 1 = the drag acts along the material frame's face normal d2
    (rectangle), 0 = on the cross-flow component (see :mod:`bullet_dlo.core.kernels.drag`).
    rest_angle: rest turning angle per bending node [rad], (n,) (interior nodes; a curved rest shape,
    see :mod:`bullet_dlo.core.kernels.rest_shape`), empty for a straight rest shape.
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
    tw_k_twist: np.ndarray = _NO_TWIST.k_twist
    tw_c_twist: np.ndarray = _NO_TWIST.c_twist
    tw_k_aniso: np.ndarray = _NO_TWIST.k_aniso
    tw_inertia: np.ndarray = _NO_TWIST.inertia
    tw_drag: np.ndarray = _NO_TWIST.drag
    tw_theta: np.ndarray = _NO_TWIST.theta
    tw_omega: np.ndarray = _NO_TWIST.omega
    tw_ref: np.ndarray = _NO_TWIST.ref
    tw_tan: np.ndarray = _NO_TWIST.tan
    tw_mref: np.ndarray = _NO_TWIST.mref
    tw_normal: np.ndarray = _NO_TWIST.normal
    tw_clamp: np.ndarray = _NO_TWIST.clamp
    tw_flag: np.ndarray = _NO_TWIST.flag
    drag_k: np.ndarray = _NO_DRAG
    drag_face: np.ndarray = _CROSS_FLOW
    rest_angle: np.ndarray = _NO_REST_SHAPE

    @property
    def tw(self) -> TwistArrays:
        """The material frame's arrays (the ``tw_*`` fields, same objects)."""
        return twist_view(self)


@dataclass(frozen=True)
class CableModel:
    """A discretised cable with its end conditions.

    spec: the cable (:class:`~bullet_dlo.core.spec.CableSpec`); first, last: how its ends are held
    (:class:`~bullet_dlo.core.boundary.EndHolder`); gravity: gravitational acceleration [m/s^2], (3,);
    arrays: what the kernels take (:class:`ModelArrays`); x0: initial node positions [m], (n, 3).
    Build with :meth:`straight`; use :attr:`arrays` in kernels.
    """

    spec: CableSpec
    first: EndHolder
    last: EndHolder
    gravity: np.ndarray
    arrays: ModelArrays
    x0: np.ndarray  # initial node positions [m], (n, 3)

    def __post_init__(self) -> None:
        tw = self.arrays.tw
        if tw.normal.shape[0]:  # the held ends' section axes before the first sample
            tw.normal[:] = np.stack([self.first.normal, self.last.normal])
            tw.clamp[:] = tw.normal[0]

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
        roll: Sequence[float] = (0.0, 0.0),
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
            roll: angles [rad] by which the first and last clamp hold the section turned about
                ``direction`` from :func:`~bullet_dlo.core.boundary.default_normal` (a cable with a
                material frame only: different rolls start it twisted, in twist equilibrium).
        """
        start_v = check_vector3("layout start", start)
        dir_v = check_vector3("layout direction", direction, unit=True)
        grav = check_vector3("gravity", gravity)
        if len(ends) != 2:
            raise ParameterError("ends must give two modes: (first, last)")
        n = spec.n_masses
        x0 = start_v + np.outer(np.arange(n) * spec.rest_length, dir_v)
        moves = tuple(motion)
        if len(roll) != 2:
            raise ParameterError("roll must give two angles [rad]: (first, last)")
        d1 = default_normal(dir_v)
        d2 = np.cross(dir_v, d1)
        normals = [math.cos(float(r)) * d1 + math.sin(float(r)) * d2 for r in roll]
        first = EndHolder(ends[0], x0[0].copy(), dir_v.copy(), tuple(m for m in moves if m.end == "first"), normals[0])
        last = EndHolder(ends[1], x0[-1].copy(), dir_v.copy(), tuple(m for m in moves if m.end == "last"), normals[1])
        return cls(spec, first, last, grav, build_arrays(spec, first.mode, last.mode, grav), x0)

    # ----- helpers used by the engines ---------------------------------------------------
    def initial_state(self) -> "CableState":
        """State at rest in the initial layout, t = 0 (a twisting cable's frame is rebuilt from it at first use)."""
        self.reset_twist()
        return CableState(self.x0.copy(), np.zeros_like(self.x0), 0.0)

    def reset_twist(self) -> None:
        """Have the kernels rebuild the twist state (frames, twist angles in equilibrium, zero spin) from
        the positions they next see. A run started from an explicit state keeps the twist state the
        model's last run left (so a run continued from its final state continues its twist) unless
        this is called first."""
        self.arrays.tw.flag[:] = 0

    @property
    def twist(self) -> TwistArrays:
        """The material frame's parameters and state (empty without twist)."""
        return self.arrays.tw

    def holder_plan(self) -> HolderPlan:
        """Start poses and motion tables of both ends, as the kernels take them (with a material frame,
        the samplers also turn the section axes, into ``arrays.tw.normal``)."""
        tw = self.arrays.tw
        return holder_plan(self.first, self.last, tw.normal if tw.normal.shape[0] else None)


def build_arrays(spec: CableSpec, first_mode: str, last_mode: str, gravity: np.ndarray) -> ModelArrays:
    """Kernel arrays for ``spec`` with end modes ``free``/``pinned``/``clamped`` and no external forces."""
    n = spec.n_masses
    k_bend = np.full(n, spec.k_bend)
    k_bend[0] = spec.k_bend_clamp if first_mode == "clamped" else 0.0
    k_bend[-1] = spec.k_bend_clamp if last_mode == "clamped" else 0.0
    held = np.zeros(n, dtype=np.bool_)
    held[0] = first_mode != "free"
    held[-1] = held[-1] or last_mode != "free"
    tw = twist_arrays(spec, first_mode, last_mode) if spec.twist_enabled else _NO_TWIST
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
        **twist_fields(tw),
        **drag_fields(spec),
    )


def drag_fields(spec: CableSpec) -> dict[str, np.ndarray]:
    """The ``drag_*`` fields of the model arrays: none (the defaults) unless ``spec`` has a drag law."""
    if spec.drag_constant <= 0.0:
        return {}
    face = spec.section == "rectangle"  # the face normal needs the material frame a rectangle always has
    return {"drag_k": np.full(spec.n_masses - 1, spec.drag_constant),
            "drag_face": np.full(1, 1 if face else 0, dtype=np.int64)}


def twist_arrays(spec: CableSpec, first_mode: str, last_mode: str) -> TwistArrays:
    """The material frame of ``spec`` (see :mod:`bullet_dlo.core.kernels.twist`): twist springs G J / l0
    (a clamp node, half a Voronoi length, twice that with the default discretisation, as its bending
    spring), anisotropic bending (E I1 - E I2) / (2 l0) at every bending node, segment inertia
    rho J_p l0 with drag rate ``mass_damping_rate``, Kelvin-Voigt twist dampers k_t tau."""
    n = spec.n_masses
    k_twist = np.full(n, spec.k_twist)
    k_aniso = np.full(n, aniso_constant(spec))
    for i, mode in ((0, first_mode), (n - 1, last_mode)):
        k_twist[i], k_aniso[i] = end_twist_constants(spec, mode)
    inertia = np.full(n - 1, spec.segment_inertia)
    return make_twist(k_twist, k_twist * spec.internal_damping, k_aniso, inertia, spec.mass_damping_rate * inertia)


def aniso_constant(spec: CableSpec) -> float:
    """Anisotropic bending constant Delta = (E I1 - E I2) / (2 l0) [N m/rad^2] of an interior node."""
    ei1, ei2 = spec.bending_rigidities
    return 0.5 * (ei1 - ei2) / spec.rest_length


def end_twist_constants(spec: CableSpec, mode: str) -> tuple[float, float]:
    """Twist spring [N m/rad] and anisotropic bending constant [N m/rad^2] of an end node held in ``mode``:
    a clamp holds the twist with its half Voronoi length (the interior values times k_bend_clamp / k_bend,
    as its bending spring); a pinned or free end holds none (0, 0)."""
    if mode != "clamped":
        return 0.0, 0.0
    clamp = spec.k_bend_clamp / spec.k_bend
    return spec.k_twist * clamp, aniso_constant(spec) * clamp


@dataclass
class CableState:
    """Time-varying state: positions x [m] (n, 3), velocities v [m/s] (n, 3), time t [s]."""

    x: np.ndarray
    v: np.ndarray
    t: float = 0.0

    def copy(self) -> "CableState":
        return CableState(self.x.copy(), self.v.copy(), self.t)
