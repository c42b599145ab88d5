"""A flat ribbon landing on the ground with its section tilted: where it works, and where it still fails (issue 22).

A PET ribbon (0.4 m, 20 x 0.3 mm, E 2 GPa, damping_rate 5) is clamped 5 cm above the ground with its clamp rolled
``--roll`` rad about the cable's axis (its weak axis tilted), released straight, and falls onto the ground in Bullet
(BDF2 by default, the model's contact). Each case runs ``--duration`` s or until the run's instability detector stops
it, and prints whether it stayed stable (else when and why it was stopped), its Newton failures and iterations per
step (a retried step's sub-steps counted), the twist angles' range at the end [rad] and the lowest node's height over
the run's last 0.2 s [mm] (a ribbon lying flat on the ground has its centre line at half its thickness, 0.15 mm: the
contact presses with the rectangle's section, docs/concepts/contact.md, "Flat sections"; ``--diameter`` is the round
envelope of the other contact layers).

What it shows (the table in docs/concepts/model.md, "A tilted ribbon landing with friction"): a ribbon clamped flat
lands at every rate; with its section tilted it lands or rests tilted (the clamp's twist, friction) from 60 Hz to 1
kHz, with and without friction, from n 11 to 41. The frictional landings needed the section's contact forces to
carry their bending couples (the gradient of the potential Newton's line search descends), the friction's whole
slip gradient in the Newton matrix, and an indefinite exact matrix to be shifted rather than replaced by
Gauss-Newton's; at 60 and 120 Hz the touch-down steps are taken again as sub-steps, and at 60 Hz a ribbon rolled 1
rad needed a Gauss-Newton matrix that is positive semi-definite (its direction had ascended).

    python demos/ribbon_landing.py                        # rolls 0, 0.3, 1; friction 0 and 0.3; 240 Hz, 1 kHz
    python demos/ribbon_landing.py --rates 4000 --rolls 0.3
    python demos/ribbon_landing.py --rates 1000 --rolls 0.3 --frictions 0.3 --widths 0.0006 0.003 0.01 0.02
    python demos/ribbon_landing.py --quick                # one tilted case each way, 1 kHz (~10 s)
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec

HEIGHT = 0.05  # [m] the clamp above the ground
SETTLE_WINDOW = 0.2  # [s] the last part of a run whose lowest node is reported
WIDTH, THICKNESS = 0.02, 0.0003  # [m] the ribbon's section
DIAMETER = 0.001  # [m] the round envelope of the contact layers that do not see the section


def ribbon(n_masses: int, friction: float, width: float = WIDTH, diameter: float = DIAMETER) -> CableSpec:
    """The PET ribbon: 0.4 m, ``width`` [m] x 0.3 mm, density 1400 kg/m^3, E 2 GPa; Coulomb friction ``friction``
    (static and dynamic); the round envelope ``diameter`` [m] of the contact layers that do not see the section."""
    return CableSpec(length=0.4, diameter=diameter, mass=0.4 * width * THICKNESS * 1400, youngs_modulus=2e9,
                     section="rectangle", width=width, thickness=THICKNESS, n_masses=n_masses, damping_rate=5.0,
                     static_friction=friction, dynamic_friction=friction)


def land(rate: float, roll: float, friction: float, n_masses: int, duration: float, method: str,
         width: float = WIDTH, diameter: float = DIAMETER) -> dict:
    """One landing at ``rate`` [Hz] from a clamp rolled ``roll`` [rad]; returns what the module doc lists."""
    model = CableModel.straight(ribbon(n_masses, friction, width, diameter), start=(0.0, 0.0, HEIGHT),
                                ends=("clamped", "free"), roll=(roll, 0.0))
    steps = int(round(duration * rate))
    window = max(1, int(round(SETTLE_WINDOW * rate)))
    lowest = np.inf
    t0 = time.thread_time()
    with BulletWorld(dt=1.0 / rate) as world:
        cable = world.add_cable(model, integrator=method)
        for k in range(steps):
            world.step()
            if not cable.stable:
                break
            if k >= steps - window:
                lowest = min(lowest, float(cable.x[:, 2].min()))
        theta = cable.twist.theta
        return {"rate": rate, "roll": roll, "friction": friction, "width": width, "stable": cable.stable,
                "stopped_at": None if cable.stable else (k + 1) / rate, "reason": cable.reason,
                "newton_failures": cable.newton_failures, "steps": k + 1,
                "iterations": cable.newton_iterations / (k + 1),
                "theta": (float(theta.min()), float(theta.max())), "lowest_mm": 1e3 * lowest,
                "cpu_s": time.thread_time() - t0}


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--rates", type=float, nargs="+", default=[240.0, 1000.0], help="Bullet rates [Hz]")
    p.add_argument("--rolls", type=float, nargs="+", default=[0.0, 0.3, 1.0], help="clamp rolls [rad]")
    p.add_argument("--frictions", type=float, nargs="+", default=[0.0, 0.3], help="Coulomb coefficients [-]")
    p.add_argument("--widths", type=float, nargs="+", default=[WIDTH],
                   help="section widths [m] (thickness 0.3 mm; default 0.02): the stiffnesses' ratio is (w/h)^2")
    p.add_argument("--diameter", type=float, default=DIAMETER,
                   help="the round envelope of the contact layers that do not see the section (self-contact, "
                        "other cables, edge wraps) [m] (default 0.001)")
    p.add_argument("--n", type=int, default=41, help="masses (default 41)")
    p.add_argument("--duration", type=float, default=1.0, help="simulated time per case [s] (default 1)")
    p.add_argument("--method", default="bdf2", help="integrator (default bdf2)")
    p.add_argument("--quick", action="store_true", help="roll 0.3 at 1 kHz, frictionless and mu 0.3, 0.4 s")
    args = p.parse_args(argv)
    if args.quick:
        args.rates, args.rolls, args.frictions, args.duration = [1000.0], [0.3], [0.0, 0.3], 0.4
    print(f"ribbon 0.4 m x 0.3 mm thick, n {args.n}, {args.method}, clamp {HEIGHT * 1e3:.0f} mm above the ground")
    print("width [mm]  rate [Hz]  roll [rad]  mu   result                                    Newton failures  "
          "iterations per step  theta [rad]       lowest node, last 0.2 s [mm]  CPU [s]")
    cases = [(w, rate, roll, mu) for w in args.widths for rate in args.rates for roll in args.rolls
             for mu in args.frictions]
    for width, rate, roll, mu in cases:
        r = land(rate, roll, mu, args.n, args.duration, args.method, width, args.diameter)
        result = "stable" if r["stable"] else f"stopped at {r['stopped_at']:.3f} s: {r['reason']}"
        low = f"{r['lowest_mm']:.2f}" if r["stable"] else "-"
        print(f"{1e3 * width:10.1f}  {rate:9.0f}  {roll:10.2f}  {mu:3.1f}  {result:40.40s}  "
              f"{r['newton_failures']:6d} of {r['steps']:<6d}  {r['iterations']:19.1f}  "
              f"{r['theta'][0]:+.2f}..{r['theta'][1]:+.2f}  {low:>12s}  "
              f"{r['cpu_s']:.1f}")


if __name__ == "__main__":
    main()
