"""Cost vs n with contact on: parked proxy spheres against live ones, interleaved (issue 24 item 4).

``python -m bullet_dlo.bench.scaling`` runs the scene of ``bullet-dlo bench scaling``'s second part (a Lv cable
lying straight on the ground, contact on (the model's), implicit Euler at 240 Hz) twice per n, once with the
cable's Bullet spheres live (``bullet_spheres="live"``: Bullet moves them every step, the code before the
proxies) and once parked (``"auto"``), and times both in thread CPU time, in interleaved rounds (the order
swapped every round), so that the load of the shared machine hits both alike. The model's trajectory is the
same in both (``tests/bullet/test_proxy_spheres.py``); only Bullet's part differs.
"""
from __future__ import annotations

import argparse
import json
import os
from typing import Sequence

import numpy as np

from bullet_dlo.bench.sweeps import _timed_steps
from bullet_dlo.core.spec import CableSpec

MODES = ("live", "auto")


def _world(n: int, dt: float, mode: str):
    """The scaling scene (:func:`bullet_dlo.bench.sweeps.coupled_scaling`'s) with ``bullet_spheres=mode``."""
    from bullet_dlo.bullet.world import BulletWorld

    spec = CableSpec.lv2017(n_masses=n, damping=0.01)
    world = BulletWorld(dt=dt)
    cable = world.add_cable(spec, start=(0.0, 0.0, 0.5 * spec.diameter), record_every=10**9, bullet_spheres=mode)
    return world, cable


def spheres_ab(n_masses: Sequence[int] = (100, 200, 500, 1000), dt: float = 1.0 / 240.0, sim_time: float = 0.1,
               repeats: int = 5) -> tuple[list[dict], dict]:
    """Thread CPU time per simulated second [s] of the scaling scene, live spheres against parked proxies.

    One world per n and mode, warmed up 0.05 s; then ``repeats`` rounds, each timing ``sim_time`` [s] of steps of
    every (n, mode), the modes' order swapped every round. Rows: n_masses, mode, proxy (the cable's spheres were
    parked), cost (median total), cost_min, cost_max, bullet (median of Bullet's stepSimulation alone), model (the
    rest), all [s per s], same_state (both modes ended in the same model state, bit for bit). Also returns the
    fitted exponents p of cost ~ n^p over the range, per mode and part, and the load averages."""
    load_start = os.getloadavg()
    worlds = {}
    for n in n_masses:
        for mode in MODES:
            world, cable = _world(n, dt, mode)
            world.step(max(5, int(round(0.05 / dt))))
            worlds[n, mode] = (world, cable)
    steps = max(1, int(round(sim_time / dt)))
    sim = steps * dt
    times = {key: [] for key in worlds}
    for rep in range(repeats):
        for n in n_masses:
            for mode in MODES if rep % 2 == 0 else MODES[::-1]:
                times[n, mode].append(_timed_steps(worlds[n, mode][0], steps))
    rows = []
    for n in n_masses:
        x = {mode: worlds[n, mode][1].x for mode in MODES}
        same = bool(np.array_equal(x["live"], x["auto"]))
        for mode in MODES:
            world, cable = worlds[n, mode]
            total = np.array([t for t, _ in times[n, mode]]) / sim
            bullet = np.array([b for _, b in times[n, mode]]) / sim
            rows.append({"n_masses": n, "mode": mode, "proxy": cable.proxy, "cost": float(np.median(total)),
                         "cost_min": float(total.min()), "cost_max": float(total.max()),
                         "bullet": float(np.median(bullet)), "model": float(np.median(total - bullet)),
                         "same_state": same, "stable": cable.stable})
    for world, _ in worlds.values():
        world.close()
    exps = {}
    for mode in MODES:
        sel = [r for r in rows if r["mode"] == mode]
        logn = np.log([r["n_masses"] for r in sel])
        exps[mode] = {key: float(np.polyfit(logn, np.log([r[key] for r in sel]), 1)[0])
                      for key in ("cost", "bullet", "model")}
    return rows, {"exponents": exps, "load_start": load_start, "load_end": os.getloadavg()}


def bullet_step_after(n: int = 1000, dt: float = 1.0 / 240.0, steps: int = 48) -> dict[str, float]:
    """Thread CPU time [us] of Bullet's ``stepSimulation`` in the parked-sphere scaling scene at n masses,
    right after each of: nothing (steps back to back), the coupled step's other phases, the contact model's
    detection alone, the world's contact query, an 8 MB NumPy sum. Medians over ``steps`` steps."""
    import time

    import pybullet as pb

    world, cable = _world(n, dt, "auto")
    world.step(max(5, int(round(0.05 / dt))))
    cid, cs, cp = world.client, cable.contact.set, cable._cp
    big = np.ones(1_000_000)
    h = cable.stepper.h

    def detect():
        cs.update(cp.x_new, cp.v_new, cable.arrays.mass, h, dt, True)

    def coupled():
        world.take_cable_steps()
        world.push_cables()

    before = {"nothing": lambda: None, "the coupled step's other phases": coupled, "contact detection": detect,
              "getContactPoints": lambda: pb.getContactPoints(-1, -1, -2, -2, cid), "8 MB NumPy sum": big.sum}
    out = {}
    for name, call in before.items():
        t = []
        for _ in range(steps):
            call()
            t0 = time.thread_time()
            pb.stepSimulation(cid)
            t.append(time.thread_time() - t0)
        out[name] = 1e6 * float(np.median(t))
    world.close()
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", default="100,200,500,1000", help="comma-separated n_masses")
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--sim-time", type=float, default=0.1, help="simulated seconds per timed round [s]")
    p.add_argument("--json", default="", help="write the rows here")
    p.add_argument("--bullet-after", action="store_true",
                   help="only time Bullet's step at the largest n after each of a few other calls")
    a = p.parse_args(argv)
    if a.bullet_after:
        n = max(int(v) for v in a.n.split(","))
        for name, us in bullet_step_after(n).items():
            print(f"n={n}: stepSimulation after {name}: {us:.0f} us (median; load {os.getloadavg()[0]:.2f})")
        return 0
    n_masses = [int(v) for v in a.n.split(",")]
    rows, info = spheres_ab(n_masses, sim_time=a.sim_time, repeats=a.repeats)
    ls, le = info["load_start"], info["load_end"]
    print(f"thread CPU s per simulated s, median (range) of {a.repeats} interleaved rounds; load "
          f"{ls[0]:.2f} / {ls[1]:.2f} / {ls[2]:.2f} at the start, {le[0]:.2f} / {le[1]:.2f} / {le[2]:.2f} at the end")
    for r in rows:
        print(f"  n={r['n_masses']:5d} {r['mode']:4s} (proxy {r['proxy']!s:5s}): {r['cost']:.4g} s "
              f"({r['cost_min']:.4g}-{r['cost_max']:.4g}); Bullet's step {r['bullet']:.4g} s, the cable's side "
              f"{r['model']:.4g} s; same state as the other mode: {r['same_state']}")
    for mode, e in info["exponents"].items():
        print(f"{mode}: cost ~ n^{e['cost']:.2f} from n = {n_masses[0]} to {n_masses[-1]} (Bullet's step "
              f"~ n^{e['bullet']:.2f}, the cable's side ~ n^{e['model']:.2f})")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"rows": rows, **info}, f, indent=2)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
