"""Peer simulators (PyElastica, MuJoCo) on the cantilever benchmark.

The benchmark, in SI units: a straight horizontal rod of length ``L`` [m],
diameter ``d`` [m], total mass ``M`` [kg], Young's modulus ``E`` [Pa] and
Poisson ratio 0.3, discretised into ``n`` nodes (``n - 1`` elements).  The
first end is clamped at the origin with its tangent along +x, the other end
is free, and gravity acts along -z.

Two modes are run by each peer:

``"static"`` (S1)
    Gravity ``g = 9.81`` m/s^2 with velocity damping, run for ``duration``
    seconds; the result is the downward tip deflection at the end, to compare
    with ``delta = w L^4 / (8 E I)``, ``w = M g / L``, ``I = pi d^4 / 64``
    (:func:`static_deflection`).

``"free"`` (S2)
    The rod first settles (damped, untimed) under the small gravity for which
    the closed form gives a tip deflection of ``1e-3 L``, which puts it close
    to its first mode shape.  Then gravity and damping are switched off, the
    velocities are zeroed and the rod swings freely for ``duration`` seconds.
    The result is the first bending frequency from the upward zero crossings
    of the tip's vertical displacement (linear interpolation), to compare with
    :func:`first_frequency`, and the amplitude of the last full period divided
    by the initial tip displacement.

Both peers clamp their whole first element/segment (that is each tool's
natural clamp), which moves the effective clamp about half an element along
the rod: it costs roughly ``2 / n`` of the static tip deflection (-21 % at
n = 10, -10 % at n = 20) and raises the first frequency by roughly ``1 / n``.
This is expected and left as is.

Damping, where used, is a uniform velocity damping *rate* ``c`` [1/s]: every
translational (and, for PyElastica, rotational) velocity decays as
``exp(-c t)``, i.e. a mass-proportional damping force ``-c m v``.  With
``c = 2 omega_1`` the first mode is critically damped and every mode decays
at least as ``exp(-omega_1 t)``; that is the default for the static mode and
for the settling phase of the free mode.  In the free phase the default is no
damping at all.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

__all__ = [
    "PeerResult",
    "available",
    "run_pyelastica",
    "run_mujoco",
    "static_deflection",
    "first_frequency",
    "POISSON",
    "GRAVITY",
]

POISSON = 0.3
"""Poisson ratio of the benchmark [-]."""

GRAVITY = 9.81
"""Gravitational acceleration of the static benchmark [m/s^2]."""

FREE_AMPLITUDE = 1e-3
"""Initial tip amplitude of the free mode, as a fraction of ``L`` (closed form)."""

SETTLE_OMEGA_T = 15.0
"""Length of the damped settling phase of the free mode, in units of ``1/omega_1``."""

_BETA1 = 1.8751040687119611  # first root of cos(x) cosh(x) = -1


@dataclass
class PeerResult:
    """Result of one benchmark run of a peer simulator.

    Attributes:
        peer: ``"pyelastica"`` or ``"mujoco"``.
        mode: ``"static"`` or ``"free"``.
        n: number of nodes.
        dt: time step [s].
        stable: False if the run diverged: non-finite state, a segment
            strain above ``MAX_STRAIN``, MuJoCo's bad qpos/qvel/qacc warning
            counters > 0 (MuJoCo then silently resets the state to its start),
            or, in the free mode, a tip excursion above ``GROWTH_LIMIT`` times
            the initial one (energy gain of an unstable explicit scheme).
        tip_deflection: static mode only: downward tip deflection at the end
            of the run [m] (positive down).
        frequency: free mode only: measured first bending frequency [Hz].
        amplitude_kept: free mode only: half peak-to-peak tip displacement
            over the last full period divided by the initial tip displacement
            [-] (1.0 means no amplitude loss).
        wall_time_s: wall-clock time of the timed loop only [s] (for the free
            mode the free phase only, not model building nor settling).
        sim_time_s: simulated time of the timed loop [s].
        note: free-form details (integrator, parameter mapping, settling).
    """

    peer: str
    mode: str
    n: int
    dt: float
    stable: bool
    tip_deflection: float | None
    frequency: float | None
    amplitude_kept: float | None
    wall_time_s: float
    sim_time_s: float
    note: str = ""


# ---------------------------------------------------------------------------
# closed forms and shared helpers
# ---------------------------------------------------------------------------


def _second_moment(d: float) -> float:
    """Second moment of area ``pi d^4 / 64`` [m^4] of a circle of diameter ``d`` [m]."""
    return math.pi * d**4 / 64.0


def static_deflection(L: float, d: float, M: float, E: float, g: float = GRAVITY) -> float:
    """Closed-form tip deflection ``w L^4 / (8 E I)`` [m] of the cantilever.

    Args:
        L: length [m].  d: diameter [m].  M: total mass [kg].
        E: Young's modulus [Pa].  g: gravitational acceleration [m/s^2].
    """
    w = M * g / L
    return w * L**4 / (8.0 * E * _second_moment(d))


def first_frequency(L: float, d: float, M: float, E: float) -> float:
    """Closed-form first bending frequency [Hz] of the cantilever.

    ``f1 = 1.8751^2 / (2 pi) * sqrt(E I / (rho A L^4))`` with ``rho A = M / L``.
    """
    return _BETA1**2 / (2.0 * math.pi) * math.sqrt(E * _second_moment(d) / (M / L * L**4))


def _omega1(L: float, d: float, M: float, E: float) -> float:
    """Closed-form first angular frequency [rad/s]."""
    return 2.0 * math.pi * first_frequency(L, d, M, E)


def _free_gravity(L: float, d: float, M: float, E: float) -> float:
    """Gravity [m/s^2] whose closed-form static tip deflection is ``FREE_AMPLITUDE * L``."""
    return GRAVITY * FREE_AMPLITUDE * L / static_deflection(L, d, M, E, GRAVITY)


MAX_STRAIN = 0.05
"""Largest segment strain [-] accepted before a run is declared diverged (the
benchmark's physical strains are below 1e-4; an exploding explicit run
stretches its segments by far more)."""

GROWTH_LIMIT = 2.0
"""Free mode: a tip excursion beyond this multiple of the initial displacement
means the (undamped, unforced) run gained energy, i.e. is numerically unstable."""


def _max_strain(pos: np.ndarray, seg: float) -> float:
    """Largest |segment length / ``seg`` - 1| [-] of the polyline ``pos`` (3, n) [m]."""
    lengths = np.sqrt((np.diff(pos, axis=1) ** 2).sum(axis=0))
    return float(np.abs(lengths / seg - 1.0).max())


def _segments_ok(pos: np.ndarray, seg: float) -> bool:
    """True if all node positions ``pos`` (3, n) [m] are finite and every
    segment length is within ``MAX_STRAIN`` of the rest length ``seg`` [m]."""
    return bool(np.isfinite(pos).all()) and _max_strain(pos, seg) < MAX_STRAIN


def _check_args(n: int, dt: float, mode: str, duration: float) -> None:
    if mode not in ("static", "free"):
        raise ValueError(f"mode must be 'static' or 'free', got {mode!r}")
    if n < 4:
        raise ValueError(f"need at least 4 nodes, got n={n}")
    if not dt > 0.0 or not duration > 0.0:
        raise ValueError("dt and duration must be positive")


def _oscillation(t: np.ndarray, z: np.ndarray) -> tuple[float | None, float | None, int]:
    """Frequency and last-period half peak-to-peak amplitude of a signal.

    Args:
        t: sample times [s].
        z: signal oscillating about 0 (tip vertical displacement [m]).

    Returns:
        ``(frequency [Hz], amplitude [m], number of upward zero crossings)``;
        frequency and amplitude are None with fewer than two crossings.
    """
    k = np.nonzero((z[:-1] < 0.0) & (z[1:] >= 0.0))[0]
    crossings = t[k] - z[k] * (t[k + 1] - t[k]) / (z[k + 1] - z[k])
    if len(crossings) < 2:
        return None, None, len(crossings)
    freq = (len(crossings) - 1) / (crossings[-1] - crossings[0])
    last = (t >= crossings[-2]) & (t <= crossings[-1])
    amp = 0.5 * (z[last].max() - z[last].min())
    return float(freq), float(amp), len(crossings)


def _first_period_amplitude(t: np.ndarray, z: np.ndarray) -> float | None:
    """Half peak-to-peak amplitude [m] over the first full period (between the
    first two upward zero crossings), or None."""
    k = np.nonzero((z[:-1] < 0.0) & (z[1:] >= 0.0))[0]
    if len(k) < 2:
        return None
    seg = z[k[0] : k[1] + 2]
    return float(0.5 * (seg.max() - seg.min()))


def _free_result(
    peer: str,
    n: int,
    dt: float,
    stable: bool,
    t: np.ndarray,
    z: np.ndarray,
    z0: float,
    wall: float,
    sim_time: float,
    note: str,
) -> PeerResult:
    """Assemble a free-mode result from the tip trace ``z(t)`` [m]."""
    freq = amp_kept = None
    if stable and np.abs(z).max() > GROWTH_LIMIT * abs(z0):
        stable = False
        note += (
            f"; tip excursion grew to {np.abs(z).max() / abs(z0):.3g} x the initial "
            "displacement: numerical instability (energy gain)"
        )
    if stable:
        freq, amp, ncross = _oscillation(t, z)
        amp1 = _first_period_amplitude(t, z)
        if freq is None:
            note += f"; only {ncross} upward zero crossing(s): run longer"
        else:
            amp_kept = amp / abs(z0)
            note += f"; {ncross} upward zero crossings; initial tip displacement {z0:.6g} m"
            if amp1 is not None:
                note += f"; first-period amplitude / initial = {amp1 / abs(z0):.6f}"
    return PeerResult(peer, "free", n, dt, stable, None, freq, amp_kept, wall, sim_time, note)


def available() -> dict[str, bool]:
    """Which peer simulators can be imported: ``{"pyelastica": bool, "mujoco": bool}``."""
    out = {}
    for peer, module in (("pyelastica", "elastica"), ("mujoco", "mujoco")):
        try:
            __import__(module)
            out[peer] = True
        except Exception:
            out[peer] = False
    return out


# ---------------------------------------------------------------------------
# PyElastica
# ---------------------------------------------------------------------------


def _pyelastica_classes() -> tuple[type, type, type]:
    """Simulator, switchable gravity and switchable damper classes for PyElastica."""
    import elastica as ea

    class Simulator(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping):
        pass

    class SharedGravity(ea.GravityForces):
        """``GravityForces`` reading a shared 3-vector [m/s^2] that can be
        changed in place during the run."""

        def __init__(self, acc_gravity: np.ndarray) -> None:
            super().__init__(acc_gravity=acc_gravity)
            self.acc_gravity = acc_gravity  # share, do not copy

    class SharedDamper(ea.DamperBase):
        """Analytical uniform velocity damping, ``v *= exp(-c dt)`` and
        ``omega *= exp(-c dt)`` each step (like ``AnalyticalLinearDamper``
        with ``uniform_damping_constant=c``), with the factor read from a
        shared 1-array that can be changed in place during the run."""

        def __init__(self, factor: np.ndarray, **kwargs: object) -> None:
            super().__init__(**kwargs)
            self.factor = factor

        def dampen_rates(self, system: ea.CosseratRod, time: np.float64) -> None:
            f = self.factor[0]
            if f != 1.0:
                system.velocity_collection *= f
                system.omega_collection *= f

    return Simulator, SharedGravity, SharedDamper


_PYELASTICA_WARM = False


def _pyelastica_warmup() -> None:
    """Step a tiny throwaway rod once so that Numba's just-in-time compilation
    is not counted in the wall time of the first timed run."""
    global _PYELASTICA_WARM
    if _PYELASTICA_WARM:
        return
    import elastica as ea

    Simulator, SharedGravity, SharedDamper = _pyelastica_classes()
    sim = Simulator()
    rod = ea.CosseratRod.straight_rod(
        4, np.zeros(3), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]),
        1.0, 0.01, 1000.0, youngs_modulus=1e6, shear_modulus=1e6 / 2.6,
    )
    sim.append(rod)
    sim.constrain(rod).using(
        ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,)
    )
    sim.add_forcing_to(rod).using(SharedGravity, acc_gravity=np.array([0.0, 0.0, -1.0]))
    sim.dampen(rod).using(SharedDamper, factor=np.array([0.5]))
    sim.finalize()
    stepper = ea.PositionVerlet()
    t = np.float64(0.0)
    for _ in range(2):
        t = stepper.step(sim, t, 1e-6)
    _PYELASTICA_WARM = True


def run_pyelastica(
    L: float,
    d: float,
    M: float,
    E: float,
    n: int,
    dt: float,
    mode: str,
    duration: float,
    damping: float | None = None,
) -> PeerResult:
    """Run the cantilever benchmark with PyElastica (Cosserat rod).

    Model: ``CosseratRod.straight_rod`` with ``n - 1`` elements from the
    origin along +x (normal +z), radius ``d / 2``, density
    ``M / (pi d^2 / 4 * L)``, Young's modulus ``E`` and shear modulus
    ``E / (2 (1 + 0.3))``; ``OneEndFixedBC`` on node 0 and element 0
    (position and directors), gravity on the nodal masses, explicit
    ``PositionVerlet`` stepping.  Damping is PyElastica's analytical uniform
    damping (``AnalyticalLinearDamper`` protocol with
    ``uniform_damping_constant``, re-implemented so that it can be switched
    off after the settling phase of the free mode).

    PyElastica is explicit and needs small steps.  In our tests the largest
    stable step was about ``1.5 r / sqrt(E / rho)`` (``r = d / 2``), set by
    the rotation of the short, thick elements rather than by ``n``: 7e-6 s
    stable and 1e-5 s diverged for L = 0.1 m, d = 4 mm, E = 1 GPa,
    rho = 7958 kg/m^3, n = 10; 5e-7 s stable at both n = 10 and n = 20 and
    7e-7 s diverged at n = 10 for L = 0.3 m, d = 4 mm, E = 263 GPa.

    Args:
        L: length [m].
        d: diameter [m].
        M: total mass [kg].
        E: Young's modulus [Pa].
        n: number of nodes (``n - 1`` elements).
        dt: time step [s].
        mode: ``"static"`` or ``"free"`` (see the module docstring).
        duration: simulated time of the timed run [s] (static: whole run;
            free: the free phase, after an untimed settling phase of
            ``15 / omega_1`` seconds).
        damping: uniform velocity damping rate [1/s].  None: ``2 omega_1`` in
            the static mode (and always in the settling phase), 0 in the free
            phase.

    Returns:
        The :class:`PeerResult`.
    """
    _check_args(n, dt, mode, duration)
    import elastica as ea

    _pyelastica_warmup()
    Simulator, SharedGravity, SharedDamper = _pyelastica_classes()
    omega1 = _omega1(L, d, M, E)
    c_settle = 2.0 * omega1
    area = math.pi * d**2 / 4.0

    sim = Simulator()
    rod = ea.CosseratRod.straight_rod(
        n - 1,
        np.zeros(3),
        np.array([1.0, 0.0, 0.0]),
        np.array([0.0, 0.0, 1.0]),
        L,
        d / 2.0,
        M / (area * L),
        youngs_modulus=E,
        shear_modulus=E / (2.0 * (1.0 + POISSON)),
    )
    sim.append(rod)
    sim.constrain(rod).using(
        ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,)
    )
    gravity = np.zeros(3)
    factor = np.ones(1)
    sim.add_forcing_to(rod).using(SharedGravity, acc_gravity=gravity)
    sim.dampen(rod).using(SharedDamper, factor=factor)
    sim.finalize()
    stepper = ea.PositionVerlet()

    pos = rod.position_collection
    seg = L / (n - 1)

    def run(t0: float, steps: int, trace: np.ndarray | None) -> tuple[float, bool, float]:
        """Step ``steps`` times; record tip z in ``trace``; return
        (time, stable, wall time)."""
        tt = np.float64(t0)
        start = time.perf_counter()
        check = max(1, min(steps, 100))
        for k in range(steps):
            tt = stepper.step(sim, tt, dt)
            if trace is not None:
                trace[k] = pos[2, -1]
            if (k + 1) % check == 0 or k + 1 == steps:
                if not _segments_ok(pos, seg):
                    return float(tt), False, time.perf_counter() - start
        return float(tt), True, time.perf_counter() - start

    base_note = (
        f"PositionVerlet; straight_rod n_elements={n - 1}, radius=d/2, "
        f"density=M/(A L)={M / (area * L):.6g} kg/m^3, shear_modulus=E/(2(1+{POISSON})), "
        f"OneEndFixedBC on node 0 + element 0"
    )

    if mode == "static":
        c = c_settle if damping is None else float(damping)
        gravity[:] = (0.0, 0.0, -GRAVITY)
        factor[0] = math.exp(-c * dt)
        steps = int(round(duration / dt))
        _, stable, wall = run(0.0, steps, None)
        tip = -float(pos[2, -1]) if stable else None
        vel = float(np.abs(rod.velocity_collection[2, -1])) if stable else float("nan")
        note = base_note + (
            f"; uniform damping c={c:.6g} 1/s; final |tip vz|={vel:.3g} m/s"
            f"; final max segment strain {_max_strain(pos, seg):.3g}"
        )
        return PeerResult(
            "pyelastica", mode, n, dt, stable, tip, None, None, wall, steps * dt, note
        )

    # free mode: settle under small gravity with damping, then release
    settle_steps = int(math.ceil(SETTLE_OMEGA_T / omega1 / dt))
    gravity[:] = (0.0, 0.0, -_free_gravity(L, d, M, E))
    factor[0] = math.exp(-c_settle * dt)
    t_now, stable, _ = run(0.0, settle_steps, None)
    note = base_note + (
        f"; settled {settle_steps * dt:.4g} s (untimed) with c={c_settle:.6g} 1/s "
        f"under g={-gravity[2]:.6g} m/s^2"
    )
    if not stable:
        return PeerResult("pyelastica", mode, n, dt, False, None, None, None, 0.0, 0.0, note)
    gravity[:] = 0.0
    c = 0.0 if damping is None else float(damping)
    factor[0] = math.exp(-c * dt)
    note += f"; free phase damping c={c:.6g} 1/s"
    rod.velocity_collection[:] = 0.0
    rod.omega_collection[:] = 0.0
    z0 = float(pos[2, -1])
    steps = int(round(duration / dt))
    trace = np.empty(steps + 1)
    trace[0] = z0
    _, stable, wall = run(t_now, steps, trace[1:])
    t = np.arange(steps + 1) * dt
    return _free_result("pyelastica", n, dt, stable, t, trace, z0, wall, steps * dt, note)


# ---------------------------------------------------------------------------
# MuJoCo
# ---------------------------------------------------------------------------

_MUJOCO_BAD_WARNINGS = ("mjWARN_BADQPOS", "mjWARN_BADQVEL", "mjWARN_BADQACC")


def _mujoco_model(
    L: float, d: float, M: float, E: float, n: int, dt: float, integrator: str
) -> tuple[object, int, np.ndarray]:
    """Build the MuJoCo rod model.

    Returns:
        ``(model, tip body id, slide dof ids of the vertex bodies)``.
    """
    import mujoco

    seg = L / (n - 1)
    points = " ".join(f"{i * seg:.17g} 0 0" for i in range(n))
    elements = " ".join(f"{i} {i + 1}" for i in range(n - 1))
    # Edge-length constraints use the stiffest time constant MuJoCo accepts
    # (2 dt, critically damped); the default 0.02 s lets a hanging soft rod
    # stretch by >10 % per edge.
    # flexcomp gives every point mass/npoint (pinned points included): ask for
    # M/(n-1) per point, the lumped mass of an interior node; the tip node is
    # halved below so that the free nodes carry the lumped-mass distribution.
    xml = f"""
<mujoco model="cantilever">
  <option timestep="{dt:.17g}" integrator="{integrator}" gravity="0 0 0"/>
  <worldbody>
    <flexcomp name="rod" type="direct" dim="1" point="{points}" element="{elements}"
              radius="{d / 2:.17g}" mass="{M * n / (n - 1):.17g}">
      <edge equality="true" solref="{2.0 * dt:.17g} 1"/>
      <elasticity young="{E:.17g}" poisson="{POISSON}"/>
      <contact contype="0" conaffinity="0"/>
      <pin id="0 1"/>
    </flexcomp>
  </worldbody>
</mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    tip = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"rod_{n - 1}")
    model.body_mass[tip] = M / (2.0 * (n - 1))
    mujoco.mj_setConst(model, mujoco.MjData(model))
    slide = mujoco.mjtJoint.mjJNT_SLIDE
    dofs = np.array(
        [model.jnt_dofadr[j] for j in range(model.njnt) if model.jnt_type[j] == slide], dtype=int
    )
    return model, tip, dofs


def run_mujoco(
    L: float,
    d: float,
    M: float,
    E: float,
    n: int,
    dt: float,
    mode: str,
    duration: float,
    damping: float | None = None,
    *,
    integrator: str = "discrete",
) -> PeerResult:
    """Run the cantilever benchmark with MuJoCo (>= 4.0) 1-D flexcomp rod.

    MuJoCo 4.0 removed the ``elasticity.cable`` plugin; its replacement is a
    ``<flexcomp dim="1">`` with ``<elasticity young=...>``, a discrete elastic
    rod (bending + torsion, no stretching).  Mapping:

    * ``n`` points at ``i L / (n - 1)`` along +x (``type="direct"``), one
      capsule element per segment, ``radius = d / 2`` so that the circle
      section has ``I = pi r^4 / 4 = pi d^4 / 64`` and ``J = 2 I``;
    * ``young = E``, ``poisson = 0.3`` (torsion ``G = E / 2.6``);
      vertex bending stiffness ``E I / (l0 + l1)`` is MuJoCo's own;
    * stretching is not part of MuJoCo's rod elasticity: edges are held at
      their length by ``<edge equality="true"/>``, soft constraints with
      ``solref = "2 dt 1"`` (the stiffest time constant MuJoCo allows; the
      default 0.02 s lets a hanging soft rod stretch by >10 % per edge);
    * mass: lumped, ``M / (n - 1)`` per vertex body and half of that at the
      tip (flexcomp would give ``M / n`` to every point, pinned ones
      included);
    * clamp: ``<pin id="0 1"/>``, which clamps the first edge and its
      material frame (MuJoCo's natural clamp);
    * damping: ``dof_damping = c * m`` on each vertex slide joint (uniform
      velocity damping rate ``c`` [1/s]); no twist damping;
    * contacts off, gravity set at run time.

    Args:
        L: length [m].
        d: diameter [m].
        M: total mass [kg].
        E: Young's modulus [Pa].
        n: number of nodes (``n - 1`` edges).
        dt: time step [s], written into the model's ``timestep``.
        mode: ``"static"`` or ``"free"`` (see the module docstring).
        duration: simulated time of the timed run [s] (static: whole run;
            free: the free phase, after an untimed settling phase of
            ``15 / omega_1`` seconds).
        damping: uniform velocity damping rate [1/s].  None: ``2 omega_1`` in
            the static mode (and always in the settling phase), 0 in the free
            phase.
        integrator: MuJoCo integrator: ``"discrete"`` (implicit velocity
            stepping, MuJoCo's recommended integrator for rods),
            ``"RK4"`` or ``"Euler"`` (explicit in the rod elasticity).
            ``implicit``/``implicitfast`` do not support 1-D rod elasticity in
            MuJoCo 4.0.

    Returns:
        The :class:`PeerResult`.  ``stable`` is False if any state became
        non-finite or MuJoCo raised a bad qpos/qvel/qacc warning (after which
        it silently resets the state to its start).
    """
    _check_args(n, dt, mode, duration)
    import mujoco

    model, tip, dofs = _mujoco_model(L, d, M, E, n, dt, integrator)
    data = mujoco.MjData(model)
    mass = np.array([model.body_mass[model.dof_bodyid[k]] for k in dofs])
    omega1 = _omega1(L, d, M, E)
    c_settle = 2.0 * omega1
    bad = [int(getattr(mujoco.mjtWarning, w)) for w in _MUJOCO_BAD_WARNINGS]

    def set_damping(c: float) -> None:
        model.dof_damping[dofs] = c * mass

    seg = L / (n - 1)

    def diverged() -> bool:
        return (
            any(data.warning[w].number > 0 for w in bad)
            or not np.isfinite(data.qvel).all()
            or not _segments_ok(data.flexvert_xpos.T, seg)
        )

    def run(steps: int, trace: np.ndarray | None) -> tuple[bool, float]:
        """Step ``steps`` times, recording tip z in ``trace``; return
        (stable, wall time)."""
        check = max(1, min(steps, 100))
        start = time.perf_counter()
        for k in range(steps):
            mujoco.mj_step(model, data)
            if trace is not None:
                trace[k] = data.xpos[tip, 2]
            if (k + 1) % check == 0 or k + 1 == steps:
                if diverged():
                    return False, time.perf_counter() - start
        return True, time.perf_counter() - start

    base_note = (
        f"integrator={integrator}; flexcomp dim=1 direct, {n} points, radius=d/2, "
        f"young=E, poisson={POISSON}, edge equality (soft, solref "
        f"{model.eq_solref[0][0]:.3g} {model.eq_solref[0][1]:.3g}), lumped mass M/(n-1) "
        f"per free vertex and half at the tip, pin id='0 1'"
    )

    if mode == "static":
        c = c_settle if damping is None else float(damping)
        model.opt.gravity[:] = (0.0, 0.0, -GRAVITY)
        set_damping(c)
        steps = int(round(duration / dt))
        stable, wall = run(steps, None)
        mujoco.mj_forward(model, data)
        tip_z = float(data.xpos[tip, 2])
        vel = float(np.abs(data.qvel[dofs]).max())
        note = base_note + (
            f"; dof damping c*m, c={c:.6g} 1/s; final max |vertex v|={vel:.3g} m/s"
            f"; final max edge strain {_max_strain(data.flexvert_xpos.T, seg):.3g}"
        )
        return PeerResult(
            "mujoco", mode, n, dt, stable, -tip_z if stable else None, None, None, wall,
            steps * dt, note,
        )

    # free mode: settle under small gravity with damping, then release
    settle_steps = int(math.ceil(SETTLE_OMEGA_T / omega1 / dt))
    g_small = _free_gravity(L, d, M, E)
    model.opt.gravity[:] = (0.0, 0.0, -g_small)
    set_damping(c_settle)
    stable, _ = run(settle_steps, None)
    note = base_note + (
        f"; settled {settle_steps * dt:.4g} s (untimed) with c={c_settle:.6g} 1/s "
        f"under g={g_small:.6g} m/s^2"
    )
    if not stable:
        return PeerResult("mujoco", mode, n, dt, False, None, None, None, 0.0, 0.0, note)
    model.opt.gravity[:] = 0.0
    c = 0.0 if damping is None else float(damping)
    set_damping(c)
    note += f"; free phase dof damping c={c:.6g} 1/s"
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)
    z0 = float(data.xpos[tip, 2])
    steps = int(round(duration / dt))
    trace = np.empty(steps + 1)
    trace[0] = z0
    stable, wall = run(steps, trace[1:])
    t = np.arange(steps + 1) * dt
    return _free_result("mujoco", n, dt, stable, t, trace, z0, wall, steps * dt, note)
