"""How often the Bullet path's contact Newton ends unconverged, when, and how far from convergence.

Every planned Bullet step of every cable is tallied (a wrapper round :meth:`CableSolver.step` reads the
:class:`~bullet_dlo.bullet.kernels.StallGuard`'s info): the contact solves that did not converge at the first
attempt, the Newton iteration they ended at (1: stalled on the start guess v' = v, the cable coasts through
the step without its forces; 30: out of iterations), and their momentum residual in units of gravity's
impulse in a step (:func:`~bullet_dlo.core.kernels.contact.stall_ratio`; the tolerance is 1e-3 of it for implicit
Euler). "near": at most ``--far`` (kept), "far": beyond (taken again as sub-steps; with ``--levels -1`` the
behaviour before the guard: kept too). Also printed with the retry on: steps retried, and whether the run
stopped (status STALLED).

    PYTHONPATH=. python demos/newton_stall.py [--scenes edge drops resting capstan arms] [--levels -1|0|2] [--quick]
"""
from __future__ import annotations

import argparse
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from bullet_dlo.bullet import plain_steps
from bullet_dlo.bullet import solver as solver_mod
from bullet_dlo.bullet.kernels import COASTED, FINAL_RATIO, FIRST_ITER, FIRST_MOVED, FIRST_RATIO, RETRY_SUBSTEPS

TESTS = Path(__file__).resolve().parents[1] / "tests" / "bullet"
DEMOS = Path(__file__).resolve().parent
TALLY: list = []  # (first ratio, first iteration, retry sub-steps, status) of each planned step with contacts


def _install(levels: int, far: float) -> None:
    """Wrap CableSolver.step: set the retry's settings, tally each step's guard info."""
    orig = solver_mod.CableSolver.step

    def step(self, arrays, control, contacts, bodies, inp):
        if self._guard is None:
            self.stall_levels, self.stall_far = levels, far
        status = orig(self, arrays, control, contacts, bodies, inp)
        info = self._guard.info
        TALLY.append((float(info[FIRST_RATIO]), int(info[FIRST_ITER]), int(info[RETRY_SUBSTEPS]), float(info[FINAL_RATIO]),
                      float(info[COASTED]), float(info[FIRST_MOVED])))
        return status

    solver_mod.CableSolver.step = step
    plain_steps.PLAIN_STEPS = False  # every step through CableSolver.step (the plain steps' loop does not call it)


def _q(a: np.ndarray) -> str:
    return f"{np.median(a):.2g} / {a.max():.2g}" if a.size else "-"


def _lo(a: np.ndarray) -> str:
    return f"{a.min():.2g} / {np.median(a):.2g}" if a.size else "-"


def _summary(name: str, far: float, tol: float, wall: float, cables: list) -> None:
    rows = np.array(TALLY, dtype=float).reshape(-1, 6)
    TALLY.clear()
    bad = rows[rows[:, 0] > 0.0]
    ratio, its = bad[:, 0], bad[:, 1]
    stall = its < 30  # the line search failed (30: out of iterations, the merit fell at every one)
    stopped = [f"{c.reason} at {c.time_to_instability:.4g} s" for c in cables if not c.stable]
    first = ", ".join(f"{int(i)}" for i in sorted(set(its[stall].tolist()))[:6])
    print(f"| {name} | {rows.shape[0]} | {bad.shape[0]} | {int(np.sum(~stall))} | {_q(ratio[~stall])} | "
          f"{int(stall.sum())} | {first or '-'} | {int(np.sum(its == 1))} | {_q(ratio[stall])} | "
          f"{int(np.sum(stall & (ratio > far)))} | {_lo(bad[:, 5][ratio > far])} | {int(np.sum(rows[:, 2] > 0))} | "
          f"{int(np.sum(rows[:, 3] > far))} | {int(np.sum(rows[:, 4] > 0))} | "
          f"{'; '.join(stopped) or 'stable'} | {wall:.0f} |", flush=True)


def edge(quick: bool):
    sys.path.insert(0, str(TESTS))
    from test_edge_slide import bracket, hang, soft_cable, threshold
    spec = soft_cable(40)
    cases = [(1000.0, 0.75)] if quick else [(1000.0, 0.75), (1000.0, 0.5), (240.0, 0.25), (60.0, 0.05)]
    for hz, place in cases:
        for phi in bracket(spec.n_masses, place, threshold(0.3)):
            tic = time.thread_time()
            _, _, cable = hang(spec, phi, place, hz)
            yield f"edge {hz:.0f} Hz place {place} phi {phi:.3f}", time.thread_time() - tic, [cable]


def drops(quick: bool):
    sys.path.insert(0, str(TESTS))
    from test_contact_drops import GRID, drop
    for target, integ, hz, n in (GRID[:3] if quick else GRID):
        tic = time.thread_time()
        cable, _, _ = drop(target, integ, hz, n)
        yield f"drop {target} {integ} {hz} Hz n {n}", time.thread_time() - tic, [cable]


def resting(quick: bool):
    sys.path.insert(0, str(DEMOS))
    import resting_bodies
    from bullet_dlo.bullet import world as world_mod
    made = []
    orig = world_mod.BulletWorld.add_cable

    def add_cable(self, *a, **k):
        made.append(orig(self, *a, **k))
        return made[-1]

    world_mod.BulletWorld.add_cable = add_cable
    try:
        for mass in ((0.03,) if quick else (0.001, 0.03, 3.0)):
            for hz in (240.0, 1000.0):
                tic = time.thread_time()
                resting_bodies.run(mass, hz, 0.01, 1.0 if quick else 2.0)
                yield f"box {mass} kg on cable {hz:.0f} Hz", time.thread_time() - tic, [made.pop()]
    finally:
        world_mod.BulletWorld.add_cable = orig


def capstan(quick: bool):
    sys.path.insert(0, str(TESTS))
    from test_contact_friction import capstan_onset
    for hz, theta, mu in ([(240.0, math.pi, 0.2)] if quick else
                          [(60.0, math.pi, 0.2), (240.0, math.pi, 0.4), (1000.0, math.pi / 2, 0.4)]):
        tic = time.thread_time()
        _, cable = capstan_onset(theta, mu, hz=hz)
        yield f"capstan {hz:.0f} Hz theta {theta:.2f} mu {mu}", time.thread_time() - tic, [cable]


def arms(quick: bool):
    sys.path.insert(0, str(DEMOS))
    from dual_arm_grasp import run_robot
    for robot in (("panda",) if quick else ("panda", "kuka")):
        tic = time.thread_time()
        scene, _ = run_robot(robot, 1.0 / 240.0, quick)
        yield f"dual-arm grasp {robot} 240 Hz", time.thread_time() - tic, [scene.cable]
        scene.close()


def landing(quick: bool):
    """A cable falling flat at 0.5 m/s onto the ground (contact damping 1: the normal damper switches on at gap
    0), placed so that the step's start guess (no force: x + h v) ends exactly at gap 0+ (tests/bullet/
    test_newton_stall.py)."""
    sys.path.insert(0, str(TESTS))
    from test_newton_stall import falling_flat
    for hz in ((240.0,) if quick else (60.0, 240.0, 1000.0)):
        tic = time.thread_time()
        with falling_flat(hz) as (world, cable, _):
            world.run(0.5)
            yield f"flat landing {hz:.0f} Hz, damper at gap 0", time.thread_time() - tic, [cable]


SCENES = {"landing": landing, "edge": edge, "drops": drops, "resting": resting, "capstan": capstan, "arms": arms}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES))
    ap.add_argument("--levels", type=int, default=solver_mod.STALL_RETRIES, help="-1: no guard (the old behaviour), 0: no retry")
    ap.add_argument("--far", type=float, default=solver_mod.STALL_FAR)
    ap.add_argument("--tol", type=float, default=1e-3, help="Newton's tolerance, for the ratio/tol column")
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    _install(args.levels, args.far)
    warnings.simplefilter("ignore", RuntimeWarning)
    print(f"retry levels {args.levels}, far = {args.far} x gravity's impulse per step")
    print("| scene | steps | unconverged | out of iterations | their ratio med/max | stalled | at iterations | "
          "at it. 1 | their ratio med/max | stalled far | far: momentum moved min/med | retried | kept far | coasted | "
          "status | CPU s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name in args.scenes:
        for label, wall, cables in SCENES[name](args.quick):
            _summary(label, args.far, args.tol, wall, cables)


if __name__ == "__main__":
    main()
