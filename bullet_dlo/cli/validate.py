"""``bullet-dlo validate``: the model against real recordings (issue 21).

``validate beam FIT_DIR PREDICT_DIR --json OUT``: beam_handling (a Panda carrying a steel strip),
:mod:`bullet_dlo.reality.beam_validate`. ``validate deform DLO_DIR --json OUT``: the DEFORM
motion-capture cables, :mod:`bullet_dlo.reality.deform` (its own options).
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from bullet_dlo.cli.outputs import print_outputs
from bullet_dlo.core.validate import ParameterError, check_in_range, check_int

BEAM_RANGES = {  # validate beam's numeric options: their ranges (SI)
    "dt": (1e-5, 0.01),  # [s] (below, a split runs for days; above, the 3 Hz mode has under 30 steps a period)
    "knot_step": (1e-3, 0.1),  # [s] the flange path's waypoints (the recordings are at 1 kHz)
    "youngs_modulus": (1e3, 1e13),  # [Pa] (the cable bounds of scene files)
    "density": (1.0, 1e5),  # [kg/m^3]
    "filter_cutoff": (0.1, 500.0),  # [Hz] (below the recordings' Nyquist frequency)
}


def cmd_beam(args: argparse.Namespace) -> int:
    from bullet_dlo.reality.beam import EstimateFilter, Numerics, Strip
    from bullet_dlo.reality.beam_validate import plot_file, table, validate_beam

    check_int("--n-masses", args.n_masses, 4, 400)
    if args.limit_files is not None:
        check_int("--limit-files", args.limit_files, 1)
    for name, (lo, hi) in BEAM_RANGES.items():
        if getattr(args, name) is not None:
            check_in_range(f"--{name.replace('_', '-')}", getattr(args, name), lo, hi)
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration >= 7.0):
        raise ParameterError(f"--duration must be >= 7 s (the metrics need end + 6 s), got {args.duration}")
    if args.filter_delay is not None and not (math.isfinite(args.filter_delay) and 0 <= args.filter_delay <= 0.1):
        raise ParameterError(f"--filter-delay must be in [0, 0.1] s, got {args.filter_delay}")
    if (args.filter_cutoff is None) != (args.filter_delay is None):
        raise ParameterError("--filter-cutoff and --filter-delay go together (give both, or neither to identify "
                             "the filter on FIT_DIR)")
    estimate = None if args.filter_cutoff is None else EstimateFilter(args.filter_cutoff, args.filter_delay,
                                                                       "given on the command line")
    numerics = Numerics(strip_model=args.strip_model, integrator=args.integrator, n_masses=args.n_masses, dt=args.dt,
                        knot_step=args.knot_step)
    strip = Strip(youngs_modulus=args.youngs_modulus, density=args.density)
    log = (lambda *a: None) if args.quiet else print
    summary, details = validate_beam(args.fit_dir, args.predict_dir, damping=args.damping, numerics=numerics,
                                     strip=strip, estimate=estimate, duration=args.duration,
                                     limit_files=args.limit_files, check_numerics=not args.no_numerics_check,
                                     fit_youngs_modulus=args.fit_youngs_modulus, drag=args.drag_coefficient,
                                     clamp_mass=args.clamp_mass, arm=args.arm, arm_dir=args.arm_dir,
                                     amplitude_damping=args.amplitude_damping, log=log)
    out = Path(args.json)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(summary, indent=2))
    plots = []
    if not args.no_plots:
        for name, (rec, m, pred) in details.items():
            plots.append(out.with_name(f"{out.stem}.{name}.png"))
            plot_file(rec, m, pred, plots[-1])
    fit = summary["parameters"][f"{args.damping}_fit"]
    print(table(summary))
    params = summary["parameters"]
    if "drag_fit" in params:
        dfit = params["drag_fit"]
        damping_note = (f"damping_rate {params['damping_rate']:.4g} 1/s and drag_coefficient "
                        f"{params['drag_coefficient']:.4g} fitted together (window damping ratios: rms residual "
                        f"{dfit['residual_rms']:.2g}, {dfit['linear_only_residual_rms']:.2g} with damping_rate alone)")
    else:
        damping_note = (f"{args.damping} {fit['value']:.4g} (spread over {len(fit['per_file'])} fit recordings "
                        f"{fit['interval'][0]:.4g}-{fit['interval'][1]:.4g})"
                        + (f", drag_coefficient {params['drag_coefficient']:.4g} held" if "drag_coefficient" in params
                           else ""))
    print(f"{damping_note}; estimate filter "
          f"{summary['estimate_filter']['cutoff_hz']:.3g} Hz + {1e3 * summary['estimate_filter']['delay_s']:.3g} ms; "
          f"{args.strip_model} strip, {summary['arm']['mode']} arm, {args.integrator}, n {args.n_masses}, "
          f"dt {numerics.dt:g} s; "
          f"{summary['cost_per_simulated_second']:.3g} CPU s per simulated s")
    law = params["damping_law"]
    drag_law = law["shared"]["drag"]["params"]
    print(f"measured damping law (FIT_DIR's decays, no model): {law['best_law']} across files, zeta = "
          f"{drag_law['zeta0']:.4f} + {drag_law['c']:.3g} A_tip [m] (relative misfit {law['shared']['drag']['rms_log']:.3f}"
          f", linear {law['shared']['viscous']['rms_log']:.3f}); per file: " + ", ".join(
              f"{k[4:]} {v['best_law']}" for k, v in law["per_file"].items())
          + ("" if "amplitude_damping" not in params else
             f"; in the model: zeta = c A_tip with c {params['amplitude_damping']:.4g} 1/m"))
    if "clamp_mass_fit" in params:
        cm = params["clamp_mass_fit"]
        print(f"clamp payload {cm['value']:.3g} kg fitted (per file {cm['interval'][0]:.3g}-{cm['interval'][1]:.3g}; "
              f"band residual {cm['residual_rms_without']:.3g} -> {cm['residual_rms_with']:.3g} N m on the fit files)")
    if "numerics" in summary:
        num = summary["numerics"]
        print(f"numerical damping ratio {num['numerical_damping_ratio']:.2g} (implicit Euler "
              f"{num['implicit_euler_damping_ratio']:.2g}); frequency vs n {num['convergence_n']}: "
              + ", ".join(f"{f:.4f}" for f in num["convergence_frequency_hz"])
              + f" Hz, order {num['observed_order']:.2f}")
    ran = summary["model"]["strip_models_run"]
    print(f"strip model ({args.strip_model}) per predicted file: "
          + "; ".join(f"{k} {', '.join(v)}" for k, v in ran.items() if v))
    for name, f in summary["files"].items():
        for w in f["warnings"]:
            print(f"warning: {name}: {w.removeprefix('warning: ')}")
    print("limits of the match: " + "; ".join(summary["limits"]))
    print_outputs(out, *plots)
    return 0


def cmd_deform(args: argparse.Namespace) -> int:
    from bullet_dlo.reality import deform

    return int(deform.main(args) or 0)


def add_deform_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``bullet-dlo validate deform`` (:func:`bullet_dlo.reality.deform.main` reads them). Here, not
    beside it: building the command line's parser then imports no fit code (SciPy's optimisers and splines, about
    0.3 s in every ``bullet-dlo`` process)."""
    parser.add_argument("dlo_dir", metavar="DLO_DIR", help="folder with train/ and eval/ of DEFORM *.pkl trials")
    parser.add_argument("--json", required=True, metavar="OUT", help="output JSON file")
    parser.add_argument("--plots", metavar="DIR", help="folder for the PNG plots (default: OUT's folder)")
    parser.add_argument("--no-plots", action="store_true", help="write no plots")
    parser.add_argument("--n-masses", type=int, help="point masses of the model (default 21)")
    parser.add_argument("--dt", type=float, help="time step [s], in [1e-5, 0.01] (default 0.002)")
    parser.add_argument("--integrator", choices=["bdf2", "implicit_midpoint", "implicit_euler"],
                        help="core integrator (default bdf2: numerical damping ~1 %% of the fitted; implicit_euler "
                             "~10 %%)")
    parser.add_argument("--twist", action="store_true",
                        help="give the cable the core's material frame (twist springs; the clamps' roll by "
                             "parallel transport of the held pairs: a marker pair does not fix it)")
    parser.add_argument("--max-train-trials", type=int, default=8,
                        help="train trials the fit uses, evenly spread over the folder, >= 2 (8)")
    parser.add_argument("--max-eval-trials", type=int, help="eval trials predicted (default: all)")
    parser.add_argument("--max-evaluations", type=int, default=60,
                        help="forward runs of the train set allowed, about (60)")
    parser.add_argument("--intervals", default="linearised", choices=["linearised", "refit"],
                        help="leave-one-trial-out intervals: linearised (one Gauss-Newton step per trial left "
                             "out, no runs) or refit (each left-out fit rerun from the optimum; N x the fit's cost)")
    parser.add_argument("--rest-shape", action="store_true",
                        help="also fit a curved rest shape (rest curvature at the free markers' places, the energy "
                             "1/2 k (beta - beta0)^2 of a cable that keeps a set) and predict with it; the straight "
                             "model's results are written beside it")
    parser.add_argument("--fit-gravity-tilt", action="store_true",
                        help="also fit gravity's direction in the motion-capture frame (two tilt angles [rad], "
                             "shared by the cable's trials); default: gravity along -z")
    parser.add_argument("--fit-drag", action="store_true",
                        help="also fit quadratic air drag, drag_per_mass = 1/2 rho_air C_d d / (rho A) [1/m]")
    parser.add_argument("--no-numerics-check", action="store_true",
                        help="skip the numerical-damping and convergence-in-n checks")


def add_parsers(sub, common: argparse.ArgumentParser) -> None:
    """``validate`` with ``beam`` and ``deform`` on ``sub`` (argparse subparsers); ``common``: shared options."""
    s = sub.add_parser("validate", help="the model against real recordings (beam_handling forces, DEFORM shapes)",
                       description="Fit on some real recordings, predict others, report measured vs predicted. "
                                   "Data: the public beam_handling and DEFORM recordings (../shared/data).")
    vsub = s.add_subparsers(dest="validate_command", required=True, metavar="DATASET")
    b = vsub.add_parser("beam", parents=[common], help="a Panda carrying a steel strip: residual vibration in the "
                        "joint torques", description=(
                            "Fit the strip's damping on the beam_handling CSVs of FIT_DIR, predict each CSV of "
                            "PREDICT_DIR from its measured joint trajectory (nominal material: 0.52 x 0.08 x 0.001 m "
                            "steel; two superposed planar runs, or one rectangle-section twisting cable). Per "
                            "file: the most affected joint's residual vibration, measured and predicted (frequency and "
                            "damping ratio of a damped sine over [end + 1 s, end + 6 s], peak-to-peak of the 1.5-8 Hz band "
                            "over [end + 1 s, end + 2 s], the amplitude of a sine at the signal's frequency fitted over "
                            "the same window (the mode's level without the band's other content), RMS torque error). "
                            "Writes the JSON, one PNG per predicted file beside it (OUT_STEM.<csv stem>.png), and "
                            "prints a table with how many files meet each goal."))
    b.add_argument("fit_dir", metavar="FIT_DIR", help="folder of beam_handling *.csv recordings to fit the damping on")
    b.add_argument("predict_dir", metavar="PREDICT_DIR", help="folder of beam_handling *.csv recordings to predict")
    b.add_argument("--json", required=True, metavar="OUT", help="output JSON file (plots are written beside it)")
    b.add_argument("--damping", default="damping_rate", choices=["damping_rate", "internal_damping"],
                   help="the damping parameter fitted: damping_rate [1/s] (mass-proportional drag, default) or "
                        "internal_damping [s] (Kelvin-Voigt)")
    b.add_argument("--drag-coefficient", default="off", metavar="{off,fit,C_D}",
                   help="quadratic air drag on the strip's face, 1/2 rho_air C_d w |v_n| v_n per length (rho_air "
                        "1.204 kg/m^3): off (default), fit (C_d fitted on FIT_DIR together with damping_rate, from "
                        "the damping's amplitude dependence over windows of each decay) or a value C_d [-] in "
                        "[0, 1000] held while the damping is fitted")
    b.add_argument("--amplitude-damping", default="off", metavar="{off,law,C}",
                   help="the measured amplitude-dependent damping zeta = c A_tip (A_tip the strip's tip amplitude [m]) "
                        "in the strip's bending dampers, set each step from the current amplitude: off (default), law "
                        "(c from the drag law zeta0 + c A fitted across FIT_DIR's decay envelopes, from the "
                        "recordings alone, then held while --damping is fitted with it) or a slope c [1/m] in [0, 10]; "
                        "needs --arm compliant or loop and the planes' weak run (--strip-model planes or auto)")
    b.add_argument("--clamp-mass", default="off", metavar="{off,fit,KG}",
                   help="a rigid payload at the clamp (the clamp hardware) that Franka's estimate does not know: its "
                        "weight change and inertia m (g - a) join the predicted torques; off (default), fit (fitted on "
                        "FIT_DIR by linear least squares of the 1.5-8 Hz torque residual over the whole recordings, "
                        "then held) or a mass [kg] in [0, 10]")
    b.add_argument("--arm", choices=["measured", "compliant", "loop"],
                   help="how the strip's clamp moves: compliant (default: the strip on the arm's joint impedance K, D "
                        "identified on FIT_DIR from tau_J against q - q_d, stepped together with the strip about the "
                        "measured path, so that the model strip's load moves the arm where it differs from the real "
                        "strip's); measured (the flange path of the measured joint angles); loop (the compliant arm in "
                        "the full loop driven by q_d)")
    b.add_argument("--arm-dir", metavar="DIR", help="with --arm compliant/loop: identify the arm's joint impedance on "
                   "the beam_handling *.csv of DIR instead of FIT_DIR (it uses tau_J and q - q_d only; Z motions alone "
                   "leave joints 0 and 2 unidentified, and they are then held rigid)")
    b.add_argument("--strip-model", default="rectangle", choices=["rectangle", "auto", "planes"],
                   help="rectangle (default): one 3-D run of a rectangle-section cable with twist, clamped with the "
                        "flange's orientation, whatever the flange does; planes: two superposed planar runs of an "
                        "isotropic cable, one per bending plane, each keeping the start pose's axes (within 3 %% of "
                        "the rectangle on the nine recordings, about 15 %% cheaper); auto: per recording, the planes "
                        "while the flange turns out of the weak plane by at most 1 degree, the rectangle beyond; each "
                        "file's JSON entry says which ran and why")
    b.add_argument("--integrator", default="bdf2", choices=["bdf2", "implicit_euler", "implicit_midpoint"],
                   help="core integrator (bdf2: its numerical damping is measured and reported; implicit_euler "
                        "adds ~0.009, as much as the physical damping; implicit_midpoint rings)")
    b.add_argument("--n-masses", type=int, default=20, help="point masses of the strip model, in [4, 400] (20)")
    b.add_argument("--dt", type=float, help="time step [s], in [1e-5, 0.01] (default 1e-3 for both strip models: BDF2 "
                   "solves the rectangle's twist in its Newton step, converged at 1 ms)")
    b.add_argument("--knot-step", type=float, default=0.004,
                   help="spacing of the flange-path waypoints taken from the recording [s], in [0.001, 0.1] (0.004)")
    b.add_argument("--youngs-modulus", type=float, default=197.5e9,
                   help="strip's E [Pa], in [1e3, 1e13] (197.5e9, nominal)")
    b.add_argument("--fit-youngs-modulus", action="store_true",
                   help="also fit E on FIT_DIR: scaled so that the undamped model's residual-vibration frequency "
                        "matches the fit recordings' (median), starting from --youngs-modulus")
    b.add_argument("--density", type=float, default=7970.0,
                   help="strip's density [kg/m^3], in [1, 1e5] (7970, nominal)")
    b.add_argument("--filter-cutoff", type=float, help="Franka estimate filter: low-pass cut-off [Hz], in [0.1, 500] "
                   "(with --filter-delay; default: identified on FIT_DIR from tau_J)")
    b.add_argument("--filter-delay", type=float, help="Franka estimate filter: delay [s], in [0, 0.1]")
    b.add_argument("--duration", type=float, help="simulated seconds per predicted file, >= 7 (default: the whole "
                   "recording)")
    b.add_argument("--limit-files", type=int, help="use only the first N >= 1 files of each folder (quick checks)")
    b.add_argument("--no-plots", action="store_true", help="do not write the PNG plots")
    b.add_argument("--no-numerics-check", action="store_true",
                   help="skip the numerical-damping and convergence-in-n check of the chosen integrator, n and dt")
    b.set_defaults(func=cmd_beam)
    d = vsub.add_parser("deform", parents=[common], help="DEFORM motion capture: fit on DLO_DIR/train, predict "
                        "DLO_DIR/eval", description="Fit on DLO_DIR/train, predict every eval trial open-loop "
                        "(bullet_dlo.reality.deform).")
    add_deform_arguments(d)
    d.set_defaults(func=cmd_deform)


__all__ = ["add_deform_arguments", "add_parsers", "cmd_beam", "cmd_deform"]
