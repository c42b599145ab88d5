"""Issue 23 item 3: a cable on a table with a fraction phi hanging over the sharp edge, released at rest.

For each rate, n, Young's modulus and edge placement (the last node on the table ``place`` segment
lengths before the edge) the cable is released at the hanging fractions its layout allows (steps of
1 / (n - 1)) nearest 0.9 and 1.1 times the capstan threshold phi* = mu e / (1 + mu e),
e = exp(mu pi / 2) (tests/bullet/test_edge_slide.py derives it), one either side, allowed 0.5 s to
drape, then watched for 1 s: "held" when its table end moved less than 2 mm, "slid" above 50 mm
("ok": held below and slid above). Also printed: the segment length l and the bend length
sqrt(EI / T) of the cable at the edge (T = phi* w L), which the segments have to resolve.

    PYTHONPATH=. python demos/edge_slide.py [--rates 60 240 1000] [--n 10 20 40] [--E 2e6 8e6] [--places 0.05 0.25 0.5 0.75]

``--lumped``: the model's own hanging fraction instead (the mass of the nodes beyond the edge; the
masses are lumped at the nodes, so it steps by 1/(n - 1)), from the layout draped round the edge at rest length, with
mu set so that it lies at 0.9 and 1.1 times phi*(mu) ("ok": held below 2 mm, slid above 20 mm; the
table of docs/concepts/contact.md, "Edges"). Beside the travel above the threshold it prints the travel of the
same lumped cable as an inextensible rope (:func:`rope_travel`: the capstan at the edge, Coulomb on the table, the
same drag, phi growing by 1/(n - 1) as each node passes the edge), the yardstick for how fast it should slide
("ok" above the threshold: 20 mm or half the rope's travel, whichever is less):

    PYTHONPATH=. python demos/edge_slide.py --lumped [--rates 60 240 1000] [--n 10 20 40] [--places 0.25 0.5 0.75]

``--corner``: the draped cable (0.2 hanging, mu 0.3) pushed along the edge off the table's corner (tests/bullet/
test_edge_slide.py's ``push_off_the_corner``) for each push [m/s^2] and start [m] of ``--pushes`` / ``--starts``
(paired), rate and n: whether it stayed stable, when it had left the table, how high a node rose after the push
began (a cable sliding off a corner falls; docs/concepts/contact.md, "Corners"):

    PYTHONPATH=. python demos/edge_slide.py --corner [--rates 60 240 1000] [--n 10 20 40 80]

``--trace PHI``: one run well above the threshold, the model's and the rope's travel and speed every 0.1 s (where the
model loses its speed: at each node's crossing of the edge):

    PYTHONPATH=. python demos/edge_slide.py --trace 0.5 --rates 240 --n 20 --places 0.5
"""
from __future__ import annotations

import argparse
import itertools
import math
import sys
from pathlib import Path

TESTS = Path(__file__).resolve().parents[1] / "tests" / "bullet"


def rope_travel(n: int, place: float, phi: float, mu: float, settle: float = 0.5, seconds: float = 1.0,
                drag: float = 5.0, length: float = 0.6, g: float = 9.81, dt: float = 1e-4) -> float:
    """Travel [m] of the table end in the ``seconds`` after ``settle`` [s] of a lumped cable with hanging fraction
    ``phi`` at rest as an inextensible rope: its last node on the table ``place`` segment lengths before the edge,
    each node that passes the edge adding 1/(n - 1) to phi; the hanging part pulls phi w L, the table part and the
    capstan over the edge hold mu e (1 - phi) w L (e = exp(mu pi / 2)), the drag takes ``drag`` [1/s] times the
    momentum. Stops where the table end reaches the edge, and counts from the release if that is before the watch
    (as the demo's run does)."""
    path = rope_path(n, place, phi, mu, settle + seconds, drag, length, g, dt)
    if not path:
        return 0.0
    start = next((s for t, s, _ in path if t >= settle), 0.0)
    return path[-1][1] - start


def rope_path(n: int, place: float, phi: float, mu: float, seconds: float, drag: float = 5.0, length: float = 0.6,
              g: float = 9.81, dt: float = 1e-4) -> list[tuple[float, float, float]]:
    """(t [s], travel [m], speed [m/s]) after each step dt [s] of :func:`rope_travel`'s rope released at rest, over
    ``seconds`` or until its table end reaches the edge."""
    e = math.exp(mu * math.pi / 2)
    seg = length / (n - 1)
    s = v = t = 0.0
    out = []
    while t < seconds and s < (1.0 - phi) * length:
        passed = 0 if s < place * seg else 1 + int((s - place * seg) / seg)
        f = min(phi + passed / (n - 1), 1.0)
        acc = g * (f - mu * e * (1.0 - f)) - drag * v
        if v <= 0.0 and acc < 0.0:  # held by static friction
            acc = v = 0.0
        v += acc * dt
        s += v * dt
        t += dt
        out.append((t, s, v))
    return out


def trace(hz: float, n: int, place: float, phi: float, mu: float, seconds: float = 1.5) -> None:
    """Print every 0.1 s the table end's travel and speed of the model (released at rest, draped round the edge with
    hanging fraction about ``phi``) and of the inextensible rope, and the nodes within 4 mm of the edge."""
    import numpy as np
    from test_edge_slide import TABLE, layout, lumped_fraction, soft_cable

    from bullet_dlo.bullet.world import BulletWorld
    from bullet_dlo.core.model import CableState

    spec = soft_cable(n, mu)
    x0, _ = layout(spec, phi, place, wrapped=True)
    rope = rope_path(n, place, lumped_fraction(x0), mu, seconds)
    e = math.exp(mu * math.pi / 2)
    print(f"lumped phi {lumped_fraction(x0):.3f}, phi* {mu * e / (1 + mu * e):.3f}")
    print("| t [s] | model travel [mm] | model speed [mm/s] | rope travel [mm] | rope speed [mm/s] | "
          "nodes at the edge |")
    print("|---|---|---|---|---|---|")
    with BulletWorld(dt=1.0 / hz, ground=False) as world:
        world.add_box(TABLE, (-TABLE[0], 0.0, -TABLE[2]), friction=mu)
        cable = world.add_cable(spec, state=CableState(x0, np.zeros_like(x0)))
        cable.set_parameters(damp=5.0 * cable.model.arrays.mass)
        start, every = cable.x[0, 0], max(1, round(hz / 10))
        for k in range(round(seconds * hz)):
            world.step()
            if not cable.stable or cable.x[0, 0] > 0.0:
                print(f"stopped at {(k + 1) / hz:.3f} s: {cable.reason or 'the table end reached the edge'}")
                break
            if (k + 1) % every == 0:
                t = (k + 1) / hz
                _, rs, rv = min(rope, key=lambda r: abs(r[0] - t)) if rope else (t, 0.0, 0.0)
                edge = [i for i in range(n) if abs(cable.x[i, 0]) < 0.004 and cable.x[i, 2] > -0.004]
                print(f"| {t:.1f} | {(cable.x[0, 0] - start) * 1e3:.1f} | {cable.v[0, 0] * 1e3:.1f} | {rs * 1e3:.1f} | "
                      f"{rv * 1e3:.1f} | {edge} |", flush=True)


def corner(pushes: list[float], starts: list[float], rates: list[float], ns: list[int]) -> None:
    """Print one row per push, rate and n of the cable pushed off the table's corner (``push_off_the_corner``, 2 s)."""
    from test_edge_slide import push_off_the_corner, soft_cable

    print("| push [m/s^2] | start [m] | Hz | n | stable | off the table at [s] | highest rise [mm] |")
    print("|---|---|---|---|---|---|---|")
    done, total = 0, 0
    for (push, start), hz, n in itertools.product(zip(pushes, starts), rates, ns):
        top, passed, cable = push_off_the_corner(n, hz, 2.0, push, start)
        rise = (top - soft_cable(n).diameter / 2) * 1e3
        off = f"{passed:.2f}" if passed is not None else "no"
        done += cable.stable and passed is not None
        total += 1
        print(f"| {push:g} | {start:g} | {hz:g} | {n} | {cable.stable or cable.reason} | {off} | {rise:.1f} |",
              flush=True)
    print(f"stable and off the table: {done} of {total}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rates", type=float, nargs="+", default=[60.0, 240.0, 1000.0])
    ap.add_argument("--n", type=int, nargs="+", default=[10, 20, 40])
    ap.add_argument("--E", type=float, nargs="+", default=[2e6])
    ap.add_argument("--places", type=float, nargs="+", default=[0.05, 0.25, 0.5, 0.75])
    ap.add_argument("--mu", type=float, default=0.3)
    ap.add_argument("--lumped", action="store_true", help="the lumped hanging fraction at 0.9 / 1.1 phi*(mu)")
    ap.add_argument("--trace", type=float, metavar="PHI",
                    help="one run (the first rate, n and place) released with hanging fraction PHI at --mu: the "
                         "model's and the rope's travel and speed every 0.1 s")
    ap.add_argument("--corner", action="store_true", help="push the draped cable along the edge off the table's corner")
    ap.add_argument("--pushes", type=float, nargs="+", default=[5.0, 3.5, 8.0],
                    help="--corner: push accelerations [m/s^2], each > 0.3 g (default 5 3.5 8)")
    ap.add_argument("--starts", type=float, nargs="+", default=[0.07, 0.05, 0.05],
                    help="--corner: start positions along the edge [m], one per push, below 0.1 (default 0.07 0.05 0.05)")
    args = ap.parse_args()
    sys.path.insert(0, str(TESTS))
    if args.corner:
        if len(args.starts) != len(args.pushes) or min(args.pushes) <= 0.3 * 9.81 or max(args.starts) >= 0.1:
            sys.exit(print("--pushes and --starts need one start (< 0.1 m) per push (> 0.3 g)", file=sys.stderr) or 2)
        corner(args.pushes, args.starts, args.rates, args.n)
        return
    if args.trace is not None:
        trace(args.rates[0], args.n[0], args.places[0], args.trace, args.mu)
        return
    from test_edge_slide import HOLD, SLID, SLIDE, bracket, hang, layout, lumped_fraction, mu_for, soft_cable, threshold

    if args.lumped:
        print("| Hz | n | place | lumped phi | mu at 0.9 phi* | travel [mm] | mu at 1.1 phi* | travel [mm] | "
              "rigid rope [mm] | verdict |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for hz, n, place in itertools.product(args.rates, args.n, args.places):
            x, _ = layout(soft_cable(n), threshold(args.mu), place, wrapped=True)
            phi = lumped_fraction(x)
            runs = []
            for f in (0.9, 1.1):
                mu = mu_for(phi / f)
                travel, _, cab = hang(soft_cable(n, mu), threshold(args.mu), place, hz, wrapped=True)
                runs.append((mu, travel, cab))
            (mu_lo, lo, c_lo), (mu_hi, hi, c_hi) = runs
            rope = rope_travel(n, place, phi, mu_hi)
            if not (c_lo.stable and c_hi.stable):
                verdict = f"unstable: {c_lo.reason or c_hi.reason}"
            else:  # sliding: 20 mm, or half the rope's travel where a slow slide near the threshold goes less far
                slid = hi > min(SLID, 0.5 * rope)
                verdict = "ok" if lo < HOLD and slid else ("slid below" if lo >= HOLD else "hooked")
            print(f"| {hz:.0f} | {n} | {place} | {phi:.3f} | {mu_lo:.3f} | {lo * 1e3:.1f} | {mu_hi:.3f} | "
                  f"{hi * 1e3:.1f} | {rope * 1e3:.0f} | {verdict} |", flush=True)
        return

    star = threshold(args.mu)
    print(f"mu {args.mu}: phi* = {star:.3f} (capstan over the edge); frictionless edge {args.mu / (1 + args.mu):.3f}")
    print("| Hz | n | E [MPa] | l [mm] | bend [mm] | place | phi/phi* | travel [mm] | phi/phi* | travel [mm] | verdict |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    rows = {}
    for hz, n, E, place in itertools.product(args.rates, args.n, args.E, args.places):
        spec = soft_cable(n, args.mu, E)
        w = spec.mass / spec.length * 9.81
        ei = E * math.pi * (spec.diameter / 2) ** 4 / 4
        bend = math.sqrt(ei / (star * w * spec.length))
        phi_lo, phi_hi = bracket(n, place, star)
        lo, phi_lo, c_lo = hang(spec, phi_lo, place, hz)
        hi, phi_hi, c_hi = hang(spec, phi_hi, place, hz)
        if not (c_lo.stable and c_hi.stable):
            verdict = f"unstable: {c_lo.reason or c_hi.reason}"
        elif hi < HOLD:
            verdict = "hooked"
        elif lo >= HOLD:
            verdict = "slid below"
        else:
            verdict = "ok" if hi > SLIDE else "slow"
        rows.setdefault((hz, n, E, spec.rest_length, bend), []).append((place, verdict))
        print(f"| {hz:.0f} | {n} | {E / 1e6:g} | {spec.rest_length * 1e3:.1f} | {bend * 1e3:.0f} | {place} | "
              f"{phi_lo / star:.2f} | {lo * 1e3:.1f} | {phi_hi / star:.2f} | {hi * 1e3:.1f} | {verdict} |", flush=True)
    print()
    print("| Hz | n | E [MPa] | l [mm] | bend sqrt(EI/T) [mm] | held below phi*, slid above | otherwise |")
    print("|---|---|---|---|---|---|---|")
    for (hz, n, E, l, bend), res in rows.items():
        other = ", ".join(f"{v} at place {p}" for p, v in res if v != "ok") or "-"
        print(f"| {hz:.0f} | {n} | {E / 1e6:g} | {l * 1e3:.1f} | {bend * 1e3:.0f} | "
              f"{sum(v == 'ok' for _, v in res)} of {len(res)} | {other} |")


if __name__ == "__main__":
    main()
