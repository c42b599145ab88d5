"""Peer simulators (PyElastica, MuJoCo, Newton) on the cantilever benchmark (S1 and S2), timed fairly.

The benchmark: a straight horizontal rod (a :class:`CableSpec`: length L, diameter d, mass M,
Young's modulus E, Poisson ratio 0.3, ``n_masses`` nodes), first end clamped at the origin
with its tangent along +x, last end free, gravity along -z. Each peer runs it in two modes:

``"static"`` (S1)
    Gravity 9.81 m/s^2 with velocity damping for ``duration`` seconds; the result is the
    downward tip deflection, against delta = w L^4 / (8 E I).
``"free"`` (S2)
    The rod settles (damped, untimed) under the reduced gravity for which the closed form
    gives a tip deflection of 1e-3 L, close to its first mode shape; then gravity and damping
    go off, velocities are zeroed and the rod swings freely for ``duration`` seconds. The result
    is the first frequency from the tip's upward zero crossings, against f1, and the amplitude
    kept over the last full period.

Each peer gets its best public set-up (see :mod:`~bullet_dlo.bench.peer_mujoco`,
:mod:`~bullet_dlo.bench.peer_pyelastica` and :mod:`~bullet_dlo.bench.peer_newton`): a true clamp
at x = 0 (a held stub element behind the origin: MuJoCo's ``pin`` of the stub's two points,
PyElastica's ``FixedConstraint`` of the stub's nodes and directors, Newton's kinematic stub body),
its recommended integrator (MuJoCo ``discrete``, PyElastica ``PositionVerlet``, Newton
``SolverVBD``), the same masses and the same velocity damping as ours, and no Python per step that
the measure does not need. All three then converge at second order on S1 (+0.29 % / +0.30 % /
+0.25 % at n = 20; Newton in its n - 1 segments, at 2e-5 s). Holding the whole first rod element instead (these adapters
before issue 24) clamps the beam one element in: an S1 error of about -2/n.

Damping is a uniform velocity damping *rate* c [1/s] (a force -c m v): c = 2 omega1 critically
damps the first mode; that is the default of the static mode and of the settling phase; the
free phase is undamped.

Timing (:func:`bench_peers`): CPU time of the measuring thread (``time.thread_time``), which a
shared machine does not inflate the way it inflates wall time. Each peer's cheapest run within
1 % (from its sweep) and our cheapest run within 1 % are then re-run in interleaved pairs (the
order alternating), and the ratio peer / ours is reported as a median with its range, next to
the machine's load (``os.getloadavg``) before and after.

Each peer is an adapter with the few operations :func:`run_peer` needs; the phases, the stepping
loop and the checks are here, once. MuJoCo's warnings are captured into
:attr:`PeerResult.warnings`, never printed nor logged to a file in the working directory.
"""
from __future__ import annotations

import datetime
import json
import math
import os
import platform
import statistics
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Protocol, Sequence

import numpy as np

from bullet_dlo.analysis.closed_forms import (
    GRAVITY,
    cantilever_angular_frequency,
    cantilever_deflection,
    cantilever_frequency,
    cantilever_model,
    cantilever_release,
    release_gravity,
)
from bullet_dlo.analysis.measures import amplitude_kept, period_amplitude, relative_error, zero_crossing_frequency
from bullet_dlo.core.spec import CableSpec

__all__ = ["PeerResult", "PeerRod", "PeerCase", "PeerConfig", "available", "versions", "run_peer", "run_pyelastica",
           "run_mujoco", "run_newton", "newton_options", "peer_cases", "convergence_order", "bench_peers", "POISSON", "GRAVITY"]

POISSON = 0.3
"""Poisson ratio of the benchmark [-]."""

FREE_AMPLITUDE = 1e-3
"""Initial tip amplitude of the free mode, as a fraction of L (closed form)."""

SETTLE_OMEGA_T = 15.0
"""Length of the damped settling phase of the free mode, in units of 1/omega1."""

MAX_STRAIN = 0.05
"""Largest segment strain [-] accepted before a run is declared diverged (the benchmark's
physical strains are below 1e-4; an exploding explicit run stretches its segments far more)."""

GROWTH_LIMIT = 2.0
"""Free mode: a tip excursion beyond this multiple of the initial one means the undamped,
unforced run gained energy, i.e. is numerically unstable."""

CHECK_EVERY = 100
"""Steps between two divergence checks."""

TOL = 0.01
"""Equal accuracy: 1 % relative error."""

TOLS = (TOL, 0.001)
"""The accuracies compared (``--quick``: 1 % only)."""


@dataclass
class PeerResult:
    """One benchmark run of a peer simulator.

    Attributes:
        peer: ``"pyelastica"``, ``"mujoco"`` or ``"newton"``; mode: ``"static"`` or ``"free"``.
        n: number of nodes; dt: time step [s].
        stable: False if the run diverged: non-finite state, a segment strain above
            :data:`MAX_STRAIN`, a peer's own divergence signal (MuJoCo's bad qpos/qvel/qacc
            warnings, after which it silently resets the state), or in the free mode a tip
            excursion above :data:`GROWTH_LIMIT` times the initial one.
        tip_deflection: static mode: downward tip deflection at the end [m].
        frequency: free mode: first bending frequency [Hz].
        amplitude_kept: free mode: amplitude over the last full period / initial tip displacement [-].
        wall_time_s: wall-clock time of the timed phase [s] (not model building nor settling).
        sim_time_s: simulated time of the timed phase [s].
        note: parameter mapping, settling and checks, in words.
        warnings: messages the peer raised during the run (MuJoCo), in order.
        cpu_time_s: CPU time of the measuring thread in the timed phase [s].
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
    warnings: list[str] = field(default_factory=list)
    cpu_time_s: float = 0.0


class PeerRod(Protocol):
    """What :func:`run_peer` asks of a peer's rod (clamped at the origin along +x, at rest)."""

    name: str
    integrator: str
    note: str
    warnings: list[str]

    def set_gravity(self, g: float) -> None:
        """Gravity g [m/s^2] along -z."""

    def set_damping(self, rate: float) -> None:
        """Uniform velocity damping rate [1/s]."""

    def advance(self, k: int, trace: np.ndarray | None = None) -> None:
        """Advance k time steps; with ``trace`` (k,), write the tip height [m] after each step."""

    def refresh(self) -> None:
        """Bring derived positions up to date with the state (before reading a result)."""

    def zero_velocities(self) -> None:
        """Stop every node (and rotation)."""

    def positions(self) -> np.ndarray:
        """Node positions (3, n) [m] of the rod on [0, L] (a held stub behind the clamp left out)."""

    def tip_z(self) -> float:
        """Height of the free end [m]."""

    def diverged(self) -> bool:
        """The peer's own divergence signal (besides non-finite values and strain)."""


PEER_MODULES = {"pyelastica": "elastica", "mujoco": "mujoco", "newton": "newton"}


def available() -> dict[str, bool]:
    """Which peer simulators can be imported: ``{"pyelastica": bool, "mujoco": bool, "newton": bool}``."""
    out = {}
    for peer, module in PEER_MODULES.items():
        try:
            __import__(module)
            out[peer] = True
        except Exception:
            out[peer] = False
    return out


def versions() -> dict[str, str | None]:
    """Installed versions of the peers (and of Warp, Newton's kernel language); None: not installed."""
    from importlib.metadata import PackageNotFoundError, version

    out: dict[str, str | None] = {}
    for name, dist in (("mujoco", "mujoco"), ("pyelastica", "pyelastica"), ("newton", "newton"), ("warp", "warp-lang")):
        try:
            out[name] = version(dist)
        except PackageNotFoundError:
            out[name] = None
    return out


def max_strain(pos: np.ndarray, rest_length: float) -> float:
    """Largest |segment length / rest length - 1| [-] of the polyline ``pos`` (3, n) [m]."""
    lengths = np.sqrt((np.diff(pos, axis=1) ** 2).sum(axis=0))
    return float(np.abs(lengths / rest_length - 1.0).max())


def _intact(rod: PeerRod, rest_length: float) -> bool:
    pos = rod.positions()
    return bool(np.isfinite(pos).all()) and max_strain(pos, rest_length) < MAX_STRAIN and not rod.diverged()


def _advance(rod: PeerRod, n_steps: int, rest_length: float,
             trace: np.ndarray | None = None) -> tuple[bool, float, float]:
    """Step ``n_steps`` times in chunks of :data:`CHECK_EVERY` steps, writing the tip height into
    ``trace`` (n_steps,) [m] if given, checking divergence after each chunk; returns
    (stable, thread CPU time [s], wall time [s])."""
    cpu0, wall0 = time.thread_time(), time.perf_counter()
    done = 0
    while done < n_steps:
        k = min(CHECK_EVERY, n_steps - done)
        rod.advance(k, None if trace is None else trace[done:done + k])
        done += k
        if not _intact(rod, rest_length):
            return False, time.thread_time() - cpu0, time.perf_counter() - wall0
    return True, time.thread_time() - cpu0, time.perf_counter() - wall0


def run_peer(rod: PeerRod, spec: CableSpec, dt: float, mode: str, duration: float,
             damping: float | None = None, settle: float | None = None) -> PeerResult:
    """Run one mode of the benchmark (see the module doc) on ``rod`` built from ``spec`` at ``dt`` [s].

    duration: simulated time of the timed phase [s]; damping: velocity damping rate of that phase
    [1/s] (None: 2 omega1 in the static mode, 0 in the free phase); settle: free mode only, the
    settling time [s] (None: :data:`SETTLE_OMEGA_T` / omega1; shorter only for timing an explicit
    peer, whose cost per step does not depend on the state: the growth check is then skipped).
    """
    if mode not in ("static", "free"):
        raise ValueError(f"mode must be 'static' or 'free', got {mode!r}")
    if not dt > 0.0 or not duration > 0.0:
        raise ValueError("dt and duration must be positive")
    if spec.n_masses < 4:
        raise ValueError(f"need at least 4 nodes, got n_masses = {spec.n_masses}")
    n_steps = int(round(duration / dt))
    if mode == "static":
        stable, cpu, wall, note, measured = _static(rod, spec, dt, n_steps, damping)
    else:
        stable, cpu, wall, note, measured = _free(rod, spec, dt, n_steps, damping, settle)
    return PeerResult(rod.name, mode, spec.n_masses, dt, stable, measured.get("tip_deflection"),
                      measured.get("frequency"), measured.get("amplitude_kept"), wall, n_steps * dt, note,
                      list(rod.warnings), cpu)


def _static(rod: PeerRod, spec: CableSpec, dt: float, n_steps: int, damping: float | None):
    """S1: damped under gravity; measures the tip deflection [m]. Returns (stable, cpu [s], wall [s], note, measures)."""
    c = 2.0 * cantilever_angular_frequency(spec) if damping is None else float(damping)
    rod.set_gravity(GRAVITY)
    rod.set_damping(c)
    stable, cpu, wall = _advance(rod, n_steps, spec.rest_length)
    rod.refresh()
    note = f"{rod.note}; damping rate {c:.6g} 1/s; final max strain {max_strain(rod.positions(), spec.rest_length):.3g}"
    return stable, cpu, wall, note, {"tip_deflection": -rod.tip_z()} if stable else {}


def _free(rod: PeerRod, spec: CableSpec, dt: float, n_steps: int, damping: float | None, settle: float | None):
    """S2: settle (untimed) under the release gravity, then swing free; measures the frequency [Hz]
    and the amplitude kept [-]. Returns (stable, cpu [s], wall [s], note, measures)."""
    omega1 = cantilever_angular_frequency(spec)
    g_small = release_gravity(spec, FREE_AMPLITUDE)
    settle_time = SETTLE_OMEGA_T / omega1 if settle is None else settle
    settle_steps = max(1, int(math.ceil(settle_time / dt)))
    rod.set_gravity(g_small)
    rod.set_damping(2.0 * omega1)
    stable, _, _ = _advance(rod, settle_steps, spec.rest_length)
    note = (f"{rod.note}; settled {settle_steps * dt:.4g} s (untimed) at {2.0 * omega1:.6g} 1/s "
            f"under g = {g_small:.6g} m/s^2")
    if not stable:
        return False, 0.0, 0.0, note, {}
    c = 0.0 if damping is None else float(damping)
    rod.set_gravity(0.0)
    rod.set_damping(c)
    rod.zero_velocities()
    rod.refresh()
    z = np.empty(n_steps + 1)  # tip height = displacement (the clamp is at z = 0)
    z[0] = rod.tip_z()
    stable, cpu, wall = _advance(rod, n_steps, spec.rest_length, z[1:])
    note += f"; free phase damping rate {c:.6g} 1/s; initial tip displacement {z[0]:.6g} m"
    if settle is not None:
        return stable, cpu, wall, note + "; short settle (timing run): no growth check, no measures", {}
    growth = np.abs(z).max() / abs(z[0])
    if stable and growth > GROWTH_LIMIT:
        stable = False
        note += f"; tip excursion grew to {growth:.3g} x the initial one: numerical instability (energy gain)"
    if not stable:
        return False, cpu, wall, note, {}
    t = np.arange(n_steps + 1) * dt
    freq = zero_crossing_frequency(t, z)
    if math.isnan(freq):
        return True, cpu, wall, note + "; fewer than two upward zero crossings: run longer", {}
    note += f"; first-period amplitude / initial = {period_amplitude(t, z, 0) / abs(z[0]):.6f}"
    return True, cpu, wall, note, {"frequency": freq, "amplitude_kept": amplitude_kept(t, z)}


def run_pyelastica(spec: CableSpec, dt: float, mode: str, duration: float, damping: float | None = None,
                   settle: float | None = None) -> PeerResult:
    """The benchmark with PyElastica (Cosserat rod, PositionVerlet); see :mod:`bullet_dlo.bench.peer_pyelastica`."""
    from bullet_dlo.bench.peer_pyelastica import PyElasticaRod

    return run_peer(PyElasticaRod(spec, dt), spec, dt, mode, duration, damping, settle)


def run_mujoco(spec: CableSpec, dt: float, mode: str, duration: float, damping: float | None = None, *,
               integrator: str = "discrete", settle: float | None = None) -> PeerResult:
    """The benchmark with a MuJoCo rod: a 1-D flexcomp (``integrator`` ``"discrete"``, ``"RK4"``, ``"Euler"``) or a
    joint chain (``"discrete chain"``, ...); see :mod:`bullet_dlo.bench.peer_mujoco`.

    MuJoCo's warnings during the run are captured into the result (not printed, no log file).
    """
    from bullet_dlo.bench.peer_mujoco import mujoco_rod

    with mujoco_rod(spec, dt, integrator) as rod:
        return run_peer(rod, spec, dt, mode, duration, damping, settle)


def newton_options(integrator: str) -> tuple[int, float]:
    """(VBD iterations, stretch and shear scale) from a Newton integrator label: ``"VBD10"`` or
    ``"VBD10 shear x0.03"`` (see :mod:`bullet_dlo.bench.peer_newton`)."""
    head, _, scale = integrator.partition(" shear x")
    if not head.startswith("VBD"):
        raise ValueError(f"Newton integrator must read 'VBD<iterations>[ shear x<scale>]', got {integrator!r}")
    return int(head[3:]), (float(scale) if scale else 1.0)


def run_newton(spec: CableSpec, dt: float, mode: str, duration: float, damping: float | None = None, *,
               integrator: str = "VBD10", settle: float | None = None) -> PeerResult:
    """The benchmark with Newton's rod (``add_rod``, ``SolverVBD`` on the CPU); see :mod:`bullet_dlo.bench.peer_newton`."""
    from bullet_dlo.bench.peer_newton import NewtonRod

    iterations, shear_scale = newton_options(integrator)
    return run_peer(NewtonRod(spec, dt, iterations, shear_scale), spec, dt, mode, duration, damping, settle)


def convergence_order(errors: Sequence[float], n_masses: Sequence[int]) -> list[float]:
    """Observed orders p of error ~ n^-p between successive node counts (error ratios of |errors|)."""
    return [math.log(abs(errors[i]) / abs(errors[i + 1])) / math.log(n_masses[i + 1] / n_masses[i])
            for i in range(len(errors) - 1)]


# ----- the peer sweep ----------------------------------------------------------------------------
N_GRID = (10, 12, 16, 20, 40)
"""Node counts of the sweep, ours and the peers' (the cheapest run within 1 % lies between 10 and 20 for several)."""


@dataclass(frozen=True)
class PeerConfig:
    """A peer, its integrator, the time steps [s] and node counts to sweep (full and --quick)."""

    peer: str
    integrator: str
    dts: tuple[float, ...]
    n_masses: tuple[int, ...]
    quick_dts: tuple[float, ...] = ()
    quick_n_masses: tuple[int, ...] = ()
    quick_scenarios: tuple[str, ...] = ("S1", "S2")
    scenarios: dict[str, tuple[tuple[float, ...], tuple[int, ...]]] = field(default_factory=dict)
    """Per scenario, (time steps, node counts) that replace the full sweep's (an empty one: not run)."""


PEER_CONFIGS = (
    # MuJoCo's joint chain (ball joints with stiffness), implicit in the joint springs: its cheapest set-up
    PeerConfig("mujoco", "discrete chain", (1 / 60, 1 / 240, 1e-3, 5e-4, 2e-4, 1e-4), N_GRID, (1 / 60, 5e-4),
               (12, 20)),
    # the chain with MuJoCo's default implicit integrator, explicit in the joint springs: small steps only
    PeerConfig("mujoco", "implicitfast chain", (1e-4, 2e-5), (12, 20), (2e-5,), (12,), ("S2",)),
    # MuJoCo's recommended (implicit) integrator for flex elasticity, at our own time steps and below
    PeerConfig("mujoco", "discrete", (1 / 60, 1 / 240, 1e-3, 5e-4, 2e-4, 1e-4), N_GRID + (80,), (1 / 60, 1e-3),
               (10, 20)),
    # explicit RK4: near and below its stability limit for this stiff rod
    PeerConfig("mujoco", "RK4", (1e-4, 1e-5), (10, 20), (1e-4,), (10, 20)),
    # PositionVerlet: stable up to ~5e-7 s for this stiff rod whatever n; 7e-7 s shows the limit
    PeerConfig("pyelastica", "PositionVerlet", (7e-7, 5e-7), N_GRID, (5e-7,), (10,), ("S1",)),
    # Newton's VBD (10 sweeps, its default) with stretch and shear at 0.03 of the material's: the bias of
    # its fixed sweep count shrinks like dt^2, so it needs 1e-5-2e-5 s (see peer_newton)
    PeerConfig("newton", "VBD10 shear x0.03", (1e-4, 2e-5, 1e-5), (5, 10, 20), (4e-5,), (4, 8), ("S1",),
               scenarios={"S2": ((1e-4, 2e-5), (10, 20))}),
    # the material's stretch and shear, as add_rod derives them: the bias of a stiff rod (S1 only)
    PeerConfig("newton", "VBD10", (1e-4, 2e-5), (10,), scenarios={"S2": ((), ())}),
)
"""What :func:`bench_peers` sweeps, per peer and integrator."""

SCENARIO_MODES = {"S1": "static", "S2": "free"}

DURATIONS = {("mujoco", "S1"): 1.0, ("pyelastica", "S1"): 0.06, ("newton", "S1"): 0.066,
             ("mujoco", "S2"): 0.15, ("pyelastica", "S2"): 0.15, ("newton", "S2"): 0.15}
"""Simulated time [s] of a sweep run: S1 settles as long as ours (1 s; PyElastica 0.06 s, 13.6 / omega1,
which leaves < 1e-4 of the transient at 2 million steps per second; Newton 0.066 s, 15 / omega1);
S2's free phase is about 5 periods."""

TIMING_DURATION = {"S1": 10.0, "S2": 1.0}
"""Simulated time [s] of a timing run (ours and the peer); a peer's timing run is cut to
:data:`TIMING_MAX_STEPS` steps (the cost per simulated second is what is compared)."""

TIMING_MAX_STEPS = 20_000

TIMING_MAX_STEPS_PEER = {"newton": 2_000}
"""A lower cap for a peer whose steps cost milliseconds (Newton's VBD on the CPU: a fixed sweep count, so
the cost per step does not depend on the state or the run's length)."""

EXPLICIT = {"RK4", "Euler", "PositionVerlet"}
"""Integrators whose work per step does not depend on the state: their S2 timing runs settle only briefly."""


@dataclass(frozen=True)
class PeerCase:
    """One peer run of the sweep: peer, its integrator, dt [s], number of nodes n, scenario S1 or S2."""

    peer: str
    integrator: str
    dt: float
    n: int
    scenario: str

    def result(self, spec: CableSpec, duration: float | None = None, settle: float | None = None) -> PeerResult:
        """Run on ``spec`` with n nodes (duration: the timed phase [s], default :data:`DURATIONS`)."""
        spec = spec.with_(n_masses=self.n)
        mode = SCENARIO_MODES[self.scenario]
        duration = DURATIONS[self.peer, self.scenario] if duration is None else duration
        if self.peer == "mujoco":
            return run_mujoco(spec, self.dt, mode, duration, integrator=self.integrator, settle=settle)
        if self.peer == "newton":
            return run_newton(spec, self.dt, mode, duration, integrator=self.integrator, settle=settle)
        return run_pyelastica(spec, self.dt, mode, duration, settle=settle)

    def run(self, spec: CableSpec) -> tuple[dict, list[str]]:
        """Run on ``spec`` with n nodes: (JSON-ready point with the error against the closed form, warnings)."""
        res = self.result(spec)
        spec = spec.with_(n_masses=self.n)
        err = None
        if res.stable and res.tip_deflection is not None:
            err = relative_error(res.tip_deflection, cantilever_deflection(spec))
        if res.stable and res.frequency is not None:
            err = relative_error(res.frequency, cantilever_frequency(spec))
        signed = None
        if res.stable and res.tip_deflection is not None:
            signed = res.tip_deflection / cantilever_deflection(spec) - 1.0
        if res.stable and res.frequency is not None:
            signed = res.frequency / cantilever_frequency(spec) - 1.0
        sim = max(res.sim_time_s, 1e-12)
        point = dict(label=f"{self.peer} ({self.integrator})", peer=self.peer, integrator=self.integrator,
                     scenario=self.scenario, n=self.n, dt=self.dt, stable=res.stable, error=err, signed_error=signed,
                     cpu_per_sim_s=res.cpu_time_s / sim, wall_per_sim_s=res.wall_time_s / sim,
                     amplitude_kept=res.amplitude_kept, warnings=len(res.warnings), note=res.note)
        return point, res.warnings


def peer_cases(available_peers: dict[str, bool], quick: bool = False,
               configs: Sequence[PeerConfig] | None = None) -> list[PeerCase]:
    """Every configuration of ``configs`` (default :data:`PEER_CONFIGS`) whose peer is available, on S1
    and S2 (--quick: fewer)."""
    cases = []
    for c in PEER_CONFIGS if configs is None else configs:
        if not available_peers.get(c.peer):
            continue
        for sc in (c.quick_scenarios if quick else tuple(SCENARIO_MODES)):
            dts, ns = (c.quick_dts, c.quick_n_masses) if quick else c.scenarios.get(sc, (c.dts, c.n_masses))
            cases += [PeerCase(c.peer, c.integrator, dt, n, sc) for dt in dts for n in ns]
    return cases


# ----- interleaved timing ------------------------------------------------------------------------
def _ours_cpu_per_sim_s(scenario: str, integrator: str, n: int, dt: float, duration: float) -> float:
    """Thread CPU time per simulated second [s] of our run (the whole ``simulate`` call, its set-up
    included; S2 records every step, as the peer's trace does)."""
    from bullet_dlo.bench.scenarios import s1_spec
    from bullet_dlo.core.engine import simulate

    steps = max(1, int(round(duration / dt)))
    if scenario == "S1":
        model, state, records = cantilever_model(s1_spec(n)), None, 3
    else:
        model, state = cantilever_release(s1_spec(n).with_(damping=0.0, damping_rate=0.0), FREE_AMPLITUDE)
        records = steps + 1
    cpu0 = time.thread_time()
    res = simulate(model, integrator, dt, duration, state=state, max_records=records)
    cpu = time.thread_time() - cpu0
    if not res.stable:
        raise RuntimeError(f"our timing run went unstable: {scenario} {integrator} n={n} dt={dt}")
    return cpu / (steps * dt)


def _peer_cpu_per_sim_s(case: PeerCase, spec: CableSpec) -> float:
    """Thread CPU time per simulated second [s] of the peer's timed phase (model building and
    settling not counted)."""
    duration = min(TIMING_DURATION[case.scenario], TIMING_MAX_STEPS_PEER.get(case.peer, TIMING_MAX_STEPS) * case.dt)
    fixed_work = case.integrator in EXPLICIT or case.peer == "newton"  # VBD: a fixed sweep count per step
    settle = 2000 * case.dt if (case.scenario == "S2" and fixed_work) else None
    res = case.result(spec, duration, settle)
    if not (res.stable or settle is not None) or res.cpu_time_s <= 0.0:
        raise RuntimeError(f"the peer's timing run went unstable: {case}")
    return res.cpu_time_s / res.sim_time_s


def interleaved_ratio(ours: dict, case: PeerCase, spec: CableSpec, reps: int) -> dict:
    """``reps`` interleaved pairs (ours, the peer; the order alternating) of timing runs; the ratio
    peer / ours of thread CPU per simulated second: median and range, and each side's median."""
    a, b = [], []
    for k in range(reps):
        order = (0, 1) if k % 2 == 0 else (1, 0)
        for side in order:
            if side == 0:
                a.append(_ours_cpu_per_sim_s(ours["scenario"], ours["integrator"], ours["n"], ours["dt"],
                                             TIMING_DURATION[ours["scenario"]]))
            else:
                b.append(_peer_cpu_per_sim_s(case, spec))
    ratios = [y / x for x, y in zip(a, b)]
    return dict(reps=reps, ratio_median=statistics.median(ratios), ratio_min=min(ratios), ratio_max=max(ratios),
                ours_cpu_per_sim_s=statistics.median(a), peer_cpu_per_sim_s=statistics.median(b))


# ----- the benchmark -----------------------------------------------------------------------------
Progress = Callable[[str], Callable[[Sequence], Iterable]]


def _no_progress(desc: str) -> Callable[[Sequence], Iterable]:
    return lambda items: items


def bench_peers(out: Path, quick: bool = False, progress: Progress = _no_progress, reps: int | None = None) -> dict:
    """``bullet-dlo bench peers``: the peers' sweeps, ours, and the interleaved CPU-time ratios at 1 %.

    Prints a table and the ratios; writes ``peers.json`` and ``peers_warnings.log`` (MuJoCo's
    warnings, counted per point) into ``out``. Returns what ``peers.json`` holds.
    """
    from bullet_dlo.bench import sweeps
    from bullet_dlo.bench.scenarios import s1_spec

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    reps = reps or (3 if quick else 7)
    load_start = os.getloadavg()
    peers_ok = available()
    vers = versions()
    print("peers available:", peers_ok, "versions:", vers)
    if not peers_ok["newton"]:
        print("Newton is not installed (pip install newton warp-lang): not benchmarked")
    else:
        print("Newton runs on Warp's CPU device (SolverVBD; no GPU is used here, even when one is present)")
    spec = s1_spec(10)  # the stiff cantilever of S1/S2: tip deflects 1e-3 L, f1 = 36 Hz
    points, log = [], []
    cases = peer_cases(peers_ok, quick)
    for case in progress("peers")(cases):
        point, warnings = case.run(spec)
        points.append(point)
        log += [f"{case.peer} {case.integrator} {case.scenario} n={case.n} dt={case.dt:g}: {w}" for w in warnings]
    (out / "peers_warnings.log").write_text("".join(line + "\n" for line in log))
    for p in points:
        err = "-" if p["signed_error"] is None else f"{100 * p['signed_error']:+.3f} %"
        kept = "-" if p["amplitude_kept"] is None else f"{p['amplitude_kept']:.3f}"
        print(f"  {p['peer']:10s} {p['integrator']:14s} {p['scenario']} n={p['n']:3d} dt={p['dt']:.3g} "
              f"stable={p['stable']!s:5s} error={err:10s} amplitude kept={kept:6s} "
              f"cpu={p['cpu_per_sim_s']:.4g} s/s" + (f" (MuJoCo warnings: {p['warnings']})" if p["warnings"] else ""))
    if log:
        print(f"{len(log)} peer warnings -> {out / 'peers_warnings.log'}")
    for c in PEER_CONFIGS:
        for dt in (c.quick_dts if quick else c.dts):
            s1 = [p for p in points if p["peer"] == c.peer and p["integrator"] == c.integrator and p["dt"] == dt
                  and p["scenario"] == "S1" and p["stable"] and p["signed_error"]]
            if len(s1) >= 2:
                # Newton's rod has n - 1 segment bodies: its error goes as (n - 1)^-2
                shift, unit = (1, "n - 1 segments") if c.peer == "newton" else (0, "n")
                orders = convergence_order([p["signed_error"] for p in s1], [p["n"] - shift for p in s1])
                print(f"  S1 order in {unit}, {c.peer} {c.integrator} dt={dt:.3g}: "
                      + ", ".join(f"{p:.2f}" for p in orders))

    ours_n, ours_dts = ((12, 20), (1 / 60, 1e-3)) if quick else (N_GRID, (1 / 60, 1 / 240, 1e-3))
    ours_cases = [sweeps.Case(sc, "core", name, n, dt) for sc in ("S1", "S2") for n in ours_n
                  for name in ("implicit_euler", "bdf2", "implicit_midpoint") for dt in ours_dts]
    gl_dts = (5e-3,) if quick else (1 / 60, 1 / 160, 5e-3, 1 / 240, 3e-3)  # 4th order: S2 at 1 % near 6 ms
    ours_cases += [sweeps.Case(sc, "core", "gauss_legendre", n, dt) for sc in ("S1", "S2") for n in ours_n
                   for dt in gl_dts]
    rows = sweeps.work_precision(ours_cases, progress("ours"))
    tols = (TOL,) if quick else TOLS
    ours = {(sc, tol): sweeps.fastest(rows, sc, tol) for tol in tols for sc in ("S1", "S2")}
    for (sc, tol), best in ours.items():
        if best:
            print(f"ours {sc} at {tol:.1%}: {best.integrator} n={best.n} dt={best.dt:.3g}: error {best.error:.4f}")

    timing = {}
    pairs = []
    for peer in dict.fromkeys(p["peer"] for p in points):
        for (sc, tol), own in ours.items():
            ok = [p for p in points if p["peer"] == peer and p["scenario"] == sc and p["stable"]
                  and p["error"] is not None and p["error"] <= tol]
            if not ok or own is None:
                errors = [p["error"] for p in points if p["peer"] == peer and p["scenario"] == sc and p["error"]]
                best = f"{min(errors):.4f}" if errors else "none stable"
                who = peer if own is not None else "we"
                print(f"equal accuracy ({tol:.1%}) on {sc}: {who} did not reach it in this sweep (best {best})")
                continue
            pairs.append((peer, sc, tol, min(ok, key=lambda p: p["cpu_per_sim_s"]), own))
    for peer, sc, tol, best, own in progress("timing")(pairs):
        case = PeerCase(peer, best["integrator"], best["dt"], best["n"], sc)
        own_d = dict(scenario=sc, integrator=own.integrator, n=own.n, dt=own.dt, error=own.error)
        r = interleaved_ratio(own_d, case, spec, reps)
        key = f"{peer}/{sc}" + ("" if tol == TOL else f"/{tol:.1%}")
        timing[key] = dict(r, tolerance=tol, ours=own_d, peer=dict(integrator=case.integrator, n=case.n, dt=case.dt,
                                                                    error=best["error"]))
        print(f"equal accuracy ({tol:.1%}) on {sc}: {peer} ({case.integrator}, n={case.n}, dt={case.dt:.3g}, "
              f"error {best['error']:.4f}) needs {r['ratio_median']:.3g}x our CPU time "
              f"(range {r['ratio_min']:.3g}-{r['ratio_max']:.3g}, {reps} interleaved pairs; ours {own.integrator} "
              f"n={own.n} dt={own.dt:.3g}: {r['ours_cpu_per_sim_s']:.3g} s/s, peer {r['peer_cpu_per_sim_s']:.3g} s/s)")
    load_end = os.getloadavg()
    print(f"load average (1, 5, 15 min) at start {', '.join(f'{x:.2f}' for x in load_start)}, "
          f"at end {', '.join(f'{x:.2f}' for x in load_end)}; {os.cpu_count()} CPUs")
    closed = {"tip_deflection_m": cantilever_deflection(spec), "frequency_hz": cantilever_frequency(spec)}
    data = {"points": points, "timing": timing, "ratios": {k: v["ratio_median"] for k, v in timing.items()},
            "closed_forms": closed, "warnings": len(log), "versions": vers, "quick": quick,
            "date": datetime.datetime.now().isoformat(timespec="seconds"), "machine": platform.platform(),
            "cpus": os.cpu_count(), "load_start": load_start, "load_end": load_end,
            "ours": {sc + ("" if tol == TOL else f"/{tol:.1%}"): (asdict(v) if v else None)
                     for (sc, tol), v in ours.items()}}
    (out / "peers.json").write_text(json.dumps(data, indent=2, default=float))
    return data
