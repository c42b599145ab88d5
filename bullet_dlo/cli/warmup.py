"""``bullet-dlo warmup``: compile the numerical kernels once, ahead of the first real run.

Numba compiles the kernels on their first call and caches them on disk beside the package; on a fresh
install (or after an upgrade) that first call takes minutes of CPU (about 8 for the main demo's kernels on a
2-core AMD EPYC, 2026-12-07). This runs every core
integrator, the twisting cable, model-owned contact with a Bullet world and the two arms for a few
steps each, so that later commands start at once. It prints what it compiled and how long it took.
"""
from __future__ import annotations

import argparse
import time


def warm_kernels(arms: bool = True) -> list[tuple[str, float]]:
    """Run each family of kernels a few steps; (what, CPU seconds) per family."""
    from bullet_dlo.core.integrators import INTEGRATORS
    from bullet_dlo.core.engine import simulate
    from bullet_dlo.core.model import CableModel
    from bullet_dlo.core.spec import CableSpec

    timings = []
    spec = CableSpec.lv2017(n_masses=5)
    for name in INTEGRATORS:
        tic = time.process_time()
        simulate(CableModel.straight(spec), name, 1e-4, 3e-4)
        timings.append((f"core {name}", time.process_time() - tic))
    tic = time.process_time()
    twisting = spec.with_(section="rectangle", width=0.004, thickness=0.001, twist=True)
    simulate(CableModel.straight(twisting), "bdf2", 1e-4, 3e-4)
    timings.append(("core twist (material frame)", time.process_time() - tic))
    from bullet_dlo.sim import Scene, build

    cable = {"length": 0.3, "diameter": 0.004, "mass": 0.03, "youngs_modulus": 126.0e6, "n_masses": 6}
    tic = time.process_time()
    lying = Scene.from_dict({"cable": cable, "layout": {"start": [0, 0, 0.002], "direction": [1, 0, 0]},
                             "ends": {"first": "free", "last": "free"}, "integrator": "bdf2", "dt": 1 / 240,
                             "duration": 0.02})
    with build(lying, "bullet") as sim:  # on the ground: the model's contact kernels
        sim.run()
    timings.append(("Bullet world, model-owned contact", time.process_time() - tic))
    if arms:
        tic = time.process_time()
        held = Scene.from_dict({"cable": cable, "integrator": "bdf2", "dt": 1 / 240, "duration": 0.02})
        with build(held, "arms", robot="panda") as sim:
            sim.run()
        timings.append(("two arms with wrist sensors", time.process_time() - tic))
    return timings


def cmd_warmup(args: argparse.Namespace) -> int:
    from bullet_dlo._numba_cache import kernels_cold

    cold = kernels_cold()
    print("compiling the numerical kernels (minutes on a fresh install; cached beside the package "
          "afterwards)" if cold else "loading the numerical kernels (compiling those not yet cached)")
    total = 0.0
    for what, cpu in warm_kernels(arms=not args.no_arms):
        total += cpu
        print(f"  {what:36s} {cpu:7.2f} s CPU")
    print(f"done in {total:.1f} s CPU; later runs start at once (run times never include compiling: "
          "see compile_time_s in results)")
    return 0


def add_parsers(sub, common: argparse.ArgumentParser) -> None:
    """``warmup`` on ``sub`` (argparse subparsers)."""
    s = sub.add_parser("warmup", parents=[common], help="compile the numerical kernels once, ahead of the first run",
                       description="Compile (or load from the on-disk cache) every family of Numba kernels: the "
                                   "core integrators, the twisting cable, a Bullet world with model-owned contact "
                                   "and the two arms, a few steps each. A fresh install spends minutes here once "
                                   "(832 s of CPU on a 2-core machine, 2026-12-07); every later command starts "
                                   "at once.")
    s.add_argument("--no-arms", action="store_true", help="skip the two-arm scene (robots are not used)")
    s.set_defaults(func=cmd_warmup)


__all__ = ["add_parsers", "cmd_warmup", "warm_kernels"]
