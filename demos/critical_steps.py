"""Predicted vs measured critical time steps of the explicit integrators.

For the study's scenario (Lv cable, clamped at both ends, settled, last end moved 5 mm,
k_d = 0.01 N s/m) the predicted critical step of symplectic Euler and RK4 (linear analysis,
``critical_dt``) is compared with the largest stable step found by bisection on short runs
(``measured_critical_dt``). Writes ``critical_steps.md`` and ``critical_steps.json``.

Usage: ``python demos/critical_steps.py [--out DIR] [--duration 0.2] [--quick]`` (``--quick``: E = 126 MPa,
n = 10, 0.1 s runs; seconds, for smoke tests).
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from bullet_dlo.analysis.study import study_model
from bullet_dlo.core.stability import critical_dt, measured_critical_dt
from bullet_dlo.core.statics import solve_static


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join("out", "critical_steps"), help="output folder")
    parser.add_argument("--duration", type=float, default=0.2, help="seconds per bisection run")
    parser.add_argument("--moduli", nargs="+", type=float, default=[126.0, 1002.6], help="E in MPa")
    parser.add_argument("--masses", nargs="+", type=int, default=[10, 40], help="numbers of masses")
    parser.add_argument("--quick", action="store_true", help="one cable (126 MPa, n = 10), 0.1 s runs (smoke test)")
    args = parser.parse_args()
    if args.quick:
        args.moduli, args.masses, args.duration = [126.0], [10], 0.1
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    lines = ["| E [MPa] | n | integrator | predicted [s] | measured [s] | measured / predicted |", "|---|---|---|---|---|---|"]
    for e in args.moduli:
        for n in args.masses:
            model = study_model(e * 1e6, n, 0.01)
            start = solve_static(model).state()
            for name in ("symplectic_euler", "rk4"):
                pred = critical_dt(model, name)
                meas = measured_critical_dt(model, name, args.duration, state=start, rel_tol=0.002)
                rows.append(dict(youngs_modulus=e * 1e6, n_masses=n, integrator=name, predicted=pred, measured=meas))
                lines.append(f"| {e:g} | {n} | {name} | {pred:.4g} | {meas:.4g} | {meas / pred:.3f} |")
                print(lines[-1], flush=True)
    (out / "critical_steps.md").write_text("\n".join(lines) + "\n")
    (out / "critical_steps.json").write_text(json.dumps(rows, indent=2))
    print(f"\noutputs written to {out.resolve()}")


if __name__ == "__main__":
    main()
