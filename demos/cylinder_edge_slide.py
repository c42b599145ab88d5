"""Issue 23 item 3 with a round edge: a cable on a table over a frictionless static cylinder, released at rest.

The table (friction mu with the cable) ends at x = 0; a cylinder of radius R along y touches its side face, its top
flush with the table top (axis at x = R, z = -R), frictionless: a pulley, so the table's friction alone holds the
cable. The cable (0.5 m, 3 mm, 12 g, E 1 MPa: the independent check's of 2026-12-07) is laid at rest length along its
path (on the table, level to above the axis, a quarter circle at the radius R + r plus the chords' sag, straight
down) so that the lumped rope's pull over the most the table's friction holds (``pull_over_hold``: a node on the
table holds mu times its weight, a node on the quarter arc at the angle theta from the top pulls its weight times
sin(theta), one below it its weight) is nearest ``--f``: a rope slides above 1 (the scene and its closed form are
tests/bullet/test_edge_cylinder.py's). It is released with a drag of 5 1/s times each mass, allowed 0.5 s to settle
and watched for ``--seconds``: "held" when the table end moved less than 2 mm, "slid" beyond 20 mm; "ok" when held
below 1 and slid above.

Cylinders have no wrap (box edges and a hull's sharp edges do: docs/concepts/contact.md, "Edges"), so a segment
about as long as the rounding's diameter 2 (R + r) or longer can lie straight across the cylinder, which pushes its
chord at one point, square to it, while the turn over the cylinder sits at the segment's nodes as bends: a coarse
cable hooks above the threshold (docs/concepts/contact.md, "A cable over a cylinder"), the table this script
measures.

    python demos/cylinder_edge_slide.py [--hz 60 240 1000] [--n 13 20 35] [--R 0.002 0.006 0.012 0.02] [--f 0.8 1.2]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

TESTS = Path(__file__).resolve().parents[1] / "tests" / "bullet"


def main() -> None:
    sys.path.insert(0, str(TESTS))
    from test_edge_cylinder import HOLD, SLID, release, thin_cable

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--hz", type=float, nargs="+", default=[60.0, 240.0, 1000.0], help="Bullet step rates [Hz]")
    ap.add_argument("--n", type=int, nargs="+", default=[13, 20, 35], help="numbers of masses")
    ap.add_argument("--R", type=float, nargs="+", default=[0.002, 0.006, 0.012, 0.02], help="cylinder radii [m]")
    ap.add_argument("--E", type=float, nargs="+", default=[1e6], help="Young's moduli [Pa]")
    ap.add_argument("--f", type=float, nargs="+", default=[0.8, 1.2],
                    help="the rope's pull over the most the table's friction holds (slides above 1)")
    ap.add_argument("--mu", type=float, default=0.4, help="friction of cable and table")
    ap.add_argument("--seconds", type=float, default=1.0, help="watch time after 0.5 s of settling [s]")
    a = ap.parse_args()
    for hz in a.hz:
        for n in a.n:
            for R in a.R:
                for E in a.E:
                    for f in a.f:
                        spec = thin_cable(n, E, a.mu)
                        t, q, cable = release(spec, R, f, hz, a.seconds)
                        word = "held" if abs(t) < HOLD else ("slid" if t > SLID else "moved")
                        ok = cable.stable and word != "moved" and (word == "held") == (q < 1.0)
                        print(f"{hz:6.0f} Hz  n {n:3d} (l {spec.rest_length * 1e3:4.1f} mm)  R {R * 1e3:4.1f} mm  "
                              f"E {E:.0e}  mu {a.mu:g}  pull/hold {q:.2f}: {word} {t * 1e3:7.2f} mm"
                              f"{'' if cable.stable else '  unstable: ' + cable.reason}  {'ok' if ok else 'WRONG'}",
                              flush=True)


if __name__ == "__main__":
    main()
