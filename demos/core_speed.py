"""Core engine speed: wall time per simulated second for each integrator and cable size.

Runs the study's scenario (clamped-clamped Lv cable, 5 mm move) at 1 kHz for the implicit
methods and at 0.9x the predicted critical step for the explicit ones, after a warm-up run
(so Numba compilation is not counted). The default run (n = 10, 100, 200) prints the
README's speed table in the same shape, with ratios against implicit Euler at the same n
(ratios are what to trust on a noisy machine), and writes ``core_speed.json`` and
``core_speed.png`` into the output folder.

Usage: ``python demos/core_speed.py [--out DIR] [--masses 10 100 200] [--repeats 3] [--quick]``
(``--quick``: n = 10, one repeat; for smoke tests).
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

IMPLICIT_RATE = 1e-3  # [s]: a robot simulator's step


def measure(model: CableModel, integrator: str, dt: float, duration: float, repeats: int) -> float:
    """Median wall time per simulated second [s/s] over ``repeats`` runs (after one warm-up)."""
    simulate(model, integrator, dt, 20 * dt, max_records=3)
    times = []
    for _ in range(repeats):
        res = simulate(model, integrator, dt, duration, max_records=3)
        times.append(res.wall_time_s / (res.steps * dt))
    return statistics.median(times)


def time_cable(n: int, repeats: int) -> list[dict]:
    """One row per timed integrator for an n-mass cable; explicit Euler (limit below 1 us) is skipped."""
    spec = CableSpec.lv2017(n_masses=n, damping=0.01)
    model = CableModel.straight(spec, ends=("clamped", "clamped"), motion=[Move("last", (0, 0, 0.005), 0.1, 0.1)])
    rows = []
    for name, integ in INTEGRATORS.items():
        crit = critical_dt(model, name)
        if integ.explicit and (crit is None or crit < 1e-6):
            continue
        dt = IMPLICIT_RATE if crit is None else 0.9 * crit
        per_s = measure(model, name, dt, min(1.0, 2000 * dt), repeats)
        rows.append(dict(n_masses=n, integrator=name, dt=dt, wall_time_per_sim_s=per_s))
    base = next(r["wall_time_per_sim_s"] for r in rows if r["integrator"] == "implicit_euler")
    for r in rows:
        r["ratio_to_implicit_euler"] = r["wall_time_per_sim_s"] / base
    return rows


def readme_table(rows: list[dict]) -> str:
    """The README's table: one row per n, implicit methods at 1 kHz, explicit ones with their step."""
    implicit = [n for n in ("implicit_euler", "bdf2", "implicit_midpoint") if any(r["integrator"] == n for r in rows)]
    explicit = [n for n in ("symplectic_euler", "rk4") if any(r["integrator"] == n for r in rows)]
    head = ["n"] + [f"{n} 1 kHz" for n in implicit] + [f"{n} (dt)" for n in explicit]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for n in dict.fromkeys(r["n_masses"] for r in rows):
        cell = {r["integrator"]: r for r in rows if r["n_masses"] == n}
        line = [str(n)] + [f"{cell[i]['wall_time_per_sim_s']:.2g} s" for i in implicit]
        line += [f"{cell[i]['wall_time_per_sim_s']:.2g} s ({cell[i]['dt']:.2g} s)" for i in explicit]
        lines.append("| " + " | ".join(line) + " |")
    return "\n".join(lines)


def plot(rows: list[dict], path: Path) -> None:
    fig, ax = plt.subplots(figsize=(8, 4.2))
    masses = sorted({r["n_masses"] for r in rows})
    for name in INTEGRATORS:
        pts = [(r["n_masses"], r["wall_time_per_sim_s"]) for r in rows if r["integrator"] == name]
        if pts:
            ax.loglog(*zip(*pts), "o-", label=name + (" (1 kHz)" if name.startswith(("implicit", "bdf")) else
                                                      " (0.9 x its limit)"))
    ax.set_xticks(masses, [str(n) for n in masses])
    ax.xaxis.set_minor_locator(plt.NullLocator())
    ax.grid(alpha=0.3, which="both")
    ax.set_xlabel("number of masses n")
    ax.set_ylabel("wall time per simulated second [s]")
    ax.set_title("Core engine, clamped Lv cable, 5 mm move")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join("out", "core_speed"), help="output folder")
    parser.add_argument("--masses", nargs="+", type=int, default=[10, 100, 200], help="cable sizes n (README: 10 100 200)")
    parser.add_argument("--repeats", type=int, default=3, help="repeats per measurement (median)")
    parser.add_argument("--quick", action="store_true", help="n = 10, one repeat (smoke test)")
    args = parser.parse_args()
    if args.quick:
        args.masses, args.repeats = [10], 1
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = [r for n in args.masses for r in time_cable(n, args.repeats)]
    print(f"{'n':>4s} {'integrator':18s} {'dt [s]':>10s} {'wall/sim-s [s]':>15s} {'x implicit Euler':>17s}")
    for r in rows:
        print(f"{r['n_masses']:4d} {r['integrator']:18s} {r['dt']:10.3g} {r['wall_time_per_sim_s']:15.4g} "
              f"{r['ratio_to_implicit_euler']:17.2f}")
    print("\nAs in the README (wall time per simulated second):\n" + readme_table(rows))
    plot(rows, out / "core_speed.png")
    (out / "core_speed.json").write_text(json.dumps(rows, indent=2))
    print(f"\noutputs written to {out.resolve()}")


if __name__ == "__main__":
    main()
