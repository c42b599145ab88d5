"""Fixed cost of one coupled step at small n, part by part, against a bare ``stepSimulation``.

The study's cable (clamped, 5 mm move, implicit Euler, 1 kHz, ground plane; n = 10 by default) is
stepped by :meth:`BulletWorld.step` (recording every step, as ``simulate`` does, and without a
recorder; its steps are plain, one compiled call each, as in a run of at least ``plain_steps.PLAIN_FROM`` steps:
``bullet/plain_steps.py``), the same in Python's phases (``plain_steps.PLAIN_STEPS`` off), and each part of the step is timed on its own on the same warmed world: Bullet's step,
the forces to Bullet (one compiled call), the contact query, the contact model's update (poses of
the bodies, detection), the model's kernel as the solver calls it (sync, checks, plan, on its packed arguments:
``bullet/solver_call.py``; the share of it that is only Numba unboxing them, timed as an empty kernel over the same
arguments, and beside it the unboxing of the same ~150 arrays passed unpacked), and the recorder's row. The Python glue
is the whole step minus its parts. Parts are timed in interleaved rounds with
``time.thread_time``; medians and ranges, the machine's load beside them. The bare step is a twin
world with the same spheres, filters and ground, its spheres live in Bullet and falling freely
(``bullet_spheres="live"``: a model-contact cable's spheres are otherwise parked proxies, asleep in Bullet, and
its world's step costs about a third of that; printed beside it).

In situ (second table): the same parts inside ``BulletWorld.step`` of a third warmed world, each wrapped with a
clock (its own cost, measured on a no-op, is taken off each part): what each part costs where it runs, after the
others have had the caches (Bullet's step and the kernels cost 1.3-4x their isolated time there), and the Python
glue left between them.

Writes ``step_breakdown.json`` (every round of every part, the in-situ parts, the load) into ``--out``.

``--startup K [K ...]``: instead, what plain steps cost a fresh process (readying the loop included): for each K, a
new process steps a warmed study world K times in one ``world.step(K)``, plain from its start
(``plain_steps.PLAIN_FROM`` 0) and in Python's phases, alternately, ``--rounds`` times each; thread CPU time [s].

Usage: ``python demos/step_breakdown.py [--n 10] [--rounds 9] [--block 400] [--out DIR] [--quick]
[--startup K ...]`` (``--quick``: one round of 20 calls; for smoke tests).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import pybullet as pb
from numba import njit

from bullet_dlo.bullet import plain_steps
from bullet_dlo.bullet.kernels import bind
from bullet_dlo.bullet.solver_call import pack_step_args, step_with
from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.boundary import Move
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec


PYTHON_REC = "  the same in Python's phases, recording"
PYTHON = "  the same in Python's phases, no recorder"


@njit
def _unbox_only(stepper, m, plan, ext, cp, ws, det, inp, contacts, bodies, guard):
    return 0


@njit
def _unbox_packed(args, inp):
    return 0


def study(n: int) -> CableModel:
    spec = CableSpec.lv2017(n_masses=n, youngs_modulus=126e6, damping=0.01)
    return CableModel.straight(spec, ends=("clamped", "clamped"), motion=[Move("last", (0, 0, 0.005), 0.1, 0.1)])


def per_call(fn, block: int) -> float:
    """Thread CPU time of one call [us], over ``block`` calls."""
    t0 = time.thread_time()
    for _ in range(block):
        fn()
    return 1e6 * (time.thread_time() - t0) / block


def in_situ(model: CableModel, rounds: int, block: int) -> tuple[dict[str, list[float]], float]:
    """Per-part thread CPU time [us per step] inside ``BulletWorld.step`` (no recorder, Python's phases: the plain
    steps' loop has no parts to wrap), each part wrapped with a clock on its instance; returns the rounds of each part
    (the clock's cost taken off) and a wrapped call's cost [us]."""
    plain_steps.PLAIN_STEPS = False
    world = BulletWorld(dt=1e-3)
    cable = world.add_cable(model, record_every=10**9)
    world.step(50)
    clock = time.thread_time_ns
    acc: dict[str, int] = {}
    calls: dict[str, int] = {}

    def wrap(obj, attr: str, label: str) -> None:
        fn = getattr(obj, attr)

        def timed(*a, **k):
            t0 = clock()
            out = fn(*a, **k)
            acc[label] = acc.get(label, 0) + clock() - t0
            calls[label] = calls.get(label, 0) + 1
            return out
        setattr(obj, attr, timed)

    # the clock's own cost, on a no-op (each round): inside a wrapped part's interval (``inner_us``) and of a whole
    # wrapped call over the plain call it replaces (``over``: what a caller's interval pays for it)
    probe = type("Probe", (), {"noop": staticmethod(lambda: None)})()
    wrap(probe, "noop", "noop")

    def clock_cost() -> tuple[float, float]:
        acc.clear(), calls.clear()
        t0 = clock()
        for _ in range(block):
            probe.noop()
        return (clock() - t0) / block / 1e3 - per_call(lambda: None, block), acc["noop"] / block / 1e3
    cs, solver = cable.contact.set, cable.solver
    # (object, method, label, the part it runs inside: None at the top)
    update, step = "contact model update", "CableSolver.step"
    parts = [(world, "push_cables", "forces to Bullet (push_cables)", None),
             (world, "step_physics", "Bullet's step", None),
             (world, "contacts", "contact query (getContactPoints)", None),
             (cable.contact, "refresh", "contact set refresh check", None),
             (cs, "update", update, None),
             (cs, "_read_poses", "  of which obstacle poses (native read)", update),
             (cs, "_detect", "  of which detection kernel", update),
             (solver, "step_input", "step input (StepInput)", None),
             (solver, "step", step, None),
             (solver, "_kernel", "  of which model kernel", step)]
    for obj, attr, label, _ in parts:
        wrap(obj, attr, label)
    rounds_us: dict[str, list[float]] = {label: [] for *_, label, _ in parts}
    rounds_us["step (timed parts)"] = []
    overs = []
    for _ in range(rounds):
        over, inner_us = clock_cost()
        overs.append(over)
        acc.clear(), calls.clear()
        t0 = clock()
        world.step(block)
        total = (clock() - t0) / block / 1e3
        wrapped = sum(calls.get(label, 0) for *_, label, _ in parts) / block
        rounds_us["step (timed parts)"].append(total - wrapped * over)
        for obj, attr, label, _ in parts:
            inner = sum(calls.get(lb, 0) for *_, lb, within in parts if within == label) / block
            rounds_us[label].append(acc.get(label, 0) / block / 1e3 - (calls.get(label, 0) / block) * inner_us
                                    - inner * over)
    world.close()
    plain_steps.PLAIN_STEPS = True
    return rounds_us, statistics.median(overs)


def fresh_run(n: int, steps: int, plain: bool) -> tuple[bool, float]:
    """In this process (fresh): a warmed study world stepped ``steps`` times in one ``world.step``, plain from its
    start or in Python's phases; whether plain steps were taken and the thread CPU time [s] of that call (readying
    the plain loop included)."""
    plain_steps.PLAIN_FROM = 0
    plain_steps.PLAIN_STEPS = plain
    with BulletWorld(dt=1e-3) as world:
        cable = world.add_cable(study(n), record_every=10**9)
        world.step(1)  # (the cable's kernels are loaded by add_cable and its first step: both ways alike)
        tic = time.thread_time()
        world.step(steps)
        return cable._plain_args is not None, time.thread_time() - tic


def startup(n: int, counts: list[int], rounds: int) -> None:
    """Print the fresh processes' cost of ``world.step(K)`` for each K of ``counts``, plain and in Python's phases."""
    load = os.getloadavg()
    print(f"n = {n}, 1 kHz: thread CPU time [s] of world.step(K) in a fresh process, plain from its start against "
          f"Python's phases, {rounds} alternating rounds; load {load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f}")
    for k in counts:
        took = {True: [], False: []}
        for _ in range(rounds):
            for plain in (True, False):
                out = subprocess.run([sys.executable, __file__, "--n", str(n), "--fresh-run", str(k), str(int(plain))],
                                     capture_output=True, text=True, check=True).stdout
                taken, seconds = out.split()[-2:]
                if (taken == "True") != plain:
                    raise SystemExit(f"K = {k}: plain steps {'not ' if plain else ''}taken where asked "
                                     f"{'for' if plain else 'off'}")
                took[plain].append(float(seconds))
        p, q = statistics.median(took[True]), statistics.median(took[False])
        print(f"  K = {k:7d}: plain {p:.3f} ({min(took[True]):.3f}-{max(took[True]):.3f}), Python's phases {q:.3f} "
              f"({min(took[False]):.3f}-{max(took[False]):.3f}); plain / Python {p / q:.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=10, help="masses of the cable")
    parser.add_argument("--rounds", type=int, default=9, help="interleaved rounds (median and range)")
    parser.add_argument("--block", type=int, default=400, help="calls per round and part")
    parser.add_argument("--out", default=os.path.join("out", "step_breakdown"), help="output folder")
    parser.add_argument("--quick", action="store_true", help="one round of 20 calls (smoke test)")
    parser.add_argument("--startup", type=int, nargs="+", metavar="K",
                        help="instead: fresh processes' cost of world.step(K), plain and in Python's phases")
    parser.add_argument("--fresh-run", type=int, nargs=2, metavar=("K", "PLAIN"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.quick:
        args.rounds, args.block = 1, 20
    if args.fresh_run:
        print(*fresh_run(args.n, args.fresh_run[0], bool(args.fresh_run[1])))
        return
    if args.startup:
        startup(args.n, args.startup, args.rounds)
        return
    plain_steps.PLAIN_FROM = 0  # the steady state of a long run (short runs keep Python's phases: plain_steps.py)
    model = study(args.n)
    rec_world = BulletWorld(dt=1e-3)
    rec_world.add_cable(model, record_every=1)
    rec_python = BulletWorld(dt=1e-3)  # the same two stepped in Python's phases
    rec_python.add_cable(model, record_every=1)
    python = BulletWorld(dt=1e-3)
    python.add_cable(model, record_every=10**9)
    world = BulletWorld(dt=1e-3)
    cable = world.add_cable(model, record_every=10**9)
    bare = BulletWorld(dt=1e-3)
    twin = bare.add_cable(model, record_every=10**9, bullet_spheres="live")
    parked = BulletWorld(dt=1e-3)
    parked.add_cable(model, record_every=10**9)  # the default: its spheres are parked proxies
    kernel_world = BulletWorld(dt=1e-3)  # its cable is stepped by the kernel alone (no Bullet step between)
    kcable = kernel_world.add_cable(model, record_every=10**9)
    for w in (rec_world, world, kernel_world, rec_python, python):
        w.step(50)  # compile and warm up
    # the kernel's inputs of a step: take over, cheap checks (every step by default), plan; with the recorder's
    # end loads and energy or without (the energy balance, every 10th step, is left out)
    kargs = kcable._kernel_args(kcable._step_input(True, False, kcable._no_index, kcable._no_rows, kcable._no_rows))
    kargs_rec = kcable._kernel_args(kcable._step_input(True, True, kcable._no_index, kcable._no_rows, kcable._no_rows))
    kargs = kargs[:7] + (kargs[7]._replace(check=True),) + kargs[8:]
    kargs_rec = kargs_rec[:7] + (kargs_rec[7]._replace(check=True),) + kargs_rec[8:]
    unbox_plain = bind(_unbox_only, *kargs)
    packed, _calls = pack_step_args(kargs[:7] + kargs[8:])  # the solver's step kernel, packed and bound as CableSolver.step
    kernel = bind(step_with, packed, kargs[7])
    unbox = bind(_unbox_packed, packed, kargs[7])
    cs = cable._contact_set
    cp = cable._cp

    def reset_twin() -> None:
        for b, pos in zip(twin.body_ids, model.x0.tolist()):
            pb.resetBasePositionAndOrientation(b, pos, [0, 0, 0, 1], physicsClientId=bare.client)
            pb.resetBaseVelocity(b, [0, 0, 0], [0, 0, 0], physicsClientId=bare.client)

    parts = {
        "coupled step, recording every step": lambda: rec_world.step(),
        "coupled step, no recorder": lambda: world.step(),
        PYTHON_REC: lambda: rec_python.step(),
        PYTHON: lambda: python.step(),
        "bare stepSimulation (twin world)": lambda: pb.stepSimulation(bare.client),
        "bare stepSimulation (twin, parked spheres)": lambda: pb.stepSimulation(parked.client),
        "  Bullet's step in the coupled world": lambda: pb.stepSimulation(world.client),
        "  forces to Bullet (apply_forces)": cable.apply_forces,
        "  contact query (getContactPoints)": lambda: pb.getContactPoints(-1, -1, -2, -2, world.client),
        "  contact model update (poses, detect)": lambda: cs.update(cp.x_new, cp.v_new, cable.arrays.mass,
                                                                     cable.stepper.h, world.dt, True),
        "  model kernel (sync, checks, plan)": lambda: kernel(packed, kargs[7]),
        "    of which unboxing its arguments": lambda: unbox(packed, kargs[7]),
        "    (the same arrays unboxed unpacked)": lambda: unbox_plain(*kargs),
        "  model kernel, recorded step": lambda: kernel(packed, kargs_rec[7]),
        "  recorder row (Python side)": lambda: cable._record_row(from_kernel=True),
    }
    times = {k: [] for k in parts}
    load = os.getloadavg()
    for _ in range(args.rounds):
        reset_twin()
        for name, fn in parts.items():
            plain_steps.PLAIN_STEPS = "Python's phases" not in name
            times[name].append(per_call(fn, args.block))
        plain_steps.PLAIN_STEPS = True
    situ, clock_us = in_situ(model, args.rounds, args.block)
    load_end = os.getloadavg()
    med = {k: statistics.median(v) for k, v in times.items()}
    situ_med = {k: statistics.median(v) for k, v in situ.items()}
    print(f"n = {args.n}, 1 kHz, implicit Euler; thread CPU time per call [us], median (range) of {args.rounds} "
          f"interleaved rounds of {args.block}; load {load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f} at the start, "
          f"{load_end[0]:.2f} / {load_end[1]:.2f} / {load_end[2]:.2f} at the end")
    for name, v in times.items():
        print(f"  {name:44s} {med[name]:7.1f} ({min(v):.1f}-{max(v):.1f})")
    top = ("  Bullet's step in the coupled world", "  forces to Bullet (apply_forces)", "  contact query (getContactPoints)",
           "  contact model update (poses, detect)", "  model kernel (sync, checks, plan)")
    glue = med[PYTHON] - sum(med[k] for k in top)
    bare_us = med["bare stepSimulation (twin world)"]
    print(f"  {'  Python glue (the Python phases minus parts)':44s} {glue:7.1f}")
    print(f"coupled / bare: {med['coupled step, no recorder'] / bare_us:.2f}x without the recorder, "
          f"{med['coupled step, recording every step'] / bare_us:.2f}x recording every step; in Python's phases "
          f"{med[PYTHON] / bare_us:.2f}x and {med[PYTHON_REC] / bare_us:.2f}x")
    print(f"in situ: each part inside BulletWorld.step (no recorder), us per step, median (range); the clock's own "
          f"cost ({clock_us:.2f} us per wrapped call) taken off")
    for name, v in situ.items():
        print(f"  {name:44s} {situ_med[name]:7.1f} ({min(v):.1f}-{max(v):.1f})")
    situ_glue = situ_med["step (timed parts)"] - sum(
        situ_med[k] for k in situ if not k.startswith("  ") and k != "step (timed parts)")
    print(f"  {'Python glue (the step minus its parts)':44s} {situ_glue:7.1f}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "step_breakdown.json").write_text(json.dumps(
        {"n": args.n, "rounds_us": times, "median_us": med, "glue_us": glue, "in_situ_rounds_us": situ,
         "in_situ_median_us": situ_med, "in_situ_glue_us": situ_glue, "clock_us": clock_us, "load_start": load,
         "load_end": load_end}, indent=2))
    print(f"outputs written to {out.resolve()}")
    for w in (rec_world, world, kernel_world, bare, parked, rec_python, python):
        w.close()


if __name__ == "__main__":
    main()
