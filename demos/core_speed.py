"""Core engine speed: wall time per simulated second for each integrator and cable size.

Runs the study's scenario (clamped-clamped Lv cable, 5 mm move) at 1 kHz for the implicit
methods and at 0.9x the predicted critical step for the explicit ones, after a warm-up run
(so Numba compilation is not counted). Prints a table and ratios against implicit Euler at
the same n (ratios are what to trust on a noisy machine), and writes ``core_speed.json`` and
``core_speed.png`` into the output folder.

Usage: ``python demos/core_speed.py [--out DIR] [--masses 10 100] [--repeats 3]``
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from bullet_dlo.core.boundary import Move  # noqa: E402
from bullet_dlo.core.engine import simulate  # noqa: E402
from bullet_dlo.core.integrators import INTEGRATORS  # noqa: E402
from bullet_dlo.core.model import CableModel  # noqa: E402
from bullet_dlo.core.spec import CableSpec  # noqa: E402
from bullet_dlo.core.stability import critical_dt  # noqa: E402


def measure(model: CableModel, integrator: str, dt: float, duration: float, repeats: int) -> float:
    """Median wall time per simulated second [s/s] over ``repeats`` runs (after one warm-up)."""
    simulate(model, integrator, dt, 20 * dt, max_records=3)
    times = []
    for _ in range(repeats):
        res = simulate(model, integrator, dt, duration, max_records=3)
        times.append(res.wall_time_s / (res.steps * dt))
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join("out", "core_speed"), help="output folder")
    parser.add_argument("--masses", nargs="+", type=int, default=[10, 100], help="cable sizes n")
    parser.add_argument("--repeats", type=int, default=3, help="repeats per measurement (median)")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for n in args.masses:
        spec = CableSpec.lv2017(n_masses=n, damping=0.01)
        model = CableModel.straight(spec, ends=("clamped", "clamped"), motion=[Move("last", (0, 0, 0.005), 0.1, 0.1)])
        base = None
        for name, integ in INTEGRATORS.items():
            crit = critical_dt(model, name)
            if integ.explicit and (crit is None or crit < 1e-6):
                continue  # explicit Euler: limit below a microsecond, not worth timing
            dt = 1e-3 if crit is None else 0.9 * crit
            duration = min(1.0, 2000 * dt)
            per_s = measure(model, name, dt, duration, args.repeats)
            if name == "implicit_euler":
                base = per_s
            rows.append(dict(n_masses=n, integrator=name, dt=dt, wall_time_per_sim_s=per_s))
        for r in rows:
            if r["n_masses"] == n:
                r["ratio_to_implicit_euler"] = r["wall_time_per_sim_s"] / base
    print(f"{'n':>4s} {'integrator':18s} {'dt [s]':>10s} {'wall/sim-s [s]':>15s} {'x implicit Euler':>17s}")
    for r in rows:
        print(f"{r['n_masses']:4d} {r['integrator']:18s} {r['dt']:10.3g} {r['wall_time_per_sim_s']:15.4g} "
              f"{r['ratio_to_implicit_euler']:17.2f}")
    fig, ax = plt.subplots(figsize=(6, 4))
    for name in INTEGRATORS:
        pts = [(r["n_masses"], r["wall_time_per_sim_s"]) for r in rows if r["integrator"] == name]
        if pts:
            ax.loglog(*zip(*pts), "o-", label=name)
    ax.set_xlabel("number of masses n")
    ax.set_ylabel("wall time per simulated second [s]")
    ax.set_title("Core engine, clamped Lv cable (implicit: 1 kHz; explicit: 0.9 x limit)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "core_speed.png", dpi=120)
    (out / "core_speed.json").write_text(json.dumps(rows, indent=2))
    print(f"\noutputs written to {out.resolve()}")


if __name__ == "__main__":
    main()
