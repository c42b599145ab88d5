"""MuJoCo / ours at 1 % on S1 and S2, only the selected runs (the last stage of ``bullet-dlo bench peers``, without
its 24-minute sweep): interleaved pairs of timing runs, thread CPU time (:func:`bullet_dlo.bench.peers.interleaved_ratio`).

The runs are the cheapest within 1 % found by the sweep (``bullet-dlo bench peers``, 2026-11-29; docs/results/speed.md):
S1, ours implicit Euler at n = 12 and 1/60 s against MuJoCo's joint chain (``discrete chain``) at n = 12 and 1/60 s and
its flexcomp (``discrete``) at n = 12 and 1/60 s; S2, ours Gauss-Legendre at n = 12 and 5 ms against the chain at
n = 10 and 5e-4 s and the flexcomp at n = 16 and 5e-4 s. Each side's cost is that of the whole call per simulated second
(ours: ``simulate`` with its set-up; the peer: its timed phase), as ``bench peers`` reports it; the cost per step is that
times dt. ``PYTHONPATH=TREE`` measures another source tree of ours the same way (interleave trees for an A/B).

Usage: ``python demos/peer_ratio.py [--reps 7] [--only S1|S2] [--tight]`` (``--tight``: the runs within 0.1 %)
"""
from __future__ import annotations

import argparse
import os

from bullet_dlo.bench.peers import PeerCase, interleaved_ratio
from bullet_dlo.bench.scenarios import s1_spec

RUNS = (("S1", dict(scenario="S1", integrator="implicit_euler", n=12, dt=1 / 60), ("discrete chain", 1 / 60, 12)),
        ("S1", dict(scenario="S1", integrator="implicit_euler", n=12, dt=1 / 60), ("discrete", 1 / 60, 12)),
        ("S2", dict(scenario="S2", integrator="gauss_legendre", n=12, dt=5e-3), ("discrete chain", 5e-4, 10)),
        ("S2", dict(scenario="S2", integrator="gauss_legendre", n=12, dt=5e-3), ("discrete", 5e-4, 16)))
"""(scenario, our run, MuJoCo's (integrator, dt [s], n)): the cheapest runs within 1 %."""
RUNS_TIGHT = (("S1", dict(scenario="S1", integrator="implicit_euler", n=40, dt=1 / 60), ("discrete chain", 1 / 60, 40)),
              ("S2", dict(scenario="S2", integrator="gauss_legendre", n=40, dt=3e-3), ("discrete chain", 2e-4, 40)))
"""The same within 0.1 % (``bench peers``, 2026-12-03; docs/results/speed.md): the joint chain only."""


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--reps", type=int, default=7, help="interleaved pairs per run (>= 1)")
    p.add_argument("--only", choices=("S1", "S2"), default=None)
    p.add_argument("--tight", action="store_true", help="the runs within 0.1 %% instead of 1 %%")
    a = p.parse_args(argv)
    if a.reps < 1:
        p.error("--reps must be >= 1")
    spec = s1_spec(10)  # as bench peers: each run sets its own n
    load0 = os.getloadavg()
    print(f"MuJoCo / ours, thread CPU per simulated second, median (range) of {a.reps} interleaved pairs; "
          f"load {load0[0]:.2f} / {load0[1]:.2f} / {load0[2]:.2f}")
    for sc, ours, (integ, dt, n) in (RUNS_TIGHT if a.tight else RUNS):
        if a.only and sc != a.only:
            continue
        case = PeerCase("mujoco", integ, dt, n, sc)
        interleaved_ratio(ours, case, spec, 1)  # compile / load, warm caches
        r = interleaved_ratio(ours, case, spec, a.reps)
        print(f"  {sc} ours {ours['integrator']} n={ours['n']} dt={ours['dt']:.4g}: "
              f"{r['ours_cpu_per_sim_s']:.4g} s/s ({1e6 * r['ours_cpu_per_sim_s'] * ours['dt']:.1f} us/step); "
              f"MuJoCo {integ} n={n} dt={dt:.4g}: {r['peer_cpu_per_sim_s']:.4g} s/s "
              f"({1e6 * r['peer_cpu_per_sim_s'] * dt:.1f} us/step); "
              f"ratio {r['ratio_median']:.2f}x ({r['ratio_min']:.2f}-{r['ratio_max']:.2f})")
    load1 = os.getloadavg()
    print(f"load at the end {load1[0]:.2f} / {load1[1]:.2f} / {load1[2]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
