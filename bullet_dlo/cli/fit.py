"""``bullet-dlo fit``: cable parameters from a recording of grasp poses and wrist forces."""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from bullet_dlo.core.validate import ParameterError


RANGES = {  # CLI option -> (low, high, inclusive-low) checked before anything runs
    "length": (0.0, math.inf, False), "diameter": (0.0, math.inf, False), "mass": (0.0, math.inf, False),
    "youngs_modulus": (0.0, math.inf, False), "dt": (0.0, math.inf, False), "skip": (0.0, math.inf, True),
    "level": (0.5, 1.0, True), "max_holdout_ratio": (1.0, math.inf, True), "max_noise_ratio": (1.0, math.inf, True),
    "max_numerical_damping": (0.0, math.inf, False), "max_relative_se": (0.0, math.inf, False),
    "sigma_force": (0.0, math.inf, False), "sigma_moment": (0.0, math.inf, False),
    "sigma_linear": (0.0, math.inf, False),
}
MAX_N_MASSES = 200
"""Most point masses of the fit's model: a fit runs it 100-300 times over the recording, and n = 200 over
a 10 s recording already takes minutes on a 2-core machine (cost grows faster than n)."""
MAX_MODEL_STEPS = 10**6
"""Most model steps per run (all recordings' last times / --dt)."""
MIN_STEPS_PER_RECORDING = 50
"""Fewest model steps over the shortest recording (a larger --dt resolves nothing the recording holds)."""
INT_RANGES = {"n_masses": (3, MAX_N_MASSES), "beam_step": (1, 100), "max_evaluations": (2, 10**6), "windows": (2, 1000),
              "min_windows": (2, 1000), "stiffness_grid": (0, 101),
              "profile_points": (0, 101)}


def check_args(args: argparse.Namespace) -> None:
    """One-line ParameterError naming the first option outside its allowed range."""
    for key, (lo, hi, closed) in RANGES.items():
        v = getattr(args, key, None)
        if v is None:
            continue
        ok = (v >= lo if closed else v > lo) and (v < hi if key == "level" else v <= hi) and math.isfinite(v)
        if not ok:
            low = f"{'>=' if closed else '>'} {lo:g}"
            high = "" if hi == math.inf else f" and {'<' if key == 'level' else '<='} {hi:g}"
            raise ParameterError(f"--{key.replace('_', '-')} must be {low}{high}, got {v!r}")
    band = getattr(args, "band", None)
    if band is not None and not (math.isfinite(band[0]) and math.isfinite(band[1]) and 0 < band[0] < band[1]):
        raise ParameterError(f"--band LOW HIGH must satisfy 0 < LOW < HIGH [Hz], got {band[0]!r} {band[1]!r}")
    for key, (lo, hi) in INT_RANGES.items():
        v = getattr(args, key)
        if v is None and key == "n_masses":  # (not given: the recording's simulation's, or 10)
            continue
        if not lo <= v <= hi:
            raise ParameterError(f"--{key.replace('_', '-')} must be an integer in [{lo}, {hi}], got {v!r}")


def cmd_fit(args: argparse.Namespace) -> int:
    from bullet_dlo.analysis.fit import FitOptions, default_parameters, fit_cable
    from bullet_dlo.core.spec import CableSpec

    check_args(args)
    kinds = tuple(k.strip() for k in args.kinds.split(",")) if args.kinds else None
    sigma = {k: v for k, v in (("force", args.sigma_force), ("moment", args.sigma_moment),
                               ("linear", args.sigma_linear)) if v}
    options = FitOptions(integrator=args.integrator, dt=args.dt, start=args.start, skip=args.skip,
                         max_evaluations=args.max_evaluations, kinds=kinds, sigma=sigma or None,
                         windows=args.windows, min_windows=args.min_windows, level=args.level,
                         max_holdout_ratio=args.max_holdout_ratio, max_numerical_damping=args.max_numerical_damping,
                         max_noise_ratio=args.max_noise_ratio,
                         max_relative_se=args.max_relative_se, profile_points=args.profile_points,
                         match_source=args.match_source, stiffness_grid=args.stiffness_grid)
    cable = argparse.Namespace(length=args.length, diameter=args.diameter, mass=args.mass)
    recs = [read_any(path, args, cable) for path in args.recording]
    strips = [is_beam_csv(path) for path in args.recording]  # the strip on a Panda: its cable is known
    if any(strips) and not all(strips):
        raise ParameterError("beam_handling recordings (a strip on a Panda) cannot be fitted together with cable "
                             "recordings: fit them separately")
    length = args.length or recs[0].length
    if length is None:
        raise ParameterError("--length is required: the recording does not state its cable's length [m]")
    diameter = args.diameter or stated_diameter(recs)
    if diameter is None and not all(strips):
        raise ParameterError("--diameter is required: the cable's diameter [m], > 0 (the recording does not state "
                             "it)")
    if args.mass is None and not any(r.force is not None or r.linear_obs is not None for r in recs):
        raise ParameterError("--mass is required for recordings without forces or torques (marker positions see "
                             "E I / (rho A) only): give the cable's mass [kg]")
    shortest = min(float(r.t[-1] - r.t[0]) for r in recs)
    if args.dt > shortest / MIN_STEPS_PER_RECORDING:
        raise ParameterError(f"--dt must be at most {shortest / MIN_STEPS_PER_RECORDING:.3g} s (the shortest recording, "
                             f"{shortest:.3g} s, in at least {MIN_STEPS_PER_RECORDING} model steps), got {args.dt:g}")
    steps = sum(float(r.t[-1]) for r in recs) / args.dt
    if steps > MAX_MODEL_STEPS:
        raise ParameterError(f"the model would run {steps:.3g} steps per evaluation (recordings' duration / --dt "
                             f"{args.dt:g} s), more than {MAX_MODEL_STEPS:.0e}: use a larger --dt, fewer or "
                             f"shorter recordings (--time-window T0 T1)")
    n_masses = args.n_masses or model_masses(recs)
    names = args.params.split(",") if args.params else default_parameters(fit_mass=args.mass is None)
    first = recs[0]
    weight = -float(np.mean(first.force[:, :, 2].sum(axis=1))) if first.force is not None else 0.0  # [N]
    if all(strips):  # beam_handling: the nominal strip as one rectangle-section cable, E and mass as given
        from bullet_dlo.reality.beam import Strip

        spec = Strip().rectangle_spec(n_masses)
        spec = spec.with_(youngs_modulus=args.youngs_modulus or spec.youngs_modulus, mass=args.mass or spec.mass)
    else:
        spec = CableSpec(length=length, diameter=diameter, mass=args.mass or max(weight / 9.81, 1e-4),
                         youngs_modulus=args.youngs_modulus or 1e8, n_masses=n_masses, twist=args.twist)
    from bullet_dlo.cli.quiet import elapsed

    with elapsed(f"fit: at most {args.max_evaluations} model runs", args.quiet):
        res = fit_cable(recs, spec, names, options)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    summary = {"recordings": [str(p) for p in args.recording], "recording": str(args.recording[0]),
               "forces": args.forces, **res.to_dict()}
    (out / "fit.json").write_text(json.dumps(summary, indent=2, default=float))
    if first.force is not None:
        plot_fit(first.t, first.force, res.forces, out / "fit.png",
                 title=f"{Path(args.recording[0]).name}: measured vs fitted")
    elif first.markers is not None and np.all(np.isfinite(res.loads[0].x)):
        from bullet_dlo.analysis.fit_recording import markers_on

        plot_markers(first.t, first.markers, markers_on(res.loads[0].x, res.loads[0].s, first.marker_s),
                     out / "fit.png", title=f"{Path(args.recording[0]).name}: measured vs fitted markers")
    print_summary(res)
    print(f"outputs written to {out.resolve()}")
    return 0


DEFAULT_N_MASSES = 10


def stated_diameter(recs) -> float | None:
    """The cable diameter [m] the recordings state (simulated files: a dataset episode's parameters, a series
    file's ``cable``), when every recording that states one states the same; else None."""
    values = {r.source["diameter"] for r in recs if r.source and "diameter" in r.source}
    return values.pop() if len(values) == 1 else None


def model_masses(recs) -> int:
    """The model's number of masses when ``--n-masses`` is not given: that of the simulation that made the
    recordings, where every one of them states the same (a series' ``cable`` attribute, a dataset episode's
    parameters; within the CLI's range), else :data:`DEFAULT_N_MASSES`. (Fitted with another n, a simulated
    recording's parameters are those of another discretisation: a 14-mass recording fitted with 10 masses gave E
    9 % low with a 0.7 % interval.)"""
    ns = {(r.source or {}).get("n_masses") for r in recs}
    n = ns.pop() if len(ns) == 1 else None
    lo, hi = INT_RANGES["n_masses"]
    return n if isinstance(n, int) and lo <= n <= hi else DEFAULT_N_MASSES


BEAM_BAND = (1.5, 8.0)
"""Band [Hz] a beam_handling torque residual is compared in by default: the strip's ringing (2.9 Hz)
without the estimate's slow, pose-dependent bias (the validation's band)."""


def is_beam_csv(path: str) -> bool:
    """Whether ``path`` is a CSV whose header names Franka's estimate columns (a beam_handling recording)."""
    if Path(path).suffix.lower() != ".csv":
        return False
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            return "tau_ext_hat_filtered[0]" in fh.readline()
    except OSError:
        return False


def read_any(path: str, args: argparse.Namespace, cable: argparse.Namespace):
    """One recording in any format ``fit`` reads: a DEFORM trial (``.pkl``, restricted unpickling: plain
    lists, numbers and numpy arrays only), a beam_handling CSV (recognised by its header) or the
    project's own (.csv, .npz, .h5); ``--band`` sets the linear kind's band (a beam's default: 1.5-8 Hz)."""
    if Path(path).suffix.lower() == ".pkl":
        from bullet_dlo.reality.deform import read_recording as read_deform

        if args.time_window or args.units:
            raise ParameterError("--time-window and --units do not apply to a DEFORM .pkl trial (100 Hz, metres)")
        return read_deform(path)
    if is_beam_csv(path):
        from bullet_dlo.reality.beam import fit_recording, read_beam_csv
        from bullet_dlo.reality.panda import Panda

        if args.time_window or args.units:
            raise ParameterError("--time-window and --units do not apply to a beam_handling CSV (1 kHz, SI)")
        with Panda() as panda:
            rec = fit_recording(read_beam_csv(path), panda, step=args.beam_step)
        return dataclasses.replace(rec, linear_band=tuple(args.band) if args.band else BEAM_BAND)
    from bullet_dlo.data.recording import read_recording

    rec = read_recording(path, args.forces, units=args.units, window=args.time_window, cable=cable)
    return dataclasses.replace(rec, linear_band=tuple(args.band)) if args.band else rec


def print_summary(res) -> None:
    """The fit's values, intervals, verdict, whiteness, per-recording residuals and model run, as text."""
    from bullet_dlo.analysis.fit_recording import KINDS

    pct = f"{100 * res.level:g} %"
    for name in res.values:
        iv = res.intervals.get(name)
        span = f"[{iv[0]:.4g}, {iv[1]:.4g}] ({pct})" if iv else "no interval"
        jac = res.jacobian_standard_errors.get(name, math.nan)
        print(f"{name:18s} {res.values[name]:.6g}  {span}  (Jacobian-only +- {jac:.3g})"
              + ("" if res.identifiable[name] else "  (not identifiable)"))
    v = res.verdict
    print("verdict: " + ("MODEL DISCREPANCY DOMINATES, no confident number: " + "; ".join(v["reasons"])
                         if v["discrepancy_dominates"] else f"confident: {', '.join(v['confident']) or 'none'}"))
    w, h = res.whiteness, res.holdout
    print(f"residual: sigma {res.sigma:.4g} (first kind's units), lag-1 autocorrelation "
          f"{w['lag1_autocorrelation']:.3g}, correlation time {w['integrated_autocorrelation_time_s']:.3g} s, "
          f"effective samples {w['effective_samples']:.4g} of {w['samples']}, Ljung-Box p {w['p_value']:.3g}")
    if h.get("ratio") is not None:
        print(f"held-out: {h['windows']} windows, held-out / in-sample residual {h['ratio']:.3g} "
              f"(limit {h['limit_ratio']:g})")
    for entry in res.per_recording:
        parts = [f"{k} rms {entry[k]['rms']:.4g} {entry[k]['unit']}" for k in KINDS if k in entry]
        print(f"  recording {entry['name']}: {entry['samples']} samples, " + ", ".join(parts))
    nd = res.numerics["model"]
    print(f"model run: {res.integrator}, dt {res.dt:.4g} s, n {res.n_masses}; numerical damping: {nd['message']}")
    print(f"{res.evaluations} model runs; condition {res.condition:.3g}")
    for warning in res.warnings:
        print(f"warning: {warning}")


def plot_fit(t: np.ndarray, measured: np.ndarray, fitted: np.ndarray, png: Path, title: str) -> None:
    """Measured (thin) and fitted (dashed) force components [N] of both arms against time [s]."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 1, sharex=True, figsize=(8, 5.5))
    for arm, ax in enumerate(axes):
        for j, (label, color) in enumerate(zip("xyz", ("C0", "C1", "C2"))):
            ax.plot(t, measured[:, arm, j], color=color, lw=0.7, alpha=0.7, label=f"measured f{label}")
            ax.plot(t, fitted[:, arm, j], color=color, lw=1.5, ls="--", label=f"fitted f{label}")
        ax.set_ylabel(f"{('left', 'right')[arm]} force [N]")
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    axes[0].legend(ncol=3, fontsize=8, loc="upper center", bbox_to_anchor=(0.5, 1.35))
    fig.suptitle(title, y=0.99)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


def plot_markers(t: np.ndarray, measured: np.ndarray, fitted: np.ndarray, png: Path, title: str) -> None:
    """Measured (thin) and fitted (dashed) marker coordinates [m] against time [s], one panel per axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(8, 7))
    for j, ax in enumerate(axes):
        for i in range(measured.shape[1]):
            color = f"C{i % 10}"
            ax.plot(t, measured[:, i, j], color=color, lw=0.7, alpha=0.7)
            ax.plot(t, fitted[:, i, j], color=color, lw=1.3, ls="--")
        ax.set_ylabel(f"{'xyz'[j]} [m]")
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time [s]  (thin: measured, dashed: fitted model, one colour per marker)")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


def add_parsers(sub, common: argparse.ArgumentParser) -> None:
    """``fit`` on ``sub`` (argparse subparsers); ``common``: shared options."""
    s = sub.add_parser(
        "fit", parents=[common], help="identify E, damping and mass from recorded end loads, with honest intervals",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Least squares on the recorded end loads: the core model, both ends clamped and following "
                    "the recorded grasp poses, is run for trial parameters (in log space) until its end forces, "
                    "clamp moments or a linear map of them match what the recordings hold (each kind divided by "
                    "its noise level; several recordings share one cable).\n\n"
                    "Intervals: the widest of a delete-a-window jackknife over time windows >= 5 residual "
                    "correlation times (recordings count as windows), the Newey-West sandwich and the Jacobian "
                    "one. Too few independent windows or a held-out residual much larger than the in-sample one "
                    "means the model lacks something the data have: every parameter is then reported with "
                    "identifiable false and no interval. The model's integrator and dt must add less numerical "
                    "damping than a share of the fitted physical damping (else the damping terms get no "
                    "number).\n\nWrites fit.json (values, intervals and their method, whiteness, held-out "
                    "residuals, per-recording residuals, integrator/n/dt, numerical-damping check, profiles, "
                    "verdict) and fit.png (measured vs fitted forces of the first recording) into --out. "
                    "Also read: DEFORM motion-capture trials (.pkl; markers as the residual, both ends clamped to "
                    "the held marker pairs, started from the first frame; --mass required) and beam_handling "
                    "CSVs (a Panda carrying a steel strip: Franka's filtered external-torque estimate as the "
                    "residual, band-passed, the strip clamped at the flange and free at its tip, one "
                    "rectangle-section cable with a material frame).\n\n"
                    "RECORDING: .csv, .npz or .h5 (a grasp --series file or a dataset episode; columns in "
                    "bullet_dlo.data.recording): CSV columns by header name t, left_x..left_z, left_qx..left_qw, "
                    "left_fx..left_fz, the same for right_; units SI (s, m, N, N m) unless the file states them "
                    "(header brackets such as 'left_x [mm]', HDF5 'units' attributes, NPZ attrs units) or --units "
                    "does. Refused before anything runs: damaged files, links, pickles, non-increasing times, "
                    "implausible SI values (time step outside 1e-5..1 s, positions > 100 m, forces > 1 kN), "
                    "recordings over 120 s or 250000 samples (cut them with --time-window).")
    s.add_argument("recording", nargs="+", help="recording file(s) (.csv, .npz, .h5, DEFORM .pkl, beam_handling "
                   ".csv); several: fitted together")
    s.add_argument("--length", type=float, help="cable length [m], > 0 (required unless the recording states it: "
                   "a DEFORM trial's length between the held markers, a dataset episode's or grasp --series file's "
                   "simulated cable)")
    s.add_argument("--diameter", type=float, help="cable diameter [m], > 0 (required unless the recording states "
                   "it: a dataset episode's or grasp --series file's simulated cable; beam_handling recordings' "
                   "strip is known: 0.52 x 0.08 x 0.001 m steel)")
    s.add_argument("--mass", type=float, help="cable mass [kg], > 0, if known (else it is fitted)")
    s.add_argument("--youngs-modulus", type=float, help="start value of E [Pa], > 0 (1e8; a beam_handling "
                   "strip: 197.5e9)")
    s.add_argument("--band", nargs=2, type=float, metavar=("LOW", "HIGH"), help="compare the linear kind (joint "
                   "torques) band-passed to [LOW, HIGH] Hz, zero-phase, measured and predicted alike (default for "
                   "beam_handling recordings: 1.5 8; else none)")
    s.add_argument("--beam-step", type=int, default=4, help="keep every N-th sample of a beam_handling "
                   "recording (1 kHz / N), 1-100 (4)")
    s.add_argument("--n-masses", type=int, default=None,
                   help=f"point masses of the model, 3-{MAX_N_MASSES} (default: the n of the simulation that made the "
                        f"recordings, when they state it, else {DEFAULT_N_MASSES})")
    s.add_argument("--units", metavar="Q=U,...", help="units of the recording's columns that the file does not "
                   "state: time=s|ms|us, length=m|cm|mm, force=N|mN, moment='N m'|'N mm'|'mN m' (default SI)")
    s.add_argument("--time-window", nargs=2, type=float, metavar=("T0", "T1"), help="fit only the samples with "
                   "T0 <= t <= T1 [s, the file's times] (their times then start at 0); cuts a recording longer "
                   "than 120 s")
    s.add_argument("--twist", action="store_true", help="give the cable a material frame (twist springs; the "
                   "grippers' roll twists it), so that shear_modulus can be fitted from the moments about the cable")
    s.add_argument("--params", help="comma-separated CableSpec fields to fit, among youngs_modulus, damping_rate, "
                   "internal_damping, damping, mass, shear_modulus (needs --twist) (default: youngs_modulus, internal_damping, damping_rate, "
                   "and mass when --mass is not given)")
    s.add_argument("--forces", default="wrench_world", choices=["wrench_world", "end_forces"],
                   help="which recorded forces to fit: the wrist sensors (default) or the simulated model's "
                        "(end_forces, then also its end_moments)")
    s.add_argument("--kinds", help="comma-separated residual kinds among force, moment, linear (default: every "
                   "kind the recordings hold: moment needs grasp-point moments, linear needs linear_map/linear_obs)")
    s.add_argument("--sigma-force", type=float, help="force noise level [N], > 0 (default: estimated from the "
                   "recordings' sample-to-sample differences)")
    s.add_argument("--sigma-moment", type=float, help="moment noise level [N m], > 0 (default: estimated)")
    s.add_argument("--sigma-linear", type=float, help="noise level of the linear kind [its units], > 0 "
                   "(default: estimated)")
    s.add_argument("--integrator", default="implicit_midpoint",
                   choices=["auto", "implicit_midpoint", "bdf2", "implicit_euler", "symplectic_euler", "rk4",
                            "explicit_euler"],
                   help="core integrator of the model (implicit_midpoint); auto: bdf2 with --dt halved (up to 3 "
                        "times) until its numerical damping passes the check")
    s.add_argument("--dt", type=float, default=1e-3,
                   help="model time step [s], > 0 and at most 1/50 of the shortest recording (1e-3)")
    s.add_argument("--match-source", action="store_true", help="run the model with the integrator and dt a "
                   "simulated recording says it was made with (its integrator's numerical damping is then "
                   "reproduced instead of fitted as physical damping)")
    s.add_argument("--start", default="auto", choices=["auto", "static", "straight", "recorded"],
                   help="model start: equilibrium at the first poses (static), straight at rest, the "
                        "recording's own first shape and velocity (recorded: motion capture); auto (default): "
                        "recorded when the recording has a shape, else static")
    s.add_argument("--stiffness-grid", type=int, default=9, help="Young's moduli tried before the descent, "
                   "log-spaced over a decade either side of --youngs-modulus, the best one starting it (an "
                   "oscillating recording has a local minimum wherever the ringing falls in phase); the same "
                   "grid about the fitted values finds other minima (one as good makes E not identifiable), "
                   "0-101 (9; 0 or 1: none)")
    s.add_argument("--skip", type=float, default=0.0, help="seconds at the start of each recording left out of "
                   "the residual, >= 0 (0)")
    s.add_argument("--max-evaluations", type=int, default=60, help="model runs allowed per fit, >= 2 (60)")
    s.add_argument("--windows", type=int, default=8, help="most time windows per recording for the held-out "
                   "intervals, 2-1000 (8)")
    s.add_argument("--min-windows", type=int, default=4, help="fewer independent windows than this in all: "
                   "discrepancy dominates, no confident number, 2-1000 (4)")
    s.add_argument("--level", type=float, default=0.95, help="interval coverage, in [0.5, 1) (0.95)")
    s.add_argument("--max-noise-ratio", type=float, default=3.0, help="residual RMS over the noise level above which, "
                   "with a residual that is not white, model discrepancy is declared (no confident number) (3)")
    s.add_argument("--max-holdout-ratio", type=float, default=1.5, help="held-out / in-sample residual RMS above "
                   "which discrepancy is declared, >= 1 (1.5)")
    s.add_argument("--max-numerical-damping", type=float, default=0.1, help="allowed numerical / physical "
                   "damping ratio on the model's lowest modes, > 0 (0.1)")
    s.add_argument("--max-relative-se", type=float, default=0.3, help="above this relative standard error "
                   "(interval half-width / 1.96 / value) a parameter is not identifiable, > 0 (0.3)")
    s.add_argument("--profile-points", type=int, default=5, help="points of each parameter's conditional "
                   "profile in fit.json, 0-101 (5; 0: none)")
    s.add_argument("--out", required=True, metavar="DIR", help="output folder for fit.json and fit.png")
    s.set_defaults(func=cmd_fit)


__all__ = ["add_parsers", "cmd_fit", "plot_fit", "ParameterError"]
