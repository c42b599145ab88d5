"""``bullet-dlo bench ...``: run a benchmark, print what it found, write CSV/JSON and charts into ``--out``.

Progress and ETA go to stderr (:func:`bullet_dlo.cli.quiet.bar`); ``--quiet`` leaves only the results.
"""
from __future__ import annotations

import argparse
import json
import os
from dataclasses import asdict
from pathlib import Path

from bullet_dlo.bench import peers as peer_mod
from bullet_dlo.bench import plots, sweeps
from bullet_dlo.bench.scenarios import s1, s1_spec, s3_model, s3_wrench_error, s4, s4_model
from bullet_dlo.cli.quiet import bar
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.integrators import INTEGRATORS

TOL = 0.01  # "equal accuracy": 1 % relative error


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options every bench command takes."""
    parser.add_argument("--out", default=os.path.join("out", "bench"), help="output folder (default out/bench)")
    parser.add_argument("--quick", action="store_true", help="a few points only (seconds to minutes; for CI)")
    parser.add_argument("--quiet", action="store_true", help="no progress bars, only the results")


def _progress(args, desc: str, unit: str = "run"):
    """A sweep's ``progress`` argument: its items, with a bar and ETA on stderr unless --quiet."""

    def wrap(items):
        with bar(len(items), desc, bool(getattr(args, "quiet", False)), unit) as progress_bar:
            for item in items:
                yield item
                progress_bar.update()

    return wrap


def _out(args) -> Path:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    return out


def _warm_up() -> None:
    """Compile every kernel once so that no measured run pays for it."""
    model = s3_model(6)
    for name in INTEGRATORS:
        simulate(model, name, 1e-5, 1e-4, max_records=3)


def work_precision(args) -> int:
    out = _out(args)
    _warm_up()
    quick = args.quick
    cases = sweeps.work_precision_cases(n_masses=(10, 20) if quick else (10, 20, 40), quick=quick)
    cases += sweeps.work_precision_cases(scenarios=("S1", "S3"), integrators=("implicit_euler", "bdf2"),
                                         n_masses=(10,) if quick else (10, 20, 40), engines=("bullet",), quick=True)
    rows = sweeps.work_precision(cases, _progress(args, "work-precision"))
    peers_file = out / "peers.json"
    peer_points = json.loads(peers_file.read_text()).get("points", []) if peers_file.is_file() else []
    sweeps.write_csv(rows, out / "work_precision.csv")
    png = plots.plot_work_precision(rows, out / "work_precision.png", peer_points)
    print(f"{len(rows)} runs ({sum(not r.stable for r in rows)} unstable, marked x) -> {png}")
    print(f"\ncheapest configuration reaching {TOL:.0%} (wall time per simulated second):")
    summary = {}
    for sc in ("S1", "S2"):
        for (name, engine), r in sorted(sweeps.cheapest(rows, sc, TOL).items()):
            print(f"  {sc} {name:18s} {engine:6s} n={r.n:3d} dt={r.dt:.3g}s error={r.error:.4f} "
                  f"cost={r.wall_per_sim_s:.4g} s")
            summary[f"{sc}/{name}/{engine}"] = asdict(r)
    print("\namplitude kept over the last period of S2 at 1 kHz (n = 20; 1 = no numerical damping):")
    for r in rows:
        if r.scenario == "S2" and r.n == 20 and r.engine == "core" and abs(r.dt - 1e-3) < 1e-12 and r.stable:
            print(f"  {r.integrator:18s} {r.extra:.3f}")
            summary[f"S2_amplitude/{r.integrator}"] = r.extra
    (out / "work_precision_summary.json").write_text(json.dumps(summary, indent=2, default=float))
    return 0


def stability(args) -> int:
    out = _out(args)
    moduli = (1e6, 1e8, 1e10) if args.quick else (1e6, 1e7, 1e8, 1e9, 1e10)
    rows = sweeps.stability_map(moduli, (10,) if args.quick else (10, 40),
                                progress=_progress(args, "stability", "cable"))
    (out / "stability.json").write_text(json.dumps(rows, indent=2))
    png = plots.plot_stability_map(rows, out / "stability.png")
    rates = " and ".join(f"{dt:.3g} s" for dt in sweeps.ROBOT_DTS)
    print(f"{'E [Pa]':>8s} {'n':>3s} {'integrator':18s} {'predicted [s]':>14s} {'measured [s]':>13s}")
    for r in rows:
        pred = "-" if r["predicted"] is None else f"{r['predicted']:.4g}"
        meas = "unstable" if r["measured"] is None else f"{r['measured']:.4g}"
        if r["predicted"] is None and r["measured"] is not None:
            meas = f"stable at {rates}"
        print(f"{r['youngs_modulus']:8.0e} {r['n_masses']:3d} {r['integrator']:18s} {pred:>14s} {meas:>13s}")
    print(f"-> {png}")
    return 0


def scaling(args) -> int:
    """Cost vs n: the core's implicit solve, then a cable lying on a table in Bullet with contact on (the
    model's), CPU time per simulated second, interleaved repeats; the machine's load is printed beside."""
    out = _out(args)
    n_masses = (50, 100, 200) if args.quick else (50, 100, 200, 500, 1000)
    rows, exponent = sweeps.implicit_scaling(n_masses, progress=_progress(args, "scaling", "cable"))
    for r in rows:
        print(f"  n={r['n_masses']:5d}: {1e6 * r['seconds_per_step']:.1f} us per implicit Euler step")
    print(f"cost ~ n^{exponent:.2f}")
    coupled_n = (50, 100, 200) if args.quick else (100, 200, 500, 1000)
    load = os.getloadavg()
    coupled, exps = sweeps.coupled_scaling(coupled_n, repeats=2 if args.quick else 5,
                                           sim_time=0.05 if args.quick else 0.1,
                                           progress=_progress(args, "scaling in Bullet", "cable"))
    load_end = os.getloadavg()
    print(f"\ncable lying on a table in Bullet, contact on (model), implicit Euler at 240 Hz: thread CPU time per "
          f"simulated second, median (range) of interleaved repeats; load {load[0]:.2f} / {load[1]:.2f} / "
          f"{load[2]:.2f} at the start, {load_end[0]:.2f} / {load_end[1]:.2f} / {load_end[2]:.2f} at the end")
    for r in coupled:
        print(f"  n={r['n_masses']:5d}: {r['cost']:.4g} s ({r['cost_min']:.4g}-{r['cost_max']:.4g}); Bullet's step "
              f"{r['bullet']:.4g} s, the cable's side {r['model']:.4g} s")
    print(f"cost ~ n^{exps['cost']:.2f} from n = {coupled_n[0]} to {coupled_n[-1]} (Bullet's step ~ n^{exps['bullet']:.2f}, "
          f"the cable's side ~ n^{exps['model']:.2f})")
    png = plots.plot_scaling(rows, exponent, coupled, exps, out / "scaling.png")
    print(f"-> {png}")
    (out / "scaling.json").write_text(json.dumps({"rows": rows, "exponent": exponent, "coupled": coupled,
                                                  "coupled_exponents": exps, "load_start": load,
                                                  "load_end": load_end}, indent=2))
    return 0


def resolve_check(args) -> int:
    """resolve() on S1, S3 and S4 as scenes, checked against their references."""
    from bullet_dlo.analysis.resolve import resolve
    from bullet_dlo.config.scene import Scene
    from bullet_dlo.sim import resolve_problem

    out = _out(args)
    tol = 0.05 if args.quick else TOL
    cases = {
        "S1": (Scene(cable=s1_spec(10), ends=("clamped", "free"), duration=1.0, name="S1"), "shape",
               lambda *a: s1(*a).error),
        # (target forces: the clamps' moments too, as resolve judges them)
        "S3": (Scene(cable=s3_model(10).spec, motion=s3_model(10).last.moves, duration=0.6, initial="static",
                     name="S3"), "forces", s3_wrench_error),
        "S4": (Scene(cable=s4_model(10).spec, ends=("pinned", "pinned"), motion=s4_model(10).last.moves,
                     duration=2.0, name="S4"), "both", lambda *a: s4(*a).error),
    }
    results, lines = {}, []
    for name in _progress(args, "resolve", "scene")(list(cases)):
        scene, target, measured = cases[name]
        r = resolve(resolve_problem(scene), tol, target)
        error = measured(r.n_masses, r.integrator, r.dt)
        meets = bool(error <= tol)
        results[name] = dict(r.to_dict(), measured_error=error, meets=meets)
        lines.append(f"{name}: n={r.n_masses} {r.integrator} dt={r.dt:.4g}s predicted {r.predicted_error:.4f}, "
                     f"measured against the reference {error:.4f} (tol {tol}): {'ok' if meets else 'MISSED'}")
    print("\n".join(lines))
    (out / "resolve.json").write_text(json.dumps(results, indent=2, default=float))
    return 0


def peers(args) -> int:
    """PyElastica, MuJoCo and Newton (CPU) on S1 and S2 next to our cheapest run at 1 %, timed in thread
    CPU time, interleaved (:func:`bullet_dlo.bench.peers.bench_peers`); MuJoCo's warnings go to
    ``peers_warnings.log`` in the output folder and are counted per point in ``peers.json``."""
    _warm_up()
    peer_mod.bench_peers(_out(args), args.quick, lambda desc: _progress(args, desc))
    return 0


COMMANDS = {"work-precision": work_precision, "stability": stability, "scaling": scaling, "resolve": resolve_check,
            "peers": peers}


def run(args) -> int:
    return COMMANDS[args.bench_command](args)
