"""Cost of contact: coupled step with the cable lying on a table / wrapped on a peg vs the contact-free step.

For n = 20 and 80, each scene's coupled step (Bullet step + the cable's implicit step with its
contacts, detection included) is timed against the same cable's contact-free coupled step (both
ends clamped in the air, same world, same integrator: implicit Euler at 240 Hz). Blocks of steps
are interleaved and the median ratio printed (ratios, not absolute times, survive a noisy machine).
The goal of issue 10 is at most 2x. Writes ``contact_cost.json``, ``contact_cost.png`` (chart)
and a picture of each scene (``contact_table.png``, ``contact_peg.png``) rendered through
``bullet_dlo.render``.

Scenes: ``table``: the Lv cable lying on the ground (every node in contact); ``resting``: the same with a
30 g box (4 x 4 x 2 cm, dynamic) resting across it (its twin: the same cable in the air, with no box: until
2026-12-05 the twin had the box on the ground, whose held load the cable's step then measured every step at about
190 us, which made the ratio look below 1; ``resting-far``: the cable on the ground with that box on the ground 30 cm
away, its twin the same cable on the ground with no box: what a free body that never touches the cable costs);
``peg``: a soft
cable (0.6 m, E 2 MPa) over a fixed 20 mm cylinder, both sides hanging with 50 g weights; ``box``
and ``hull``: the Lv cable lying on a 0.4 x 0.2 x 0.1 m block, a Bullet box (exact geometry) or the
same block as a convex hull mesh (the project's exact hull geometry since 2026-12-01); ``duck``: the Lv cable
lying across pybullet_data's duck (scaled 0.08, a convex hull of 1070 triangles: a finely faceted curved mesh,
demos/cable_on_duck.py) and the ground; their contact-free twins have the block or the duck in the world too, far
from the cable. Step times are thread
times (``time.thread_time``).

With ``--plain``, worlds without a free body take plain steps (one compiled call a step, ``bullet/plain_steps.py``, as
runs of at least ``plain_steps.PLAIN_FROM`` steps do), both sides of the ratio alike. ``--split``: every step in
Python's phases (the parts are timed there), and the contact scene's
step part by part (thread time per step, medians of the blocks):
``ContactSet.update`` (the bodies' poses, detection), ``CableSolver.step`` (the cable's kernel: take-over,
checks, the planned contact steps), the rest (Bullet's step, the forces to Bullet, the reactions on the bodies,
Python), and the stall guard's copies per contact step (its save of what the step reads and writes, timed in a
compiled loop).

Usage: ``python demos/contact_cost.py [--out DIR] [--masses 20 80] [--scenes table peg box hull duck resting resting-far]
[--repeats 5] [--block 200] [--split] [--plain] [--quick]``
(``--out`` defaults to ``out/contact_cost``; ``--out demos/gallery`` renews the committed pictures)
(``--quick``: n = 20, one block of 20 steps, no pictures; for smoke tests).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pybullet as pb  # noqa: E402

from bullet_dlo.bullet import plain_steps  # noqa: E402
from bullet_dlo.bullet.world import BulletWorld  # noqa: E402
from bullet_dlo.core.model import CableState  # noqa: E402
from bullet_dlo.core.spec import CableSpec  # noqa: E402

HZ = 240.0
Q_AXIS_Y = (math.sin(math.pi / 4), 0.0, 0.0, math.cos(math.pi / 4))
R_PEG = 0.02
COLORS = {"table": "#c46a2b", "peg": "#3b6ea5", "box": "#6a9a3b", "hull": "#8a4fa0", "duck": "#b8a030",
          "resting": "#a03b4f", "resting-far": "#d08090"}
RESTING_HALF = (0.02, 0.02, 0.01)  # [m] the resting box: 4 cm square across the cable, 2 cm tall (30 g)


def _soft(n: int) -> CableSpec:
    return CableSpec(length=0.6, diameter=0.004, mass=0.009, youngs_modulus=2e6, n_masses=n, dynamic_friction=0.4,
                     static_friction=0.4)


def _wrapped(spec: CableSpec) -> np.ndarray:
    """Node positions of a cable hanging symmetrically over the peg (axis y at the origin), (n, 3)."""
    rr = R_PEG + spec.diameter / 2
    hang = (spec.length - math.pi * rr) / 2
    a = np.linspace(math.pi, 0.0, 400)
    path = np.vstack([[[-rr, 0, -hang]], np.stack([rr * np.cos(a), 0 * a, rr * np.sin(a)], 1), [[rr, 0, -hang]]])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    t = np.arange(spec.n_masses) * spec.rest_length
    return np.stack([np.interp(t, s, path[:, j]) for j in range(3)], axis=1)


def _block(world: BulletWorld, hull: bool) -> None:
    """The 0.4 x 0.2 x 0.1 m block on the ground: a Bullet box or a convex hull of its corners."""
    he = (0.2, 0.1, 0.05)
    if not hull:
        world.add_box(he, (0, 0, he[2]))
        return
    corners = [[sx * he[0], sy * he[1], sz * he[2]] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    col = pb.createCollisionShape(pb.GEOM_MESH, vertices=corners, physicsClientId=world.client)
    pb.createMultiBody(0, col, -1, [0, 0, he[2]], physicsClientId=world.client)


def scene(kind: str, n: int, contact: bool, renderer: str | None = None):
    """(world, cable) of ``kind`` (table/peg/box/hull); contact=False: the same cable clamped in the air."""
    if kind in ("box", "hull"):
        spec = CableSpec.lv2017(n_masses=n, damping=0.02)
        world = BulletWorld(dt=1 / HZ, renderer=renderer)
        _block(world, kind == "hull")
        top = 0.1 + (0.001 if kind == "hull" else 0.0) + spec.diameter / 2  # a hull's surface: + Bullet's 1 mm margin
        if contact:
            cable = world.add_cable(spec, start=(-0.15, 0, top), direction=(1, 0, 0))
        else:
            cable = world.add_cable(spec, start=(-0.15, 0, 0.5), direction=(1, 0, 0), ends=("clamped", "clamped"))
        return world, cable
    if kind == "duck":
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from cable_on_duck import duck, lay_across

        spec = CableSpec.lv2017(n_masses=n, damping=0.02)
        world = BulletWorld(dt=1 / HZ, renderer=renderer)
        body = duck(world, concave=False)
        if contact:
            cable = lay_across(world, body, spec)
        else:
            cable = world.add_cable(spec, start=(-0.15, 0.5, 0.5), direction=(1, 0, 0), ends=("clamped", "clamped"))
        return world, cable
    if kind == "resting":
        spec = CableSpec.lv2017(n_masses=n, damping=0.02)
        world = BulletWorld(dt=1 / HZ, renderer=renderer)
        r = spec.diameter / 2
        if contact:
            cable = world.add_cable(spec, start=(-0.15, 0, r), direction=(1, 0, 0))
            world.add_box(RESTING_HALF, (0.0, 0.0, 2 * r + RESTING_HALF[2]), mass=0.03, friction=0.5)
        else:  # the same cable in the air, no box
            cable = world.add_cable(spec, start=(-0.15, 0, 0.5), direction=(1, 0, 0), ends=("clamped", "clamped"))
        return world, cable
    if kind == "resting-far":
        spec = CableSpec.lv2017(n_masses=n, damping=0.02)
        world = BulletWorld(dt=1 / HZ, renderer=renderer)
        r = spec.diameter / 2
        cable = world.add_cable(spec, start=(-0.15, 0, r), direction=(1, 0, 0))
        if contact:  # (its twin: the same cable on the ground, no box)
            world.add_box(RESTING_HALF, (0.0, 0.3, RESTING_HALF[2]), mass=0.03, friction=0.5)
        return world, cable
    if kind == "table":
        spec = CableSpec.lv2017(n_masses=n, damping=0.02)
        world = BulletWorld(dt=1 / HZ, renderer=renderer)
        r = spec.diameter / 2
        if contact:
            cable = world.add_cable(spec, start=(-0.15, 0, r), direction=(1, 0, 0))
        else:
            cable = world.add_cable(spec, start=(-0.15, 0, 0.5), direction=(1, 0, 0), ends=("clamped", "clamped"))
        return world, cable
    spec = _soft(n)
    world = BulletWorld(dt=1 / HZ, renderer=renderer)
    world.add_cylinder(R_PEG, 0.2, (0, 0, 0.4), Q_AXIS_Y, friction=0.4)
    if contact:
        x0 = _wrapped(spec) + np.array([0, 0, 0.4])
        cable = world.add_cable(spec, state=CableState(x0, np.zeros_like(x0)))
        cable.add_point_mass(0, 0.05)
        cable.add_point_mass(-1, 0.05)
    else:
        cable = world.add_cable(spec, start=(-0.3, 0.3, 0.8), direction=(1, 0, 0), ends=("clamped", "clamped"))
    return world, cable


def per_step(world: BulletWorld, steps: int) -> float:
    tic = time.thread_time()
    world.step(steps)
    return (time.thread_time() - tic) / steps


class _PartTimer:
    """Thread time [s] spent in ``ContactSet.update`` and ``CableSolver.step`` while active (wrapped methods; every
    step then takes Python's phases: the plain steps' loop calls neither)."""

    def __init__(self):
        from bullet_dlo.bullet.contact import ContactSet
        from bullet_dlo.bullet.solver import CableSolver
        plain_steps.PLAIN_STEPS = False
        self.spent = {"update": 0.0, "solver": 0.0}
        self._orig = [(ContactSet, "update", ContactSet.update), (CableSolver, "step", CableSolver.step)]
        for cls, name, fn in self._orig:
            setattr(cls, name, self._wrap(fn, "update" if name == "update" else "solver"))

    def _wrap(self, fn, key):
        spent = self.spent

        def timed(*args, **kwargs):
            tic = time.thread_time()
            try:
                return fn(*args, **kwargs)
            finally:
                spent[key] += time.thread_time() - tic
        return timed

    def restore(self) -> None:
        for cls, name, fn in self._orig:
            setattr(cls, name, fn)
        plain_steps.PLAIN_STEPS = True


def guard_copy_us(cable, calls: int = 20000) -> float:
    """Thread time [us] of the stall guard's save before one contact step of ``cable`` (compiled loop)."""
    from numba import njit

    from bullet_dlo.bullet.kernels import _copy_rows, _copy_whole

    @njit
    def loop(rows, whole, k, reps):
        for _ in range(reps):
            _copy_rows(rows, k, True)
            _copy_whole(whole, True)
        return 0

    g, k = cable.solver._guard, int(cable.contacts.count[0])
    loop(g.rows, g.whole, k, 1)
    tic = time.thread_time()
    loop(g.rows, g.whole, k, calls)
    return 1e6 * (time.thread_time() - tic) / calls


def measure(kind: str, n: int, repeats: int, block: int, split: bool = False) -> dict:
    """Median per-step times [s] of the contact scene and its contact-free twin, and their ratio; ``split``: also
    the contact scene's parts per step [us] (see the module doc)."""
    (wc, cc), (wf, cf) = scene(kind, n, True), scene(kind, n, False)
    timer = _PartTimer() if split else None
    try:
        wc.run(0.5)
        wf.run(0.5)
        with_c, free, parts = [], [], []
        for _ in range(repeats):
            if timer:
                timer.spent.update(update=0.0, solver=0.0)
            with_c.append(per_step(wc, block))
            if timer:
                parts.append({k: v / block for k, v in timer.spent.items()})
            free.append(per_step(wf, block))
        assert cc.stable and cf.stable
        ratios = [a / b for a, b in zip(with_c, free)]
        row = {"scene": kind, "n": n, "contacts": int(cc.contacts_last_step),
               "step_us": 1e6 * statistics.median(with_c), "free_step_us": 1e6 * statistics.median(free),
               "ratio": statistics.median(ratios), "ratio_min": min(ratios), "ratio_max": max(ratios),
               "newton_per_step": cc.newton_iterations / max(cc.steps, 1), "load": os.getloadavg()[0]}
        if split:
            row["update_us"] = 1e6 * statistics.median(p["update"] for p in parts)
            row["solver_us"] = 1e6 * statistics.median(p["solver"] for p in parts)
            row["rest_us"] = 1e6 * statistics.median(t - p["update"] - p["solver"] for t, p in zip(with_c, parts))
            row["guard_copy_us"] = guard_copy_us(cc)
        return row
    finally:
        if timer:
            timer.restore()
        wc.close()
        wf.close()


def picture(kind: str, n: int, path: Path) -> None:
    """Render the settled scene (1 s) through bullet_dlo.render to ``path``."""
    from bullet_dlo.render.camera import framing_camera, render_frame

    world, cable = scene(kind, n, True, renderer="tiny")
    try:
        world.run(1.0)
        pts = np.vstack([cable.x, cable.x + [0, 0.1, 0], cable.x - [0, 0.1, 0]])
        cam = framing_camera(pts, view_direction=(0.3, -1.0, 0.35), width=480, height=360)
        frame = render_frame(world.client, cam, world.renderer)
        plt.imsave(path, frame.rgb)
    finally:
        world.close()


def chart(rows: list[dict], path: Path) -> None:
    fig, ax = plt.subplots(figsize=(6, 3.5))
    labels = [f"{r['scene']}\nn={r['n']} ({r['contacts']} contacts)" for r in rows]
    ax.bar(range(len(rows)), [r["ratio"] for r in rows], color=[COLORS[r["scene"]] for r in rows])
    ax.axhline(2.0, color="k", ls="--", lw=1, label="goal: 2x")
    ax.set_xticks(range(len(rows)), labels)
    ax.set_ylabel("step time / contact-free step time")
    ax.set_title(f"Cost of contact (implicit Euler, {HZ:.0f} Hz, detection included)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out/contact_cost",
                    help="output folder (default out/contact_cost; --out demos/gallery renews the committed pictures)")
    ap.add_argument("--masses", type=int, nargs="+", default=[20, 80])
    ap.add_argument("--scenes", nargs="+", default=["table", "peg", "box", "hull", "duck", "resting"],
                    choices=["table", "peg", "box", "hull", "duck", "resting", "resting-far"])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--block", type=int, default=200, help="steps per timed block")
    ap.add_argument("--split", action="store_true", help="also the contact step's parts (see the module doc)")
    ap.add_argument("--quick", action="store_true", help="n = 20, one block of 20 steps, no pictures")
    ap.add_argument("--plain", action="store_true",
                    help="time plain steps (as a run of at least plain_steps.PLAIN_FROM steps takes them)")
    args = ap.parse_args()
    if args.plain:
        plain_steps.PLAIN_FROM = 0
    if args.quick:
        args.masses, args.repeats, args.block = [20], 1, 20
        print("--quick: one block of 20 steps, a smoke test; its ratios are not measurements")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for kind in args.scenes:
        for n in args.masses:
            row = measure(kind, n, args.repeats, args.block, args.split)
            rows.append(row)
            print(f"{kind:7s} n={n:3d} contacts {row['contacts']:3d}: {row['step_us']:7.1f} us vs contact-free "
                  f"{row['free_step_us']:7.1f} us -> {row['ratio']:.2f}x ({row['ratio_min']:.2f}-{row['ratio_max']:.2f}; "
                  f"Newton {row['newton_per_step']:.2f}/step; load {row['load']:.1f})", flush=True)
            if args.split:
                print(f"{'':7s}   parts per step: update {row['update_us']:.1f} us, solver {row['solver_us']:.1f} us, "
                      f"rest {row['rest_us']:.1f} us; the guard's save {row['guard_copy_us']:.2f} us per contact step",
                      flush=True)
    (out / "contact_cost.json").write_text(json.dumps(rows, indent=1))
    chart(rows, out / "contact_cost.png")
    if not args.quick:
        for kind in ("table", "peg"):
            picture(kind, 40, out / f"contact_{kind}.png")
    print(f"wrote {out / 'contact_cost.json'} and {out / 'contact_cost.png'}")


if __name__ == "__main__":
    main()
