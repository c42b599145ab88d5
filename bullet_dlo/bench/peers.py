"""Peer simulators (PyElastica, MuJoCo) on the cantilever benchmark (S1 and S2).

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

Both peers clamp their whole first element (each tool's natural clamp), which moves the
effective clamp about half an element along the rod: it costs roughly 2/n of the static tip
deflection (-21 % at n = 10) and raises the first frequency by roughly 1/n. That is expected.

Damping is a uniform velocity damping *rate* c [1/s] (a force -c m v): c = 2 omega1 critically
damps the first mode; that is the default of the static mode and of the settling phase; the
free phase is undamped.

Each peer is an adapter (:mod:`~bullet_dlo.bench.peer_pyelastica`, :mod:`~bullet_dlo.bench.peer_mujoco`)
with the few operations :func:`run_peer` needs; the phases, the stepping loop and the checks are here,
once. MuJoCo's warnings are captured into :attr:`PeerResult.warnings`, never printed nor logged to
a file in the working directory.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from bullet_dlo.analysis.closed_forms import (
    GRAVITY,
    cantilever_angular_frequency,
    cantilever_deflection,
    cantilever_frequency,
    release_gravity,
)
from bullet_dlo.analysis.measures import amplitude_kept, period_amplitude, relative_error, zero_crossing_frequency
from bullet_dlo.core.spec import CableSpec

__all__ = ["PeerResult", "PeerRod", "PeerCase", "available", "run_peer", "run_pyelastica", "run_mujoco", "peer_cases",
           "equal_accuracy_ratios", "POISSON", "GRAVITY"]

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


@dataclass
class PeerResult:
    """One benchmark run of a peer simulator.

    Attributes:
        peer: ``"pyelastica"`` or ``"mujoco"``; mode: ``"static"`` or ``"free"``.
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


class PeerRod(Protocol):
    """What :func:`run_peer` asks of a peer's rod (clamped at the origin along +x, at rest)."""

    name: str
    note: str
    warnings: list[str]

    def set_gravity(self, g: float) -> None:
        """Gravity g [m/s^2] along -z."""

    def set_damping(self, rate: float) -> None:
        """Uniform velocity damping rate [1/s]."""

    def step(self) -> None:
        """Advance one time step."""

    def refresh(self) -> None:
        """Bring derived positions up to date with the state (before reading a result)."""

    def zero_velocities(self) -> None:
        """Stop every node (and rotation)."""

    def positions(self) -> np.ndarray:
        """Node positions (3, n) [m]."""

    def tip_z(self) -> float:
        """Height of the free end [m]."""

    def diverged(self) -> bool:
        """The peer's own divergence signal (besides non-finite values and strain)."""


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


def max_strain(pos: np.ndarray, rest_length: float) -> float:
    """Largest |segment length / rest length - 1| [-] of the polyline ``pos`` (3, n) [m]."""
    lengths = np.sqrt((np.diff(pos, axis=1) ** 2).sum(axis=0))
    return float(np.abs(lengths / rest_length - 1.0).max())


def _intact(rod: PeerRod, rest_length: float) -> bool:
    pos = rod.positions()
    return bool(np.isfinite(pos).all()) and max_strain(pos, rest_length) < MAX_STRAIN and not rod.diverged()


def _advance(rod: PeerRod, n_steps: int, rest_length: float, trace: np.ndarray | None = None) -> tuple[bool, float]:
    """Step ``n_steps`` times, writing the tip height into ``trace`` (n_steps,) [m] if given,
    checking divergence every :data:`CHECK_EVERY` steps; returns (stable, wall time [s])."""
    check = max(1, min(n_steps, CHECK_EVERY))
    start = time.perf_counter()
    for k in range(n_steps):
        rod.step()
        if trace is not None:
            trace[k] = rod.tip_z()
        if ((k + 1) % check == 0 or k + 1 == n_steps) and not _intact(rod, rest_length):
            return False, time.perf_counter() - start
    return True, time.perf_counter() - start


def run_peer(rod: PeerRod, spec: CableSpec, dt: float, mode: str, duration: float,
             damping: float | None = None) -> PeerResult:
    """Run one mode of the benchmark (see the module doc) on ``rod`` built from ``spec`` at ``dt`` [s].

    duration: simulated time of the timed phase [s]; damping: velocity damping rate of that phase
    [1/s] (None: 2 omega1 in the static mode, 0 in the free phase).
    """
    if mode not in ("static", "free"):
        raise ValueError(f"mode must be 'static' or 'free', got {mode!r}")
    if not dt > 0.0 or not duration > 0.0:
        raise ValueError("dt and duration must be positive")
    if spec.n_masses < 4:
        raise ValueError(f"need at least 4 nodes, got n_masses = {spec.n_masses}")
    n_steps = int(round(duration / dt))
    run = _static if mode == "static" else _free
    stable, wall, note, measured = run(rod, spec, dt, n_steps, damping)
    return PeerResult(rod.name, mode, spec.n_masses, dt, stable, measured.get("tip_deflection"),
                      measured.get("frequency"), measured.get("amplitude_kept"), wall, n_steps * dt, note,
                      list(rod.warnings))


def _static(rod: PeerRod, spec: CableSpec, dt: float, n_steps: int, damping: float | None):
    """S1: damped under gravity; measures the tip deflection [m]. Returns (stable, wall [s], note, measures)."""
    c = 2.0 * cantilever_angular_frequency(spec) if damping is None else float(damping)
    rod.set_gravity(GRAVITY)
    rod.set_damping(c)
    stable, wall = _advance(rod, n_steps, spec.rest_length)
    rod.refresh()
    note = f"{rod.note}; damping rate {c:.6g} 1/s; final max strain {max_strain(rod.positions(), spec.rest_length):.3g}"
    return stable, wall, note, {"tip_deflection": -rod.tip_z()} if stable else {}


def _free(rod: PeerRod, spec: CableSpec, dt: float, n_steps: int, damping: float | None):
    """S2: settle (untimed) under the release gravity, then swing free; measures the frequency [Hz]
    and the amplitude kept [-]. Returns (stable, wall [s], note, measures)."""
    omega1 = cantilever_angular_frequency(spec)
    g_small = release_gravity(spec, FREE_AMPLITUDE)
    settle_steps = int(math.ceil(SETTLE_OMEGA_T / omega1 / dt))
    rod.set_gravity(g_small)
    rod.set_damping(2.0 * omega1)
    stable, _ = _advance(rod, settle_steps, spec.rest_length)
    note = (f"{rod.note}; settled {settle_steps * dt:.4g} s (untimed) at {2.0 * omega1:.6g} 1/s "
            f"under g = {g_small:.6g} m/s^2")
    if not stable:
        return False, 0.0, note, {}
    c = 0.0 if damping is None else float(damping)
    rod.set_gravity(0.0)
    rod.set_damping(c)
    rod.zero_velocities()
    rod.refresh()
    z = np.empty(n_steps + 1)  # tip height = displacement (the clamp is at z = 0)
    z[0] = rod.tip_z()
    stable, wall = _advance(rod, n_steps, spec.rest_length, z[1:])
    note += f"; free phase damping rate {c:.6g} 1/s; initial tip displacement {z[0]:.6g} m"
    growth = np.abs(z).max() / abs(z[0])
    if stable and growth > GROWTH_LIMIT:
        stable = False
        note += f"; tip excursion grew to {growth:.3g} x the initial one: numerical instability (energy gain)"
    if not stable:
        return False, wall, note, {}
    t = np.arange(n_steps + 1) * dt
    freq = zero_crossing_frequency(t, z)
    if math.isnan(freq):
        return True, wall, note + "; fewer than two upward zero crossings: run longer", {}
    note += f"; first-period amplitude / initial = {period_amplitude(t, z, 0) / abs(z[0]):.6f}"
    return True, wall, note, {"frequency": freq, "amplitude_kept": amplitude_kept(t, z)}


def run_pyelastica(spec: CableSpec, dt: float, mode: str, duration: float, damping: float | None = None) -> PeerResult:
    """The benchmark with PyElastica (Cosserat rod, PositionVerlet); see :mod:`bullet_dlo.bench.peer_pyelastica`."""
    from bullet_dlo.bench.peer_pyelastica import PyElasticaRod

    return run_peer(PyElasticaRod(spec, dt), spec, dt, mode, duration, damping)


def run_mujoco(spec: CableSpec, dt: float, mode: str, duration: float, damping: float | None = None, *,
               integrator: str = "discrete") -> PeerResult:
    """The benchmark with a MuJoCo 1-D flexcomp rod; see :mod:`bullet_dlo.bench.peer_mujoco`.

    MuJoCo's warnings during the run are captured into the result (not printed, no log file).
    """
    from bullet_dlo.bench.peer_mujoco import MujocoRod

    with MujocoRod(spec, dt, integrator) as rod:
        return run_peer(rod, spec, dt, mode, duration, damping)


# ----- the peer sweep ----------------------------------------------------------------------------
PEER_CONFIGS = (("pyelastica", "PositionVerlet", 5e-7),  # PositionVerlet: stable up to ~5e-7 s for this stiff rod
                ("mujoco", "discrete", 1e-3), ("mujoco", "RK4", 1e-4))
"""(peer, integrator, dt [s]) of the sweep."""

SCENARIO_MODES = {"S1": ("static", 0.1), "S2": ("free", 0.15)}  # free: about 5 periods of the 36 Hz mode
"""Benchmark scenario: (mode, duration of the timed phase [s])."""


@dataclass(frozen=True)
class PeerCase:
    """One peer run of the sweep: peer, its integrator, dt [s], number of nodes n, scenario S1 or S2."""

    peer: str
    integrator: str
    dt: float
    n: int
    scenario: str

    def run(self, spec: CableSpec) -> tuple[dict, list[str]]:
        """Run on ``spec`` with n nodes: (JSON-ready point with the error against the closed form, warnings)."""
        spec = spec.with_(n_masses=self.n)
        mode, duration = SCENARIO_MODES[self.scenario]
        if self.peer == "mujoco":
            res = run_mujoco(spec, self.dt, mode, duration, integrator=self.integrator)
        else:
            res = run_pyelastica(spec, self.dt, mode, duration)
        err = None
        if res.stable and res.tip_deflection is not None:
            err = relative_error(res.tip_deflection, cantilever_deflection(spec))
        if res.stable and res.frequency is not None:
            err = relative_error(res.frequency, cantilever_frequency(spec))
        point = dict(label=f"{self.peer} ({self.integrator})", peer=self.peer, integrator=self.integrator,
                     scenario=self.scenario, n=self.n, dt=self.dt, stable=res.stable, error=err,
                     wall_per_sim_s=res.wall_time_s / max(res.sim_time_s, 1e-12), amplitude_kept=res.amplitude_kept,
                     warnings=len(res.warnings), note=res.note)
        return point, res.warnings


def peer_cases(n_masses: dict[str, tuple[int, ...]], available_peers: dict[str, bool]) -> list[PeerCase]:
    """Every configuration of :data:`PEER_CONFIGS` whose peer is available, at the node counts
    ``n_masses[peer]``, on S1 and S2."""
    return [PeerCase(peer, integ, dt, n, sc) for peer, integ, dt in PEER_CONFIGS if available_peers.get(peer)
            for n in n_masses[peer] for sc in SCENARIO_MODES]


def equal_accuracy_ratios(points: list[dict], ours: dict[str, float | None], tol: float = 0.01) -> dict[str, float]:
    """Wall time of each peer's cheapest run within ``tol`` over ours, per "peer/scenario";
    ``ours``: our cheapest wall time per simulated second within ``tol`` per scenario (None: none)."""
    ratios = {}
    for peer in dict.fromkeys(p["peer"] for p in points):
        for sc, own in ours.items():
            costs = [p["wall_per_sim_s"] for p in points if p["peer"] == peer and p["scenario"] == sc
                     and p["stable"] and p["error"] is not None and p["error"] <= tol]
            if costs and own:
                ratios[f"{peer}/{sc}"] = min(costs) / own
    return ratios
