"""``bullet-dlo fit``: cable parameters from a recording of grasp poses and wrist forces."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from bullet_dlo.core.validate import ParameterError


def cmd_fit(args: argparse.Namespace) -> int:
    from bullet_dlo.analysis.fit import FitOptions, default_parameters, fit_cable
    from bullet_dlo.core.spec import CableSpec
    from bullet_dlo.data.recording import read_recording

    rec = read_recording(args.recording, args.forces)
    names = args.params.split(",") if args.params else default_parameters(fit_mass=args.mass is None)
    weight = -float(np.mean(rec.force[:, :, 2].sum(axis=1)))  # [N]: the start value of the mass
    spec = CableSpec(length=args.length, diameter=args.diameter, mass=args.mass or max(weight / 9.81, 1e-4),
                     youngs_modulus=args.youngs_modulus, n_masses=args.n_masses)
    options = FitOptions(integrator=args.integrator, dt=args.dt, start=args.start, skip=args.skip,
                         max_evaluations=args.max_evaluations)
    res = fit_cable(rec, spec, names, options)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    summary = {"recording": str(args.recording), "forces": args.forces, **res.to_dict()}
    (out / "fit.json").write_text(json.dumps(summary, indent=2))
    plot_fit(rec.t, rec.force, res.forces, out / "fit.png", title=f"{Path(args.recording).name}: measured vs fitted")
    for name in res.values:
        se = res.standard_errors[name]
        print(f"{name:18s} {res.values[name]:.6g} +- {se:.3g}" + ("" if res.identifiable[name] else "  (not identifiable)"))
    print(f"residual sigma {res.sigma:.4g} N, condition {res.condition:.3g}, {res.evaluations} model runs")
    for w in res.warnings:
        print(f"warning: {w}")
    print(f"outputs written to {out.resolve()}")
    return 0


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


def add_parsers(sub, common: argparse.ArgumentParser) -> None:
    """``fit`` on ``sub`` (argparse subparsers); ``common``: shared options."""
    s = sub.add_parser("fit", parents=[common], help="identify E, damping and mass from grasp poses and wrist forces",
                       description="Least squares on the wrist-force residual: the core model, both ends clamped "
                                   "and following the recorded grasp poses, is run for trial parameters (in log "
                                   "space) until its end forces match the recorded tared world-frame forces. "
                                   "Writes fit.json (values, standard errors, identifiability, condition) and "
                                   "fit.png (measured vs fitted) into --out. RECORDING: .csv, .npz or .h5 (a "
                                   "grasp --series file or a dataset episode; columns in bullet_dlo.data.recording).")
    s.add_argument("recording", help="recording file (.csv, .npz, .h5)")
    s.add_argument("--length", type=float, required=True, help="cable length [m]")
    s.add_argument("--diameter", type=float, required=True, help="cable diameter [m]")
    s.add_argument("--mass", type=float, help="cable mass [kg] if known (else it is fitted)")
    s.add_argument("--youngs-modulus", type=float, default=1e8, help="start value of E [Pa] (1e8)")
    s.add_argument("--n-masses", type=int, default=10, help="point masses of the model (10)")
    s.add_argument("--params", help="comma-separated CableSpec fields to fit (default: youngs_modulus, "
                   "internal_damping, damping_rate, and mass when --mass is not given)")
    s.add_argument("--forces", default="wrench_world", choices=["wrench_world", "end_forces"],
                   help="which recorded forces to fit: the wrist sensors (default) or the simulated model's")
    s.add_argument("--integrator", default="implicit_midpoint", help="core integrator of the model (implicit_midpoint)")
    s.add_argument("--dt", type=float, default=1e-3, help="model time step [s] (1e-3)")
    s.add_argument("--start", default="static", choices=["static", "straight"],
                   help="model start: equilibrium at the first poses (default) or straight at rest")
    s.add_argument("--skip", type=float, default=0.0, help="seconds at the start left out of the residual (0)")
    s.add_argument("--max-evaluations", type=int, default=60, help="model runs allowed (60)")
    s.add_argument("--out", required=True, metavar="DIR", help="output folder for fit.json and fit.png")
    s.set_defaults(func=cmd_fit)


__all__ = ["add_parsers", "cmd_fit", "plot_fit", "ParameterError"]
