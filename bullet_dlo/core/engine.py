"""The core engine: run a cable model with one integrator, watch for instability, record.

``simulate(model, "implicit_euler", dt=1e-3, duration=2.0)`` runs the whole time loop in
Numba (:func:`bullet_dlo.core.kernels.loop.run_loop`, so even 1e-7 s steps are affordable; in pieces of
about 0.1 s, so that a Ctrl-C stops it promptly, with the one-call result bit for bit) and returns
a :class:`SimulationResult`. An unstable run is data, not an exception: the result says when it went
unstable and why.

Instability detector (cheap checks every ``check_every`` steps, energy every ``energy_every``):

* non-finite positions or velocities;
* a segment stretched or compressed beyond ``max_strain`` (default 50 %). A strain is not by
  itself a numerical blow-up (a soft cable under load really stretches that much), so with the
  default bound the core engine re-runs such a run without it: if it ends finite and without
  energy growth the run is stable and the large strain is a *warning* (``max_strain_seen``),
  otherwise it stays unstable. An explicit ``max_strain`` is a hard stop, as before;
* energy created from nothing: E(t) - E(0) - W_holders(t) > ``energy_factor`` * E_scale, with
  E the kinetic + elastic + gravitational energy, W the work done by the held ends (forces
  and clamp moments), and E_scale = M |g| L + EI / L + |E(0) elastic and kinetic| + sum |dW|
  (so a dissipative or energy-conserving method never trips it, while exponential growth trips
  it within a few steps). EI / L (the energy of bending the whole cable through about a
  radian) keeps the scale physical without gravity.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from bullet_dlo.core.boundary import ROLL_SAMPLES, ROLL_TOL, end_roll, turns
from bullet_dlo.core.enums import EndMode
from bullet_dlo.core.integrators import NewtonOptions, get_integrator, make_stepper
from bullet_dlo.core.kernels.forces import clamp_torque, internal_energy, max_strain, mechanical_energy
from bullet_dlo.core.kernels.holders import HeldSamples, HolderPlan, empty_samples, peak_speeds, sample_holders
from bullet_dlo.core.kernels.loop import make_records, run_loop, start_loop
from bullet_dlo.core.kernels.monitor import REASONS, STABLE, STRETCH, Detector, clamp_moments, end_forces
from bullet_dlo.core.kernels.steppers import make_workspace
from bullet_dlo.core.model import CableModel, CableState, KernelArrays
from bullet_dlo.core.validate import ParameterError, check_int, check_positive


@dataclass(frozen=True)
class DetectorOptions:
    """Instability detector thresholds.

    max_strain: largest allowed |l/l0 - 1| of any segment [-]; None (default): 0.5, and a run stopped
    by it is confirmed by a re-run without it (see module doc); energy_factor: allowed energy
    created, as a multiple of the energy scale [-] (see module doc); check_every: steps between
    the cheap checks (finite, strain); energy_every: steps between energy-balance checks
    (an energy evaluation costs about a force evaluation).
    """

    max_strain: float | None = None
    energy_factor: float = 1.0
    check_every: int = 1
    energy_every: int = 10

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        if self.max_strain is not None:
            set_(self, "max_strain", check_positive("detector.max_strain", self.max_strain))
        set_(self, "energy_factor", check_positive("detector.energy_factor", self.energy_factor))
        set_(self, "check_every", check_int("detector.check_every", self.check_every, 1))
        set_(self, "energy_every", check_int("detector.energy_every", self.energy_every, 1))


    @property
    def strain_bound(self) -> float:
        """The strain bound the detector kernels check [-]."""
        return DEFAULT_STRAIN_BOUND if self.max_strain is None else float(self.max_strain)


DEFAULT_STRAIN_BOUND = 0.5
CONFIRM_STRAIN_BOUND = 1e3  # the re-run's bound: a segment 1000x its rest length is a blow-up whatever the loads
NEWTON_WARN_SHARE = 0.01  # warn when Newton fails to converge in more than this share of the steps
MOVE_WARN_SEGMENTS = 1.0  # warn when a held end moves more than this many segment lengths in one step
MOVE_SAMPLES = 20_000  # times at which the held ends' speed is sampled for that warning (or 4 per step if more) ...
FEATURE_SAMPLES = 100  # ... but no more than this many per the motion's shortest feature (peak within 0.05 %)
PEAK_MEMO_SIZE = 64  # motions whose sampled peak speeds are kept (a fit runs each recording's motion many times)
STRAIN_REASON = REASONS[STRETCH]


@dataclass
class SimulationResult:
    """Outcome of a run. Arrays are recorded every ``record_every`` steps (plus the final state).

    integrator: the method's name; dt: the step [s]; stable: False if the detector stopped the run;
    time_to_instability: when it did [s] (None: stable); reason: why (None: stable); steps: steps taken;
    final_state: the last state (a :class:`~bullet_dlo.core.model.CableState`); newton_failures,
    newton_iterations: implicit methods' unconverged solves and iterations in all; warnings: what the
    run noticed (large held-end moves, many unconverged solves, a physical stretch); max_strain_seen:
    the largest recorded |l/l0 - 1| [-] when it passed the default bound (else None);
    t: times [s], (k,); x, v: positions [m] / velocities [m/s], (k, n, 3);
    end_forces: force the cable exerts on each holder [N], (k, 2, 3) (first, last);
    energy: total mechanical energy [J], (k,); end_moments: torque the cable exerts on each
    clamp in the final state [N m], (2, 3) (zeros after an unstable run); end_moment_history:
    the same at every recorded row [N m], (k, 2, 3) (None where an engine does not record it);
    wall_time_s: the time loop's wall-clock time [s], without compile_time_s: loading or compiling the
    loop's kernels before it (a minute on a fresh install, milliseconds from the cache) [s].
    """

    integrator: str
    dt: float
    stable: bool
    time_to_instability: float | None
    reason: str | None
    steps: int
    wall_time_s: float
    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    end_forces: np.ndarray
    energy: np.ndarray
    final_state: CableState
    end_moments: np.ndarray = field(default_factory=lambda: np.zeros((2, 3)))
    newton_failures: int = 0
    newton_iterations: int = 0
    warnings: list[str] = field(default_factory=list)
    max_strain_seen: float | None = None  # largest recorded |l/l0 - 1| when it passed the default bound
    end_moment_history: np.ndarray | None = None
    compile_time_s: float = 0.0

    @property
    def newton_failure_share(self) -> float:
        """Share of the steps whose Newton solve did not converge (0 for explicit methods)."""
        return self.newton_failures / self.steps if self.steps else 0.0


def start_detector(options: DetectorOptions, model: CableModel, m: KernelArrays, x: np.ndarray, v: np.ndarray,
                   samples: HeldSamples) -> Detector:
    """The detector at the start state (x [m], v [m/s], (n, 3)), held ends at sample 0 of ``samples``.

    Its energy scale starts at M |g| L + EI / L + the kinetic and elastic energy of the start state [J]
    (EI / L: without gravity the scale once fell to a 1e-12 J floor and stopped valid runs).
    """
    check_positive("max_strain", options.strain_bound)
    check_positive("energy_factor", options.energy_factor)
    check_int("check_every", options.check_every, 1)
    check_int("energy_every", options.energy_every, 1)
    dirs = samples.dir[0]
    kinetic = 0.5 * float(np.sum(m.mass[:, None] * v**2))
    scale = model.spec.mass * float(np.linalg.norm(m.gravity)) * model.spec.length + kinetic
    scale += internal_energy(m, x, model.holder_plan().start_dir) + model.spec.bending_rigidity / model.spec.length
    force, moment = np.zeros((2, 3)), np.zeros((2, 3))
    end_forces(m, x, v, dirs, samples.acc[0], force)
    clamp_moments(m, x, v, dirs, moment)
    return Detector(
        max_strain=options.strain_bound, energy_factor=float(options.energy_factor),
        check_every=int(options.check_every), energy_every=int(options.energy_every),
        e0=float(mechanical_energy(m, x, v, dirs)), work=np.zeros(1), scale=np.array([scale]),
        end_force=force, hold_pos=samples.pos[0].copy(), end_moment=moment, hold_dir=dirs.copy(),
    )


def simulate(
    model: CableModel,
    integrator: str = "implicit_euler",
    dt: float = 1e-3,
    duration: float = 1.0,
    *,
    state: CableState | None = None,
    record_every: int | None = None,
    max_records: int = 2001,
    newton: NewtonOptions = NewtonOptions(),
    detector: DetectorOptions = DetectorOptions(),
    f_ext: np.ndarray | None = None,
) -> SimulationResult:
    """Run ``model`` for ``duration`` seconds with fixed steps ``dt``.

    Args:
        model: the cable and its end conditions.
        integrator: name from :data:`bullet_dlo.core.integrators.INTEGRATORS`.
        dt: time step [s], > 0.
        duration: simulated time [s], > 0 (rounded to a whole number of steps).
        state: start state (default: the model's initial state at rest); its ``twist`` (a cable with a
            material frame) continues a run's ``final_state``, None builds it from the positions.
        record_every: steps between recorded rows (default: so that about ``max_records`` rows are kept).
        newton: Newton options for implicit methods.
        detector: instability thresholds.
        f_ext: constant external forces [N], (n, 3) (the run's control; the model is read only).

    The result's ``warnings`` say what a user should know although the run is stable (Newton
    failing in more than ``NEWTON_WARN_SHARE`` of the steps; a large but physical strain; a held
    end moved more than ``MOVE_WARN_SEGMENTS`` segment lengths per step; a clamp rolled about the cable's axis
    although the cable has no material frame, which it then does not feel).
    """
    kwargs = dict(state=state, record_every=record_every, max_records=max_records, newton=newton, f_ext=f_ext)
    result = _simulate(model, integrator, dt, duration, detector=detector, **kwargs)
    if result.reason == STRAIN_REASON and detector.max_strain is None:
        result = confirm_strain(model, result, lambda bound: _simulate(
            model, integrator, dt, duration, detector=replace(detector, max_strain=bound), **kwargs))
    result.warnings.extend(held_move_warnings(model, dt, duration))
    result.warnings.extend(unfelt_roll_warnings(model, duration))
    share = result.newton_failure_share
    if share > NEWTON_WARN_SHARE:
        result.warnings.append(
            f"Newton did not converge in {result.newton_failures} of {result.steps} steps ({100 * share:.1f} %): "
            "the implicit equations were solved only approximately; use a smaller dt, raise newton.max_iter, "
            "or use implicit_euler")
    return result


_ROLL_MEMO: dict[tuple, tuple] = {}


def unfelt_roll_warnings(model: CableModel, duration: float) -> list[str]:
    """A warning when a clamp's (or a fork's) motion rolls it about the cable's axis by more than
    :data:`~bullet_dlo.core.boundary.ROLL_TOL` within ``duration`` [s] while the cable has no material frame (a
    round cable without ``twist``): the roll is not felt, no torsion, no torque about the axis (scene files and the
    dual-arm scene turn the frame on for it; the core API leaves the model as given). Remembered per pair of
    holders (a fit runs the same motion tens of times; sampling it costs about 0.1 s)."""
    if model.spec.twist_enabled:
        return []
    key = (id(model.first), id(model.last), duration)
    hit = _ROLL_MEMO.get(key)
    if hit is not None and hit[0] is model.first and hit[1] is model.last:
        return list(hit[2])
    times = np.linspace(0.0, duration, ROLL_SAMPLES)
    out = []
    for name, holder in (("first", model.first), ("last", model.last)):
        if not EndMode(holder.mode).holds_roll or not any(map(turns, holder.moves)):
            continue
        roll = float(np.max(np.abs(np.unwrap(end_roll(holder, times)))))
        if roll > ROLL_TOL:
            out.append(f"the {name} {EndMode(holder.mode).holder} rolls {math.degrees(roll):.3g} deg about the "
                       "cable's axis, but the cable has no material frame (a round section without twist): the "
                       "roll is not felt (no torsion); give the cable twist=True")
    if len(_ROLL_MEMO) >= 64:
        _ROLL_MEMO.clear()
    _ROLL_MEMO[key] = (model.first, model.last, tuple(out))
    return out


def held_move_warnings(model: CableModel, dt: float, duration: float) -> list[str]:
    """A warning when a prescribed held end moves more than :data:`MOVE_WARN_SEGMENTS` segment lengths
    in one step, else none. Measured on the study's cable at 60 Hz from its static equilibrium, n = 200-1000:
    every implicit run at <= 0.87 was stable, implicit Euler at n = 1000 diverged at 1.30 (the bound was 1.5
    until the static solver stopped converging falsely at n >= 500: started from the straight layout, the
    1.30 run had passed), every run at >= 4.2 diverged (``tests/cli/test_instability_reports.py``)."""
    segments, end, speed = fastest_held_move(model, dt, duration)
    if segments <= MOVE_WARN_SEGMENTS:
        return []
    return [f"the {end} end is moved up to {segments:.2g} segment lengths per step ({speed:.3g} m/s x dt / rest "
            f"length): beyond about {MOVE_WARN_SEGMENTS}, runs of the study's cable were seen to diverge (at 1.3 at "
            "n = 1000, every run at 4.2 or more); use a smaller dt, fewer masses or a slower motion"]


def fastest_held_move(model: CableModel, dt: float, duration: float) -> tuple[float, str, float]:
    """The largest distance a prescribed held end travels in one step at its peak speed, in rest segment
    lengths (peak speed x dt / rest length), that end's name (first | last) and the peak speed [m/s]:
    (0, "", 0) without a moving held end. The speed is sampled at :data:`MOVE_SAMPLES` times (at least
    4 per step) over the duration, at most :func:`motion_samples` (a run at 1 us sampled a 0.4 s move 1.6
    million times, 6 s of CPU)."""
    plan = model.holder_plan()
    tables = ((plan.moves_first, plan.path_first, plan.sines_first), (plan.moves_last, plan.path_last, plan.sines_last))
    held = (bool(model.arrays.held[0]), bool(model.arrays.held[-1]))
    moving = [held[e] and any(t.shape[0] for t in tables[e]) for e in (0, 1)]
    if not any(moving):
        return 0.0, "", 0.0
    count = min(max(MOVE_SAMPLES, 4 * int(duration / dt) + 1), motion_samples(plan, duration))
    peak = sampled_peak_speeds(plan, duration, count)
    peak[~np.array(moving)] = 0.0
    e = int(np.argmax(peak))
    return float(peak[e]) * dt / float(np.min(model.arrays.rest_length)), ("first", "last")[e], float(peak[e])


def motion_samples(plan: HolderPlan, duration: float) -> int:
    """Sample times over [0, duration] [s] that put :data:`FEATURE_SAMPLES` in the plan's shortest feature: a move's
    or a waypoint segment's duration, a sine's period or ramp (each smooth within it: a minimum-jerk or quintic
    speed peak sampled 100 times is within 0.05 % of its top, a sine's within 0.05 %)."""
    scales = [duration]
    for moves in (plan.moves_first, plan.moves_last):
        scales += moves[:, 1].tolist()
    for path in (plan.path_first, plan.path_last):
        scales += (path[:, 1] - path[:, 0]).tolist()
    for sines in (plan.sines_first, plan.sines_last):
        scales += (1.0 / sines[:, 3]).tolist() + sines[:, 2].tolist()
    shortest = min(scale for scale in scales if scale > 0.0) if duration > 0.0 else 1.0
    return int(math.ceil(FEATURE_SAMPLES * duration / shortest)) + 1


_PEAK_MEMO: dict[tuple, np.ndarray] = {}


def sampled_peak_speeds(plan: HolderPlan, duration: float, count: int) -> np.ndarray:
    """:func:`~bullet_dlo.core.kernels.holders.peak_speeds` of both ends [m/s] (2,), over [0, duration] [s] at
    ``count`` times, remembered for the last :data:`PEAK_MEMO_SIZE` motions: sampling costs about 0.14 s
    (20,000 times), as much as a fit's whole run of a short recording, and a fit runs the same motion with
    other parameters tens of times. The key is the plan's bytes, so an equal motion gives the same answer."""
    key = (duration, count, *((a.shape, a.tobytes()) for a in map(np.asarray, plan)))
    peak = _PEAK_MEMO.pop(key, None)
    if peak is None:
        peak = np.zeros(2)
        peak_speeds(plan, duration, count, empty_samples(), peak)
        if len(_PEAK_MEMO) >= PEAK_MEMO_SIZE:
            del _PEAK_MEMO[next(iter(_PEAK_MEMO))]  # the least recently used
    _PEAK_MEMO[key] = peak  # (re)inserted last: the most recently used
    return peak.copy()


def confirm_strain(model: CableModel, first: SimulationResult,
                   rerun: Callable[[float], SimulationResult]) -> SimulationResult:
    """A run stopped by the default strain bound, re-run without it (``rerun(max_strain)`` runs it again with
    that bound): stable (with a warning) if the re-run stays finite without energy growth, else the
    first result, its cause confirmed. Any engine: the core one here, the Bullet one in
    :func:`bullet_dlo.bullet.world.run_scene_bullet`."""
    again = rerun(CONFIRM_STRAIN_BOUND)
    if again.stable:
        m = model.kernel_arrays()
        again.max_strain_seen = float(max(max_strain(m, x) for x in again.x))
        again.warnings = first.warnings + again.warnings + [
            f"segment strain reached {again.max_strain_seen:.3g} (beyond {DEFAULT_STRAIN_BOUND}) at "
            f"t = {first.time_to_instability:.4g} s with no energy growth and finite state: a physically large "
            "stretch, not a numerical blow-up (detector.max_strain makes a strain bound a hard stop)"]
        return again
    first.warnings.append(f"confirmed by a re-run without the strain bound: {again.reason} at "
                          f"t = {again.time_to_instability:.4g} s")
    return first


PIECE_S = 0.1  # wall time [s] a piece of the compiled time loop aims at: Python sees a Ctrl-C between pieces
FIRST_PIECE = 16  # steps of the first piece; each next one is sized from the last one's speed, at most 8x longer


def run_in_pieces(run: Callable[[int], int], n_steps: int) -> None:
    """Call ``run(stop)`` (the compiled loop up to step ``stop``, returning its status) with growing ``stop``
    until ``n_steps`` or an unstable status, each call sized to take about :data:`PIECE_S`: a Ctrl-C (which
    Python raises only once a compiled call returns) then stops a run within about that time, however long
    the run. The loop carries its whole state between calls, so the pieces give the one-call result bit for bit."""
    done, piece = 0, FIRST_PIECE
    while done < n_steps:
        stop = min(n_steps, done + piece)
        tic = time.perf_counter()
        if run(stop) != STABLE:
            return
        took, ran = time.perf_counter() - tic, stop - done
        piece = max(1, min(8 * ran, int(ran * PIECE_S / took) if took > 0 else 8 * ran))
        done = stop


def _simulate(model: CableModel, integrator: str, dt: float, duration: float, *, state: CableState | None,
              record_every: int | None, max_records: int, newton: NewtonOptions, detector: DetectorOptions,
              f_ext: np.ndarray | None) -> SimulationResult:
    """One run of :func:`simulate` with the detector as given."""
    method = get_integrator(integrator)
    stepper = make_stepper(method, dt, newton)
    duration = check_positive("duration", duration)
    n_steps = max(1, int(round(duration / dt)))
    if record_every is None:
        record_every = max(1, math.ceil(n_steps / max(1, max_records - 1)))
    record_every = check_int("record_every", record_every, 1)
    st = (state or model.initial_state()).copy()
    n = model.n
    if st.x.shape != (n, 3) or st.v.shape != (n, 3):
        raise ParameterError(f"state arrays must have shape ({n}, 3)")
    control = model.control(f_ext)  # the model's end conditions, the constant external forces
    twist = st.twist if st.twist is not None else model.twist_state()
    m = model.kernel_arrays(control, twist)
    plan = model.holder_plan(control)
    samples = empty_samples()
    sample_holders(plan, st.t, dt, samples)
    det = start_detector(detector, model, m, st.x, st.v, samples)
    rec = make_records(n_steps // record_every + 3, n, record_every)
    x, v = st.x, st.v
    ws = make_workspace(n)
    loop = start_loop(det)
    tic = time.perf_counter()
    run_loop(stepper, m, plan, x, v, st.t, n_steps, 0, det, ws, rec, loop)  # no step: compiles/loads, records row 0
    compile_s = time.perf_counter() - tic
    tic = time.perf_counter()
    run_in_pieces(lambda stop: run_loop(stepper, m, plan, x, v, st.t, n_steps, stop, det, ws, rec, loop), n_steps)
    wall = time.perf_counter() - tic
    steps, rows, failures, iters, status = (int(c) for c in loop.counts)
    t_bad = float(loop.t_bad[0])
    t_final = st.t + steps * dt
    moments = np.zeros((2, 3))
    if status == STABLE:
        sample_holders(plan, t_final, 0.0, samples)  # clamp directions at the end
        moments = np.stack([clamp_torque(m, x, v, samples.dir[0], e) for e in (0, 1)])
    return SimulationResult(
        integrator=method.name, dt=stepper.h, stable=status == STABLE,
        time_to_instability=None if status == STABLE else float(t_bad), reason=REASONS[status],
        steps=int(steps), wall_time_s=wall,
        t=rec.t[:rows].copy(), x=rec.x[:rows].copy(), v=rec.v[:rows].copy(),
        end_forces=rec.end_force[:rows].copy(), energy=rec.energy[:rows].copy(),
        final_state=CableState(x, v, t_final, twist), end_moments=moments,
        newton_failures=int(failures), newton_iterations=int(iters),
        end_moment_history=rec.end_moment[:rows].copy(), compile_time_s=compile_s,
    )
