"""Order in dt of a twisting cable's implicit step in contact and out of it (issue 22, item 1).

The implicit methods solve a twisting cable's positions and twist angles in one Newton system, out of contact
(``coupled_implicit``) and in contact (``coupled_contact``, ``bullet_dlo/core/kernels/twist_coupled.py``; before,
the contact step solved the positions with the twist held, then the twist in an implicit-Euler sub-step:
staggered, first order). This demo measures the order on one scene, in contact and out of it:

a soft steel-like strip (rectangle 10 x 1 mm, E 2 GPa, 0.3 m, 9 nodes, the scene of
``tests/core/test_twist_coupled.py``) clamped flat at 2 cm above the ground, its free part drooped onto the
ground (settled first, 0.5 s at dt 0.5 ms), then its clamp rolled by ``--roll`` degrees about the cable's
axis over 0.3 s. On the ground: its last four nodes lie on it (the same four rows throughout), frictionless by
default; the roll swings the strip sideways, so with ``--friction MU`` the rows slide (at mu 1 and 8 alike), and
sliding friction is first order of its own (its direction from the anchor the last step left). Without the
ground: the same start, no contact. Errors at the end against the
same run at dt 4 ms / 64: the end torque about the clamp's axis [N m] (the clamp spring, its damper and the
twist), the node positions [m] and the segments' material axes m1 (max over nodes).

Two details keep the comparison one of the integrator alone:

- the contact's penalty stiffness is k_n = alpha m / dt^2 (``contact_stiffness`` alpha): each run passes
  alpha = 1e4 (dt / 4 ms)^2, so k_n is the same at every dt (alpha 1e4 at 4 ms);
- a Bullet cable's step plans the coming step: after ``world.step()`` its ``x``, ``v`` are at t but its twist
  state (``cable.twist``) already at t + dt. The demo compares the planned state (``x_new``, ``v_new`` and the
  twist, all at T + dt) with the reference's at the same time, or with ``--as-reported`` what
  ``cable.end_loads()`` and ``cable.state()`` report, all at T (before the fix they paired x at t with the twist
  of t + dt: first order).

    python demos/twist_contact_order.py                  # BDF2, roll 30 degrees, frictionless (~5 s)
    python demos/twist_contact_order.py --friction 1     # the rows slide: the friction's own first order
    python demos/twist_contact_order.py --method implicit_euler
    python demos/twist_contact_order.py --as-reported    # cable.state() / end_loads() as reported (at T)
    python demos/twist_contact_order.py --fine           # dt 1 ms to 0.125 ms (~30 s)
"""
from __future__ import annotations

import argparse
import math
from dataclasses import replace

import numpy as np

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.boundary import Move
from bullet_dlo.core.integrators import NewtonOptions
from bullet_dlo.core.kernels.forces import clamp_torque
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec

H0 = 0.004  # [s] the largest step: contact stiffness alpha 1e4 there, the same k_n at every dt
DTS = (0.004, 0.002, 0.001, 0.0005)
REF = H0 / 64
T = 0.3  # [s] the roll
Z = 0.02  # [m] the clamp's height
NEWTON = NewtonOptions(tol=1e-8, max_iter=50)
SPEC = CableSpec(length=0.3, diameter=0.001, mass=0.024, youngs_modulus=2e9, section="rectangle", width=0.01,
                 thickness=0.001, n_masses=9, damping_rate=2.0, internal_damping=1e-3, static_friction=0.0,
                 dynamic_friction=0.0)


def model(roll: float = 0.0) -> CableModel:
    motion = [Move("first", rotation=(roll, 0.0, 0.0), duration=T)] if roll else []
    return CableModel.straight(SPEC, start=(0.0, 0.0, Z), ends=("clamped", "free"), motion=motion)


def material_axes(tw) -> np.ndarray:
    """The segments' material axes m1 (n-1, 3) of a twist state."""
    return np.cos(tw.theta)[:, None] * tw.ref + np.sin(tw.theta)[:, None] * np.cross(tw.tan, tw.ref)


def settled():
    """The strip at rest after 0.5 s (dt 0.5 ms) clamped flat, drooped onto the ground."""
    h = 0.0005
    with BulletWorld(dt=h, ground=True) as world:
        cable = world.add_cable(model(), integrator="bdf2", contact_stiffness=1e4 * (h / H0) ** 2, newton=NEWTON)
        world.run(0.5)
        state = cable.state()
    state.t = 0.0
    return state


def run(state, h, ground, method, roll, stops, as_reported=False):
    """Step the rolled strip from ``state`` at dt h; at each step count in ``stops`` take (torque about the clamp's
    axis [N m], x [m], m1), the contact rows' counts met and the steps whose Newton solve ended
    unconverged: the planned state at t + h (module docstring), or with ``as_reported``
    what ``cable.end_loads()`` and ``cable.state()`` give."""
    out = {}
    rows = set()
    with BulletWorld(dt=h, ground=ground) as world:
        cable = world.add_cable(model(roll), integrator=method, state=state.copy(),
                                contact_stiffness=1e4 * (h / H0) ** 2, newton=NEWTON)
        cp = cable._cp
        for k in range(1, max(stops) + 1):
            world.step()
            if ground:
                rows.add(int(cable.contacts.count[0]))
            if k in stops:
                if as_reported:
                    tq = cable.end_loads()[1][0]
                    x = cable.x.copy()
                    axis = cp.samples.dir[0, 0]
                else:  # x_new, v_new and the twist state: all at t + h (the clamp axes m.tw_clamp too)
                    axis = cp.samples.dir[2, 0]
                    tq = clamp_torque(cable.arrays, cp.x_new, cp.v_new, cp.samples.dir[2], 0)
                    x = cp.x_new.copy()
                tw = cable.state().twist if as_reported else cable.twist  # (the twist state planned for t + h)
                out[k] = (float(np.dot(tq, axis)), x, material_axes(tw))
        assert cable.stable, cable.reason
        fails = cable.newton_failures
    return out, rows, fails


def table(method: str, roll: float, as_reported: bool, dts=DTS, ref_h=REF) -> None:
    global DTS, REF
    DTS, REF = dts, ref_h
    start = settled()
    for ground in (True, False):
        # the reference stops where each run's compared state lies: at T + h (planned), or T (as reported)
        shift = 0 if as_reported else 1
        stops = {h: round(T / h) for h in DTS}
        ref_stops = {h: round((T + shift * h) / REF) - shift for h in DTS}
        ref, _, _ = run(start, REF, ground, method, roll, set(ref_stops.values()), as_reported)
        ref_at = {h: ref[k] for h, k in ref_stops.items()}
        print(f"\n{method}, {'on the ground (contact step)' if ground else 'no ground'}, "
              f"friction {SPEC.static_friction}")
        print(f"{'dt [ms]':>8} {'rows':>6} {'torque err [N m]':>17} {'order':>6} {'x err [m]':>10} {'order':>6} "
              f"{'m1 err':>10} {'order':>6} {'unconv.':>8}")
        prev = None
        for h in DTS:
            res, rows, fails = run(start, h, ground, method, roll, {stops[h]}, as_reported)
            tq, x, m1 = res[stops[h]]
            rtq, rx, rm1 = ref_at[h]
            err = (abs(tq - rtq), float(np.abs(x - rx).max()), float(np.abs(m1 - rm1).max()))
            orders = ["" if prev is None else f"{math.log2(p / e):.2f}" for p, e in zip(prev or err, err)]
            span = f"{min(rows)}-{max(rows)}" if rows else "0"
            print(f"{h * 1e3:8.2f} {span:>6} {err[0]:17.3e} {orders[0]:>6} {err[1]:10.3e} {orders[1]:>6} "
                  f"{err[2]:10.3e} {orders[2]:>6} {fails:>8}")
            prev = err
        print(f"  reference: dt {REF * 1e3:.4f} ms, torque about the axis {ref_at[DTS[-1]][0]:.6e} N m")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", choices=("bdf2", "implicit_euler"), default="bdf2")
    ap.add_argument("--roll", type=float, default=30.0, help="the clamp's roll over the run [deg], in (0, 90]")
    ap.add_argument("--as-reported", action="store_true",
                    help="compare cable.end_loads() and cable.state() as reported, at T")
    ap.add_argument("--friction", type=float, default=0.0, help="the strip's friction coefficient, >= 0")
    ap.add_argument("--fine", action="store_true", help="dt 1, 0.5, 0.25, 0.125 ms against dt 4 ms / 512")
    a = ap.parse_args(argv)
    if not 0.0 < a.roll <= 90.0:
        ap.exit(2, f"--roll must be in (0, 90] degrees, got {a.roll}\n")
    if not a.friction >= 0.0:
        ap.exit(2, f"--friction must be >= 0, got {a.friction}\n")
    global SPEC
    SPEC = replace(SPEC, static_friction=a.friction, dynamic_friction=a.friction)
    if a.fine:
        table(a.method, math.radians(a.roll), a.as_reported, (0.001, 0.0005, 0.00025, 0.000125), H0 / 512)
    else:
        table(a.method, math.radians(a.roll), a.as_reported)


if __name__ == "__main__":
    main()
