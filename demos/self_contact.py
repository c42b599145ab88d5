"""A cable lying on itself: folded flat along its length, and a coil whose stacked turns settle on each other.

    PYTHONPATH=. python demos/self_contact.py [--rates 60 240 1000] [--n 40 80 160]
    PYTHONPATH=. python demos/self_contact.py --coils --rates 1000 --n 30 40 50 --turns 1.8 2.2 2.6 --duration 3

Fold: a soft 0.3 m Lv cable (E 0.1 MPa) lies 0.165 m on the ground along x, turns up and back, and the rest lies
along the lower strand 0.1 mm above contact; after 1 s, per rate and n: the vertical self-contact force on the upper
strand's nodes and on the lower strand's over the upper strand's weight (equal and opposite; the U-turn holds the
rest of it), the sum of all self-contact forces over the weight (internal: 0), the ground's support over the weight,
the largest speed and the lowest node of the upper strand away from the U-turn over the radius (3: on the lower one).
Coil: a 0.6 m, 60 g cable (E 1 MPa) wound as a helix of 2.2 turns (``--turns``) standing on the ground, turns 0.1 mm
apart (with a material frame: ``--twist``), after 1.5 s (``--duration``): the same sums, the closest approach of
segments far apart along the cable over the run over the diameter, the steps whose contact solve ended unconverged,
and whether the run was stopped (``--coils``: the coils alone). ``--coulomb`` adds the reported rows
(``contact_forces()`` after every step) whose friction exceeds mu_s times their normal force: in the steps whose
solve ended unconverged, in the others (of these, how many with f_n = 0), and the largest ratio to mu_s f_n in the
others. See docs/concepts/contact.md, "Self-contact".

    PYTHONPATH=. python demos/self_contact.py --coils --coulomb --rates 240 --n 40 --duration 1
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "bullet"))
from test_contact_self import coil, fold  # noqa: E402  (the tests' scenes)


def fold_row(rate: float, n: int) -> str:
    cable, spec, cf, ground = fold(rate, n)
    r, weight = spec.diameter / 2, spec.mass * 9.81
    x = cable.x
    upper = x[:, 2] > 2 * r
    strand = upper & (x[:, 0] < x[upper, 0].max() - 0.02)
    own = cf["body"] == -1
    on_upper = sum(cf["force"][k, 2] for k in np.nonzero(own)[0] if upper[cf["node"][k, 0]])
    on_lower = sum(cf["force"][k, 2] for k in np.nonzero(own)[0] if not upper[cf["node"][k, 0]])
    w_up = upper.mean() * weight
    return (f"{rate:>5.0f} {n:>4} {on_upper / w_up:>+8.4f} {on_lower / w_up:>+9.4f} "
            f"{np.abs(cf['force'][own].sum(axis=0)).max() / weight:>9.1e} "
            f"{cf['force'][cf['body'] == ground, 2].sum() / weight:>8.4f} {np.abs(cable.v).max():>8.1e} "
            f"{x[strand, 2].min() / r:>7.4f}  {cable.reason or '-'}")


class CoulombTally:
    """Per step (called with the cable): the reported rows, and those whose friction exceeds mu_s f_n (1e-9 relative
    allowance), split by whether the step's contact solve ended unconverged; of the others, those with f_n = 0 and the
    largest |f_t| / (mu_s f_n) of the rest."""

    def __init__(self) -> None:
        self.rows = self.beyond_unconverged = self.beyond_converged = self.zero_normal = 0
        self.worst = 0.0
        self._failures = 0

    def __call__(self, cable) -> None:
        failures = cable.solver.newton_failures
        unconverged, self._failures = failures > self._failures, failures
        cf = cable.contact_forces()
        fn, ft = cf["normal_force"], np.linalg.norm(cf["friction"], axis=1)
        bound = cable.contacts.static_friction[:fn.shape[0]] * fn
        beyond = ft > bound + 1e-9 * (1.0 + ft)
        self.rows += fn.shape[0]
        if unconverged:
            self.beyond_unconverged += int(beyond.sum())
        else:
            self.beyond_converged += int(beyond.sum())
            pushing = beyond & (bound > 0.0)
            self.zero_normal += int((beyond & ~pushing).sum())
            self.worst = max(self.worst, float((ft[pushing] / bound[pushing]).max(initial=0.0)))


def coil_row(rate: float, n: int, turns: float, duration: float, twist: bool, coulomb: bool = False) -> str:
    tally = CoulombTally() if coulomb else None
    cable, spec, cf, ground, closest = coil(rate, n, duration, turns, twist, each_step=tally)
    weight = spec.mass * 9.81
    own = cf["body"] == -1
    s = cable.solver
    row = (f"{rate:>5.0f} {n:>4} {turns:>5.2f} {np.abs(cf['force'][own].sum(axis=0)).max() / weight:>9.1e} "
           f"{cf['force'][cf['body'] == ground, 2].sum() / weight:>8.4f} {np.abs(cable.v).max():>8.1e} "
           f"{closest / spec.diameter:>8.4f} {f'{s.newton_failures}/{s.steps_planned}':>10}")
    if tally is not None:
        row += (f" {tally.rows:>7} {tally.beyond_unconverged:>8} {tally.beyond_converged:>8} {tally.zero_normal:>6} "
                f"{tally.worst:>8.3g}")
    return row + f"  {cable.reason or '-'}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rates", type=float, nargs="+", default=[60, 240, 1000], help="Bullet step rates [Hz]")
    ap.add_argument("--n", type=int, nargs="+", default=[40, 80], help="node counts")
    ap.add_argument("--turns", type=float, nargs="+", default=[2.2], help="the coil's turns")
    ap.add_argument("--duration", type=float, default=1.5, help="the coil's settling time [s]")
    ap.add_argument("--coils", action="store_true", help="the coils alone (no fold)")
    ap.add_argument("--twist", action="store_true", help="coils with a material frame")
    ap.add_argument("--coulomb", action="store_true",
                    help="coils: count the reported rows whose friction exceeds mu_s times their normal force")
    a = ap.parse_args()
    if not a.coils:
        fold_table(a.rates, a.n)
    print("coil")
    head = (f"{'rate':>5} {'n':>4} {'turns':>5} {'net/W':>9} {'ground/W':>8} {'|v| max':>8} {'min/d':>8} "
            f"{'unconv.':>10}")
    if a.coulomb:
        head += f" {'rows':>7} {'>mu f_n':>8} {'>mu f_n':>8} {'f_n=0':>6} {'worst':>8}  (unconverged / converged steps)"
    print(head + "  stopped")
    for rate in a.rates:
        for n in a.n:
            for turns in a.turns:
                print(coil_row(rate, n, turns, a.duration, a.twist, a.coulomb), flush=True)


def fold_table(rates: list[float], ns: list[int]) -> None:
    print("fold")
    print(f"{'rate':>5} {'n':>4} {'up/Wup':>8} {'low/Wup':>9} {'net/W':>9} {'ground/W':>8} {'|v| max':>8} "
          f"{'z_up/r':>7}  stopped")
    for rate in rates:
        for n in ns:
            print(fold_row(rate, n), flush=True)


if __name__ == "__main__":
    main()
