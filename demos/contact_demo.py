"""Contact and friction demos: a cable pulled over a peg (picture + held-end force), the capstan table, the drop grid.

Default: an Lv cable (n = 40) pinned at one end lies over a peg (radius 8 mm) and a box; the held
end is lowered 12 cm, pulling the cable over the peg; friction holds the hanging part until the
pull wins. Writes ``contact_demo.png`` (three frames rendered through ``bullet_dlo.render`` and
the force on the held end beside them) and, with ``--video``, ``contact_demo.mp4``.

``--capstan``: slip onset of a soft cable over a cylinder vs the capstan law exp(mu theta), for
mu 0.2 / 0.4, wraps pi and pi/2, at 60, 240 and 1000 Hz (the check of
tests/bullet/test_contact_friction.py over all rates).

``--stiff-capstan``: the same cable made stiffer (E 2e6-3e7 Pa: bend length sqrt(E I / T) 0.3-1.2 times the wrap
radius), wrap pi, mu 0.4, a 24 s ramp: slip onset vs the elastica's capstan ratio
(``analysis.closed_forms.capstan_ratio``) and the string's (both with the wrapped part's weight); then E 3e7 on
48-, 96- and 192-gon hull pegs at mu 0.3.

``--drops``: the full drop grid of tests/bullet/test_contact_drops.py: ground / box / peg, each
implicit integrator, 60 / 240 / 1000 Hz, n = 10, 20, 40, 80 (108 runs): stability, tunnelling,
penetration and the final speed.

Usage: ``python demos/contact_demo.py [--out DIR] [--video] [--capstan] [--stiff-capstan] [--drops] [--quick]``
(``--quick``: the pull demo for 0.5 s, no video; for smoke tests).
"""
from __future__ import annotations

import argparse
import functools
import itertools
import json
import math
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from bullet_dlo.bullet.world import BulletWorld  # noqa: E402
from bullet_dlo.core.boundary import Move  # noqa: E402
from bullet_dlo.core.spec import CableSpec  # noqa: E402
from bullet_dlo.render.camera import framing_camera  # noqa: E402
from bullet_dlo.render.tube import CableTube  # noqa: E402
from bullet_dlo.render.video import Recorder, VideoWriter  # noqa: E402

TESTS = Path(__file__).resolve().parents[1] / "tests" / "bullet"
Q_AXIS_Y = (math.sin(math.pi / 4), 0.0, 0.0, math.cos(math.pi / 4))


def pull_over_peg(out: Path, duration: float, video: bool) -> dict:
    """The pull demo; returns its summary (and writes the picture / video)."""
    spec = CableSpec.lv2017(n_masses=40, damping=0.02, static_friction=0.6, dynamic_friction=0.5)
    r = spec.diameter / 2
    world = BulletWorld(dt=1 / 240, renderer="auto")
    try:
        world.add_cylinder(0.008, 0.2, (0.0, 0.0, 0.20), Q_AXIS_Y, friction=0.6, name="peg")
        world.add_box((0.05, 0.1, 0.06), (0.18, 0.0, 0.06), friction=0.6, name="box")
        down = Move("first", (0.0, 0.0, -0.12), 0.5, 2.0)
        cable = world.add_cable(spec, start=(-0.1, 0.0, 0.208 + r), direction=(1, 0, 0), ends=("pinned", "free"),
                                motion=[down])
        tube = CableTube(cable)
        cam = framing_camera([(-0.15, -0.12, 0.0), (0.25, 0.12, 0.3)], view_direction=(0.25, -1.0, 0.3),
                             width=480, height=360)
        writer = VideoWriter(out / "contact_demo", 30.0) if video else None
        rec = Recorder(world, cam, world.renderer, fps=30.0, writer=writer, tube=tube)
        world.after_step.append(rec.on_step)
        t, force, sliding, frames = [], [], [], []
        snaps = {0.4, 0.5 + 0.5 * duration / 3.0 * 2, duration}  # before, during, after the pull
        for k in range(int(duration * 240)):
            world.step()
            t.append(world.time)
            force.append(cable.end_forces()[0])
            sliding.append(int(cable.contact_forces()["sliding"].sum()))
            if any(abs(world.time - s) < 0.5 / 240 for s in snaps):
                frames.append((world.time, rec.snap().rgb))
        if writer is not None:
            writer.close()
        force = np.array(force)
        fig = plt.figure(figsize=(12, 3.6))
        for i, (ti, rgb) in enumerate(frames[:3]):
            ax = fig.add_subplot(1, 4, i + 1)
            ax.imshow(rgb)
            ax.set_title(f"t = {ti:.2f} s")
            ax.axis("off")
        ax = fig.add_subplot(1, 4, 4)
        ax.plot(t, force[:, 0], label="x")
        ax.plot(t, force[:, 2], label="z")
        ax.set_xlabel("t [s]")
        ax.set_ylabel("force on the held end [N]")
        ax.legend()
        fig.tight_layout()
        fig.savefig(out / "contact_demo.png", dpi=100)
        plt.close(fig)
        return {"stable": cable.stable, "reason": cable.reason, "final_force": force[-1].tolist(),
                "max_sliding_contacts": max(sliding), "video": str(writer.path) if writer else None}
    finally:
        world.close()


def capstan_table() -> list[dict]:
    sys.path.insert(0, str(TESTS))
    from test_contact_friction import capstan_onset

    rows = []
    for hz, theta, mu in itertools.product((60.0, 240.0, 1000.0), (math.pi, math.pi / 2), (0.2, 0.4)):
        tic = time.perf_counter()
        onset, cable = capstan_onset(theta, mu, hz=hz)
        exact = math.exp(mu * theta)
        rows.append({"hz": hz, "theta": theta, "mu": mu, "onset": onset, "exp_mu_theta": exact,
                     "error": None if onset is None else onset / exact - 1.0,
                     "newton_failures": cable.newton_failures})
        err = "never" if onset is None else f"{onset / exact - 1:+.1%}"
        print(f"{hz:6.0f} Hz wrap {math.degrees(theta):5.1f} deg mu {mu}: slip at {onset or float('nan'):.3f} vs "
              f"exp(mu theta) {exact:.3f} ({err}), Newton failures {cable.newton_failures}, "
              f"{time.perf_counter() - tic:.1f} s", flush=True)
    return rows


def stiff_capstan_table() -> list[dict]:
    sys.path.insert(0, str(TESTS))
    from test_contact_friction import R_CAPSTAN, capstan_onset, capstan_references

    rows, mu, theta = [], 0.4, math.pi
    for youngs, hz in ((2e6, 240.0), (1e7, 240.0), (2e7, 240.0), (3e7, 60.0), (3e7, 240.0), (3e7, 1000.0)):
        onset, cable = capstan_onset(theta, mu, hz=hz, youngs_modulus=youngs, ramp=24.0)
        stiff, string, t_short = capstan_references(cable, theta, mu)
        spec = cable.model.spec
        bend = math.sqrt(spec.bending_rigidity / t_short) / (R_CAPSTAN + spec.diameter / 2)
        rows.append({"youngs_modulus": youngs, "hz": hz, "bend_length_over_radius": bend, "onset": onset,
                     "elastica": stiff, "string": string, "newton_failures": cable.newton_failures})
        ratio = float("nan") if onset is None else onset
        print(f"E {youngs:.0e} Pa {hz:6.0f} Hz bend length / radius {bend:.2f}: slip at {ratio:.3f}, elastica "
              f"{stiff:.3f} ({ratio / stiff - 1:+.1%}), string {string:.3f} ({ratio / string - 1:+.1%}), "
              f"Newton failures {cable.newton_failures}", flush=True)
    # the same on hull pegs (tests/bullet/test_contact_mesh.py): a rod too stiff to follow the facets rests on the
    # vertices, so the polygon's sides count
    sys.path.insert(0, str(TESTS.parent))  # (test_contact_mesh imports tests/probes.py)
    from test_contact_mesh import hull_peg

    mu = 0.3
    for sides in (48, 96, 192):
        onset, cable = capstan_onset(theta, mu, peg=functools.partial(hull_peg, sides=sides), youngs_modulus=3e7,
                                     ramp=24.0)
        stiff, _, _ = capstan_references(cable, theta, mu)
        rows.append({"youngs_modulus": 3e7, "hz": 240.0, "hull_sides": sides, "mu": mu, "onset": onset,
                     "elastica": stiff, "newton_failures": cable.newton_failures})
        ratio = float("nan") if onset is None else onset
        print(f"E 3e+07 Pa, {sides}-gon hull peg, mu {mu}: slip at {ratio:.3f}, elastica {stiff:.3f} "
              f"({ratio / stiff - 1:+.1%}), Newton failures {cable.newton_failures}", flush=True)
    return rows


def drop_grid() -> list[dict]:
    sys.path.insert(0, str(TESTS))
    from test_contact_drops import drop

    rows = []
    for target, integ, hz, n in itertools.product(("ground", "box", "peg"),
                                                  ("implicit_euler", "bdf2", "implicit_midpoint"),
                                                  (60, 240, 1000), (10, 20, 40, 80)):
        cable, tunnelled, gap = drop(target, integ, hz, n)
        row = {"target": target, "integrator": integ, "hz": hz, "n": n, "stable": cable.stable,
               "reason": cable.reason, "tunnelled": tunnelled, "penetration_um": -gap * 1e6,
               "final_max_speed_mm_s": float(np.abs(cable.v).max()) * 1e3, "newton_failures": cable.newton_failures}
        rows.append(row)
        print(f"{target:6s} {integ:17s} {hz:5d} Hz n={n:3d}: stable {cable.stable} tunnelled {tunnelled} "
              f"penetration {row['penetration_um']:6.1f} um final speed {row['final_max_speed_mm_s']:7.3f} mm/s",
              flush=True)
    bad = [r for r in rows if not r["stable"] or r["tunnelled"]]
    print(f"{len(rows)} drops: {len(bad)} unstable or tunnelled")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out/contact_demo",
                    help="output folder (default out/contact_demo; --out demos/gallery renews the committed pictures)")
    ap.add_argument("--video", action="store_true", help="also write contact_demo.mp4")
    ap.add_argument("--capstan", action="store_true", help="capstan table at 60, 240, 1000 Hz")
    ap.add_argument("--stiff-capstan", action="store_true",
                    help="stiff cables over the cylinder and hull pegs against the elastica's capstan ratio (9 runs)")
    ap.add_argument("--drops", action="store_true", help="the full drop grid (108 runs)")
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    summary = {"pull": pull_over_peg(out, 0.5 if args.quick else 3.0, args.video and not args.quick)}
    print("pull over a peg:", summary["pull"])
    if args.capstan:
        summary["capstan"] = capstan_table()
    if args.stiff_capstan:
        summary["stiff_capstan"] = stiff_capstan_table()
    if args.drops:
        summary["drops"] = drop_grid()
    (out / "contact_demo.json").write_text(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
