"""``bullet-dlo bench ...``: run a benchmark, print ratios, write CSV/JSON and charts."""
from __future__ import annotations

import json
import math
from dataclasses import asdict
from pathlib import Path

from bullet_dlo.bench import scenarios as bench
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.integrators import INTEGRATORS


def _warm_up() -> None:
    """Compile every kernel once so that no measured run pays for it."""
    model = bench.s3_model(6)
    for name in INTEGRATORS:
        simulate(model, name, 1e-5, 1e-4, max_records=3)


def _cheapest(rows, scenario, tol):
    """Cheapest stable point per (integrator, engine) with error <= tol (None if none)."""
    out = {}
    for r in rows:
        if r.scenario == scenario and r.stable and r.error <= tol:
            key = (r.integrator, r.engine)
            if key not in out or r.wall_per_sim_s < out[key].wall_per_sim_s:
                out[key] = r
    return out


def work_precision(args) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    _warm_up()
    masses = (10, 20) if args.quick else (10, 20, 40)
    rows = bench.work_precision(masses=masses, quick=args.quick)
    bullet_rows = bench.work_precision(scenarios=("S1", "S3"), integrators=("implicit_euler", "bdf2"),
                                       masses=(10,) if args.quick else (10, 20, 40), engines=("bullet",),
                                       quick=True)
    rows += bullet_rows
    peers = []
    peers_file = out / "peers.json"
    if peers_file.is_file():
        peers = json.loads(peers_file.read_text()).get("points", [])
    bench.write_csv(rows, out / "work_precision.csv")
    bench.plot_work_precision(rows, out / "work_precision.png", peers)
    print(f"{len(rows)} runs ({sum(not r.stable for r in rows)} unstable, marked x) -> {out / 'work_precision.png'}")
    print("\ncheapest configuration reaching 1 % (wall time per simulated second):")
    summary = {}
    for sc in ("S1", "S2"):
        for (name, engine), r in sorted(_cheapest(rows, sc, 0.01).items()):
            print(f"  {sc} {name:18s} {engine:6s} n={r.n:3d} dt={r.dt:.3g}s error={r.error:.4f} "
                  f"cost={r.wall_per_sim_s:.4g} s")
            summary[f"{sc}/{name}/{engine}"] = asdict(r)
    print("\namplitude kept after 1 s in S2 at 1 kHz (n = 20; 1 = no numerical damping):")
    for r in rows:
        if r.scenario == "S2" and r.n == 20 and r.engine == "core" and abs(r.dt - 1e-3) < 1e-12 and r.stable:
            print(f"  {r.integrator:18s} {r.extra:.3f}")
            summary[f"S2_amplitude/{r.integrator}"] = r.extra
    (out / "work_precision_summary.json").write_text(json.dumps(summary, indent=2, default=float))
    return 0


def stability(args) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    moduli = (1e6, 1e8, 1e10) if args.quick else (1e6, 1e7, 1e8, 1e9, 1e10)
    rows = bench.stability_map(moduli, (10,) if args.quick else (10, 40))
    (out / "stability.json").write_text(json.dumps(rows, indent=2))
    bench.plot_stability_map(rows, out / "stability.png")
    print(f"{'E [Pa]':>8s} {'n':>3s} {'integrator':18s} {'predicted [s]':>14s} {'measured [s]':>13s}")
    for r in rows:
        pred = "-" if r["predicted"] is None else f"{r['predicted']:.4g}"
        meas = "unstable" if r["measured"] is None else f"{r['measured']:.4g}"
        if r["predicted"] is None and r["measured"] is not None:
            meas = "stable at 1 ms and 1/60 s"
        print(f"{r['youngs_modulus']:8.0e} {r['n_masses']:3d} {r['integrator']:18s} {pred:>14s} {meas:>13s}")
    print(f"-> {out / 'stability.png'}")
    return 0


def scaling(args) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    masses = (50, 100, 200) if args.quick else (50, 100, 200, 500, 1000)
    rows, exponent = bench.implicit_scaling(masses)
    for r in rows:
        print(f"  n={r['n_masses']:5d}: {1e6 * r['seconds_per_step']:.1f} us per implicit Euler step")
    print(f"cost ~ n^{exponent:.2f}")
    (out / "scaling.json").write_text(json.dumps({"rows": rows, "exponent": exponent}, indent=2))
    return 0


def resolve_check(args) -> int:
    """resolve() on S1, S3 and S4 as scenes, checked against their references."""
    from bullet_dlo.analysis.resolve import resolve
    from bullet_dlo.config.scene import Scene

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tol = 0.05 if args.quick else 0.01
    cases = {
        "S1": (Scene(cable=bench.s1_spec(10), ends=("clamped", "free"), duration=1.0, name="S1"), "shape", bench.s1),
        "S3": (Scene(cable=bench.s3_model(10).spec, motion=bench.s3_model(10).last.moves, duration=0.6,
                     initial="static", name="S3"), "forces", bench.s3),
        "S4": (Scene(cable=bench.s4_model(10).spec, ends=("pinned", "pinned"),
                     motion=bench.s4_model(10).last.moves, duration=2.0, name="S4"), "both", bench.s4),
    }
    results = {}
    for name, (scene, target, runner) in cases.items():
        r = resolve(scene, tol, target)
        check = runner(r.n_masses, r.integrator, r.dt)
        results[name] = dict(r.to_dict(), measured_error=check.error, meets=bool(check.error <= tol))
        print(f"{name}: n={r.n_masses} {r.integrator} dt={r.dt:.4g}s predicted {r.predicted_error:.4f}, "
              f"measured against the reference {check.error:.4f} (tol {tol}): {'ok' if check.error <= tol else 'MISSED'}")
    (out / "resolve.json").write_text(json.dumps(results, indent=2, default=float))
    return 0


def peers(args) -> int:
    from bullet_dlo.bench import peers as peer_mod

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    avail = peer_mod.available()
    print("peers available:", avail)
    _warm_up()
    spec = bench.s1_spec(10)  # the stiff cantilever of S1/S2: tip deflects 1e-3 L, f1 = 36 Hz
    L, d, M, E = spec.length, spec.diameter, spec.mass, spec.youngs_modulus
    f1 = bench.cantilever_frequency(spec)
    delta = bench.cantilever_deflection(spec)
    points = []
    # both peers clamp the whole first segment (-2/n of the tip deflection), so 1 % needs n ~ 200
    ns = (10, 20) if args.quick else (10, 40, 120, 250)
    configs = [("pyelastica", "PositionVerlet", 5e-7)]  # stable up to ~5e-7 s for this stiff rod
    configs += [("mujoco", "discrete", 1e-3), ("mujoco", "RK4", 1e-4)]
    for peer, integ, dt in configs:
        fn = getattr(peer_mod, f"run_{peer}", None)
        if not avail.get(peer) or fn is None:
            continue
        for n in ns:
            if peer == "pyelastica" and n > 120 and args.quick:
                continue
            for mode, sc in (("static", "S1"), ("free", "S2")):
                kwargs = {"integrator": integ} if peer == "mujoco" else {}
                dur = 0.1 if mode == "static" else 0.15  # free: ~5 periods of the 36 Hz mode
                try:
                    res = fn(L, d, M, E, n, dt, mode, dur, **kwargs)
                except Exception as err:  # noqa: BLE001 - a peer failing is a result
                    print(f"  {peer} {integ} n={n} dt={dt:g} {mode}: failed ({err})")
                    continue
                err = None
                if res.stable and mode == "static" and res.tip_deflection is not None:
                    err = abs(res.tip_deflection / delta - 1)
                if res.stable and mode == "free" and res.frequency:
                    err = abs(res.frequency / f1 - 1)
                cost = res.wall_time_s / max(res.sim_time_s, 1e-12)
                points.append(dict(label=f"{peer} ({integ})", peer=peer, integrator=integ, scenario=sc, n=n, dt=dt,
                                   stable=res.stable, error=err, wall_per_sim_s=cost,
                                   amplitude_kept=res.amplitude_kept, note=res.note))
                print(f"  {peer:10s} {integ:14s} {sc} n={n:3d} dt={dt:.0e} stable={res.stable} error="
                      f"{'-' if err is None else f'{err:.4f}'} amplitude={res.amplitude_kept} cost={cost:.4g} s/s",
                      flush=True)
    (out / "peers.json").write_text(json.dumps({"points": points}, indent=2, default=float))
    # ours: fastest configuration at 1 % on S1 and on S2's frequency
    ours = {}
    for sc, runner in (("S1", bench.s1), ("S2", bench.s2)):
        best = None
        for n in (10, 20, 40):
            for name in ("implicit_euler", "bdf2", "implicit_midpoint"):
                for dt in (1 / 60, 1 / 240, 1e-3):
                    p = runner(n, name, dt)
                    if p.stable and p.error <= 0.01 and (best is None or p.wall_per_sim_s < best.wall_per_sim_s):
                        best = p
        ours[sc] = best
        if best:
            print(f"ours {sc}: {best.integrator} n={best.n} dt={best.dt:.3g}: error {best.error:.4f}, "
                  f"{best.wall_per_sim_s:.4g} s/s")
    ratios = {}
    for peer in ("pyelastica", "mujoco"):
        for sc in ("S1", "S2"):
            ok = [p for p in points if p["peer"] == peer and p["scenario"] == sc and p["stable"] and p["error"] is not None
                  and p["error"] <= 0.01]
            if ok and ours.get(sc):
                cheapest = min(p["wall_per_sim_s"] for p in ok)
                ratios[f"{peer}/{sc}"] = cheapest / ours[sc].wall_per_sim_s
                print(f"equal accuracy (1 %) on {sc}: {peer} needs {ratios[f'{peer}/{sc}']:.0f}x our wall time")
            else:
                best_err = min([p["error"] for p in points if p["peer"] == peer and p["scenario"] == sc
                                and p["error"] is not None] or [math.nan])
                print(f"equal accuracy (1 %) on {sc}: {peer} did not reach 1 % in this sweep (best {best_err:.3f})")
    (out / "peers.json").write_text(json.dumps({"points": points, "ratios": ratios,
                                                "ours": {k: (asdict(v) if v else None) for k, v in ours.items()}},
                                               indent=2, default=float))
    return 0


COMMANDS = {"work-precision": work_precision, "stability": stability, "scaling": scaling, "resolve": resolve_check,
            "peers": peers}


def run(args) -> int:
    return COMMANDS[args.bench_command](args)
