"""Discrete cable model (immutable arrays), its control and its time-varying state.

Following Newton (warp.sim) and MuJoCo: a :class:`CableModel` holds everything that does not change during
a run (masses, springs, how the ends are held at the start: :class:`ModelArrays`, read only), a
:class:`CableControl` what whoever holds the cable sets while it runs (which ends are held and how, the clamp
springs in force, the holders' poses and section axes, friction grips, external forces), and a
:class:`CableState` what the integrators advance (positions, velocities, time and the material frame's
:class:`~bullet_dlo.core.kernels.twist.TwistState`). The Numba kernels take the three as one flat argument,
:class:`KernelArrays` (:func:`kernel_arrays`: the same array objects, no copies).
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace
from typing import NamedTuple, Sequence

import numpy as np

from bullet_dlo.core.boundary import EndHolder, Motion, default_normal, holder_plan
from bullet_dlo.core.enums import EndMode
from bullet_dlo.core.kernels.contact import Grip, make_grip
from bullet_dlo.core.kernels.holders import ExternalHolders, HolderPlan
from bullet_dlo.core.kernels.twist import (
    TWIST_PARAMETERS,
    TwistArrays,
    TwistState,
    make_twist,
    make_twist_state,
    no_twist,
    twist_view,
)
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError, check_vector3

STANDARD_GRAVITY = (0.0, 0.0, -9.81)


def read_only(a: np.ndarray) -> np.ndarray:
    """``a`` write-protected: itself if it is a read-only array owning its data, else a read-only copy (so
    that nobody holding the original can change it either)."""
    if not a.flags.writeable and a.base is None:
        return a
    out = np.array(a, copy=True)
    out.flags.writeable = False
    return out


_NO_TWIST = no_twist()._replace(**{k: read_only(getattr(no_twist(), k)) for k in TWIST_PARAMETERS})
_NO_DRAG = read_only(np.zeros(0))  # the empty drag law of every cable without quadratic drag
_CROSS_FLOW = read_only(np.zeros(1, dtype=np.int64))
_NO_REST_SHAPE = read_only(np.zeros(0))  # no rest angles: a straight rest shape (no kernel touches it)


class TwistParameters(NamedTuple):
    """The material frame's parameters in a model (SI; empty arrays without twist): k_twist: twist spring
    constants [N m/rad], (n,); c_twist: Kelvin-Voigt twist dampers [N m s/rad], (n,); k_aniso: anisotropic
    bending constants [N m/rad^2], (n,); inertia: segment inertia about the axis [kg m^2], (n-1,);
    drag: twist drag c I_k [N m s/rad], (n-1,). The ends' values are those of the model's end modes."""

    k_twist: np.ndarray
    c_twist: np.ndarray
    k_aniso: np.ndarray
    inertia: np.ndarray
    drag: np.ndarray


class ModelArrays(NamedTuple):
    """The model's parameters (SI units), read only; a new force term adds its arrays here.

    mass: point masses [kg], (n,); damp: viscous drag coefficients [N s/m], (n,);
    k_stretch: segment spring constants [N/m], (n-1,); rest_length: segment rest lengths [m], (n-1,);
    k_bend: bending constants [N m/rad^2], (n,) (index 0 / n-1 are the clamp springs, 0 if that end is not
    clamped in the model's end modes; a :class:`CableControl` holds the ones in force);
    gravity: gravitational acceleration [m/s^2], (3,); held: which nodes the model's end modes hold, (n,) bool;
    c_stretch: Kelvin-Voigt segment dampers k_s tau [N s/m], (n-1,);
    c_bend: Kelvin-Voigt bending dampers k_b tau [N m s/rad^2], (n,) (clamp dampers as k_bend).
    tw_k_twist [N m/rad], tw_c_twist [N m s/rad], tw_k_aniso [N m/rad^2] (n,), tw_inertia [kg m^2],
    tw_drag [N m s/rad] (n-1,): the material frame's parameters (:class:`TwistParameters`), empty without
    twist. With a section that is not round ``k_bend`` holds the mean (k1 + k2)/2.
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
    held: np.ndarray
    c_stretch: np.ndarray
    c_bend: np.ndarray
    tw_k_twist: np.ndarray = _NO_TWIST.k_twist
    tw_c_twist: np.ndarray = _NO_TWIST.c_twist
    tw_k_aniso: np.ndarray = _NO_TWIST.k_aniso
    tw_inertia: np.ndarray = _NO_TWIST.inertia
    tw_drag: np.ndarray = _NO_TWIST.drag
    drag_k: np.ndarray = _NO_DRAG
    drag_face: np.ndarray = _CROSS_FLOW
    rest_angle: np.ndarray = _NO_REST_SHAPE

    @property
    def tw(self) -> TwistParameters:
        """The material frame's parameters (the ``tw_*`` fields, same objects)."""
        return TwistParameters(*(getattr(self, f"tw_{k}") for k in TWIST_PARAMETERS))


class KernelArrays(NamedTuple):
    """What the Numba kernels take as ``m``: the model's parameters with the control's end conditions in force
    and the twist state, flat (built by :func:`kernel_arrays`; the same array objects as the
    :class:`ModelArrays`, :class:`CableControl` and :class:`~bullet_dlo.core.kernels.twist.TwistState` it is
    built from, so a kernel that advances the twist state writes the state's arrays).

    mass [kg], damp [N s/m], k_stretch [N/m], rest_length [m], gravity [m/s^2], c_stretch [N s/m],
    tw_inertia [kg m^2], tw_drag [N m s/rad], drag_k [kg/m], drag_face, rest_angle [rad]: the model's
    k_bend [N m/rad^2], c_bend [N m s/rad^2], f_ext [N], held, tw_k_twist [N m/rad], tw_c_twist [N m s/rad],
    tw_k_aniso [N m/rad^2], tw_normal, tw_clamp: the control's (:class:`CableControl`); tw_theta [rad],
    tw_omega [rad/s], tw_ref, tw_tan, tw_mref [rad], tw_flag: the twist state's
    (:class:`~bullet_dlo.core.kernels.twist.TwistState`), tw_prev [rad, rad/s] its BDF2 history.
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
    tw_k_twist: np.ndarray
    tw_c_twist: np.ndarray
    tw_k_aniso: np.ndarray
    tw_inertia: np.ndarray
    tw_drag: np.ndarray
    tw_theta: np.ndarray
    tw_omega: np.ndarray
    tw_ref: np.ndarray
    tw_tan: np.ndarray
    tw_mref: np.ndarray
    tw_normal: np.ndarray
    tw_clamp: np.ndarray
    tw_flag: np.ndarray
    tw_prev: np.ndarray
    drag_k: np.ndarray
    drag_face: np.ndarray
    rest_angle: np.ndarray

    @property
    def tw(self) -> TwistArrays:
        """The material frame's arrays (the ``tw_*`` fields, same objects)."""
        return twist_view(self)


@dataclass(frozen=True)
class CableControl:
    """What whoever holds the cable sets while it runs (SI). The arrays are changed in place and the fields
    are never rebound: the kernels' arrays (:class:`KernelArrays`) share them. Make one with
    :meth:`CableModel.control` (the model's end conditions, no external force).

    held: which nodes are kinematic (held ends), (n,) bool;
    k_bend: bending constants in force [N m/rad^2], (n,): the model's, with each end's clamp spring as the end
    is held now (0: not clamped); c_bend: their Kelvin-Voigt dampers [N m s/rad^2], (n,);
    k_twist: twist spring constants in force [N m/rad], (n,) ((0,) without a material frame), the ends' as
    held now; c_twist: their Kelvin-Voigt dampers [N m s/rad], (n,) or (0,); k_aniso: anisotropic bending
    constants in force [N m/rad^2], (n,) or (0,);
    f_ext: external force on each node [N], (n, 3) (constant until changed);
    normal: the held ends' section axes d1 (unit) at the three held-end sample times of a step, (3, 2, 3)
    ((0, 2, 3) without a material frame; the holder samplers write it); clamp: the section axes (unit) the
    force kernels use now, (2, 3);
    holders: measured poses of external holders (grippers) the ends follow
    (:class:`~bullet_dlo.core.kernels.holders.ExternalHolders`; ``active`` says which);
    grip: the friction grips of the ends (:class:`~bullet_dlo.core.kernels.contact.Grip`).
    """

    held: np.ndarray
    k_bend: np.ndarray
    c_bend: np.ndarray
    k_twist: np.ndarray
    c_twist: np.ndarray
    k_aniso: np.ndarray
    f_ext: np.ndarray
    normal: np.ndarray
    clamp: np.ndarray
    holders: ExternalHolders
    grip: Grip

    @classmethod
    def of(cls, arrays: ModelArrays, start_dir: np.ndarray, start_normal: np.ndarray,
           f_ext: np.ndarray | None = None) -> "CableControl":
        """The control that holds the ends as the model ``arrays`` do (own copies of their end conditions),
        with holder directions ``start_dir`` and section axes ``start_normal`` (2, 3) each and external forces
        ``f_ext`` [N] (n, 3) (None: none)."""
        n = arrays.mass.shape[0]
        twisting = arrays.tw_k_twist.shape[0] > 0
        normal = np.zeros((3 if twisting else 0, 2, 3))
        clamp = np.zeros((2, 3))
        if twisting:  # the held ends' section axes before the first sample
            normal[:] = start_normal
            clamp[:] = start_normal
        force = np.zeros((n, 3))
        if f_ext is not None:
            f = np.asarray(f_ext, dtype=float)
            if f.shape != (n, 3) or not np.all(np.isfinite(f)):
                raise ParameterError(f"f_ext must be a finite array of shape ({n}, 3)")
            force[:] = f
        zeros = np.zeros((2, 3))
        holders = ExternalHolders(active=np.zeros(2, dtype=np.bool_), pos=zeros.copy(), vel=zeros.copy(),
                                  acc=zeros.copy(), omega=zeros.copy(), alpha=zeros.copy(),
                                  dir=np.array(start_dir, dtype=float),  # clamp directions until a holder takes over
                                  normal=np.array(start_normal, dtype=float))
        return cls(held=arrays.held.copy(), k_bend=arrays.k_bend.copy(), c_bend=arrays.c_bend.copy(),
                   k_twist=arrays.tw_k_twist.copy(), c_twist=arrays.tw_c_twist.copy(),
                   k_aniso=arrays.tw_k_aniso.copy(), f_ext=force, normal=normal, clamp=clamp, holders=holders,
                   grip=make_grip())


def kernel_arrays(model: ModelArrays, control: CableControl | None = None,
                  twist: TwistState | None = None) -> KernelArrays:
    """The kernels' view of ``model`` under ``control`` with twist state ``twist`` (same array objects).

    control None: the model's end conditions (:meth:`CableControl.of`, section axes zero: for kernels that do
    not read them); twist None: a new twist state, built from the positions at its first use.
    """
    n = model.mass.shape[0]
    if control is None:
        control = CableControl.of(model, np.zeros((2, 3)), np.zeros((2, 3)))
    if twist is None:
        twist = make_twist_state(n, model.tw_k_twist.shape[0] > 0)
    return KernelArrays(
        mass=model.mass, damp=model.damp, k_stretch=model.k_stretch, rest_length=model.rest_length,
        k_bend=control.k_bend, gravity=model.gravity, f_ext=control.f_ext, held=control.held,
        c_stretch=model.c_stretch, c_bend=control.c_bend, tw_k_twist=control.k_twist,
        tw_c_twist=control.c_twist, tw_k_aniso=control.k_aniso, tw_inertia=model.tw_inertia,
        tw_drag=model.tw_drag, tw_theta=twist.theta, tw_omega=twist.omega, tw_ref=twist.ref, tw_tan=twist.tan,
        tw_mref=twist.mref, tw_normal=control.normal, tw_clamp=control.clamp, tw_flag=twist.flag,
        tw_prev=twist.prev,
        drag_k=model.drag_k, drag_face=model.drag_face, rest_angle=model.rest_angle)


@dataclass(frozen=True)
class CableModel:
    """A discretised cable with its end conditions.

    spec: the cable (:class:`~bullet_dlo.core.spec.CableSpec`); first, last: how its ends are held
    (:class:`~bullet_dlo.core.boundary.EndHolder`); gravity: gravitational acceleration [m/s^2], (3,);
    arrays: its parameters as the kernels take them (:class:`ModelArrays`, read only);
    x0: initial node positions [m], (n, 3).
    Build with :meth:`straight`; a run takes :meth:`control`, :meth:`initial_state` and :meth:`kernel_arrays`.
    """

    spec: CableSpec
    first: EndHolder
    last: EndHolder
    gravity: np.ndarray
    arrays: ModelArrays
    x0: np.ndarray  # initial node positions [m], (n, 3)

    def __post_init__(self) -> None:
        # read only: a model is shared by runs and cables (each takes its own control and state)
        set_ = object.__setattr__
        set_(self, "arrays", type(self.arrays)(*(read_only(a) for a in self.arrays)))
        set_(self, "gravity", read_only(np.asarray(self.gravity, dtype=float)))
        set_(self, "x0", read_only(np.asarray(self.x0, dtype=float)))

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
            ends: mode of the first and last end (``free``/``pinned``/``fork``/``clamped``); a clamped
                end holds the initial tangent ``direction``, a fork the roll about it.
            motion: prescribed moves of held ends.
            gravity: gravitational acceleration [m/s^2].
            roll: angles [rad] by which the first and last clamp hold the section turned about
                ``direction`` from :func:`~bullet_dlo.core.boundary.default_normal` (a cable with a
                material frame only: different rolls start it twisted, in twist equilibrium). The start
                state takes the shortest turn between the two sections, so the rolls must differ by less
                than pi (ParameterError otherwise); twist a cable further by turning a clamp in ``motion``.
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
        turn = float(roll[1]) - float(roll[0])
        if not abs(turn) < math.pi:  # (also NaN) the start state is the shortest turn between the two sections
            raise ParameterError(f"roll: the last clamp's roll minus the first's must be in (-pi, pi) [rad], got "
                                 f"{turn!r} (twist a cable further by turning a clamp in its motion)")
        d1 = default_normal(dir_v)
        d2 = np.cross(dir_v, d1)
        normals = [math.cos(float(r)) * d1 + math.sin(float(r)) * d2 for r in roll]
        first = EndHolder(ends[0], x0[0].copy(), dir_v.copy(), tuple(m for m in moves if m.end == "first"), normals[0])
        last = EndHolder(ends[1], x0[-1].copy(), dir_v.copy(), tuple(m for m in moves if m.end == "last"), normals[1])
        return cls(spec, first, last, grav, build_arrays(spec, first.mode, last.mode, grav), x0)

    # ----- what a run takes ----------------------------------------------------------------
    def initial_state(self) -> "CableState":
        """State at rest in the initial layout, t = 0 (a twisting cable's frame is built from it at first use)."""
        return CableState(self.x0.copy(), np.zeros_like(self.x0), 0.0)

    def twist_state(self) -> TwistState:
        """A new twist state (empty without a material frame), built from the positions at its first use."""
        return make_twist_state(self.n, self.arrays.tw_k_twist.shape[0] > 0)

    def control(self, f_ext: np.ndarray | None = None) -> CableControl:
        """A control that holds the ends as the model says (its own arrays), with external forces ``f_ext`` [N],
        (n, 3) (None: none)."""
        return CableControl.of(self.arrays, np.stack([self.first.direction, self.last.direction]),
                               np.stack([self.first.normal, self.last.normal]), f_ext)

    def kernel_arrays(self, control: CableControl | None = None, twist: TwistState | None = None) -> KernelArrays:
        """The kernels' view of the model under ``control`` (None: a new :meth:`control`) with twist state
        ``twist`` (None: a new one, built at first use): see :func:`kernel_arrays`."""
        return kernel_arrays(self.arrays, self.control() if control is None else control, twist)

    def reset_twist(self) -> None:
        """Deprecated, does nothing: the twist state now lives in :class:`CableState` (``twist``); a state
        without one (``twist`` None, as :meth:`initial_state` and a static solution give) has it built from its
        positions at the first step, a run's ``final_state`` carries its own on."""
        warnings.warn("CableModel.reset_twist() is no longer needed: the twist state lives in CableState.twist "
                      "(None: built from the positions at the first step)", DeprecationWarning, stacklevel=2)

    def holder_plan(self, control: CableControl | None = None) -> HolderPlan:
        """Start poses and motion tables of both ends, as the kernels take them; with a ``control`` of a cable
        with a material frame, the samplers also turn the section axes, into ``control.normal`` (else the roll
        is not tracked)."""
        normal = control.normal if control is not None and control.normal.shape[0] else None
        return holder_plan(self.first, self.last, normal)


def with_arrays(model: CableModel, **arrays: np.ndarray) -> CableModel:
    """A copy of ``model`` with some parameter arrays replaced (``ModelArrays`` field names, e.g. ``mass`` [kg]
    with a weight hung on a node, ``damp`` [N s/m]), each finite, non-negative (masses positive) and of the
    field's shape; ``model`` itself is left as it was."""
    a = model.arrays
    new = {}
    for name, value in arrays.items():
        if name not in a._fields:
            raise ParameterError(f"{name} is not a model array (one of {', '.join(a._fields)})")
        old = getattr(a, name)
        v = np.array(value, dtype=old.dtype)
        low = "positive" if name == "mass" else "non-negative"
        if v.shape != old.shape or not np.all(np.isfinite(v)) or not np.all(v > 0 if name == "mass" else v >= 0):
            raise ParameterError(f"{name} must be {low} finite values of shape {old.shape}")
        new[name] = v
    return replace(model, arrays=a._replace(**new))


def build_arrays(spec: CableSpec, first_mode: str, last_mode: str, gravity: np.ndarray) -> ModelArrays:
    """The model's parameters for ``spec`` with end modes ``free``/``pinned``/``fork``/``clamped`` (read-only
    arrays)."""
    n = spec.n_masses
    k_bend = np.full(n, spec.k_bend)
    k_bend[0] = spec.k_bend_clamp if first_mode == "clamped" else 0.0
    k_bend[-1] = spec.k_bend_clamp if last_mode == "clamped" else 0.0
    held = np.zeros(n, dtype=np.bool_)
    held[0] = first_mode != "free"
    held[-1] = held[-1] or last_mode != "free"
    tw = twist_arrays(spec, first_mode, last_mode) if spec.twist_enabled else _NO_TWIST
    twist = {f"tw_{k}": getattr(tw, k) for k in TWIST_PARAMETERS}
    arrays = ModelArrays(
        mass=spec.point_masses(),
        damp=spec.damping_coefficients(),
        k_stretch=np.full(n - 1, spec.k_stretch),
        rest_length=np.full(n - 1, spec.rest_length),
        k_bend=k_bend,
        gravity=np.asarray(gravity, dtype=float),
        held=held,
        c_stretch=np.full(n - 1, spec.stretch_damping),
        c_bend=k_bend * spec.internal_damping,
        **twist,
        **drag_fields(spec),
    )
    return ModelArrays(*(read_only(a) for a in arrays))  # write-protected: a model never changes


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
    as its bending spring); a fork holds the same twist and no bending (0 for the anisotropic part, as its
    isotropic bending spring is 0); a pinned or free end holds neither (0, 0)."""
    if not EndMode(mode).holds_roll:
        return 0.0, 0.0
    clamp = spec.k_bend_clamp / spec.k_bend
    return spec.k_twist * clamp, (aniso_constant(spec) * clamp if mode == "clamped" else 0.0)


@dataclass
class CableState:
    """Time-varying state: positions x [m] (n, 3), velocities v [m/s] (n, 3), time t [s] and the material
    frame's state ``twist`` (:class:`~bullet_dlo.core.kernels.twist.TwistState`; None: built from x at the
    first step, in twist equilibrium with the held ends; empty arrays for a cable without twist)."""

    x: np.ndarray
    v: np.ndarray
    t: float = 0.0
    twist: TwistState | None = None

    def copy(self) -> "CableState":
        return CableState(self.x.copy(), self.v.copy(), self.t, None if self.twist is None else self.twist.copy())

    @classmethod
    def along(cls, points, spacing: float, n: int) -> "CableState":
        """A cable at rest with its ``n`` nodes ``spacing`` [m] apart in arc length along the polyline ``points``
        [m] (k, 3), from its first point (beyond the last point the last one is repeated)."""
        p = np.asarray(points, dtype=float)
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
        x = np.stack([np.interp(np.arange(n) * spacing, s, p[:, j]) for j in range(3)], axis=1)
        return cls(x, np.zeros_like(x))
