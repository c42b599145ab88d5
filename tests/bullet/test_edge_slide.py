"""A cable lying on a table (a box) with a fraction phi hanging over its sharp edge, released at rest.

Closed form (light, flexible, inextensible cable; mu_s = mu_d = mu on the table and at the edge):
the part on the table, (1 - phi) L long, holds the cable at the edge with at most its friction,
T_in = mu (1 - phi) w L (w: weight per length [N/m]); the hanging part pulls with T_out = phi w L.
The cable, a tube of radius r, wraps the edge: its axis follows an arc of radius r about the edge
through the wrap angle theta = pi/2, a capstan (the capstan's ratio does not depend on the radius),
so it slips when T_out > exp(mu theta) T_in, i.e. when

    phi / (1 - phi) > mu exp(mu pi / 2),   phi* = mu e / (1 + mu e),  e = exp(mu pi / 2)

(0.325 for mu = 0.3). The issue's phi > mu / (1 + mu) (0.231) treats the edge as a frictionless pulley;
a single frictional point turning the cable by pi/2 would give (1 + mu) / (1 - mu) instead of e
(phi* = 0.358); an elastica touching the edge at one point (bending length sqrt(EI/T) much larger
than r) gives T_out / T_in = 1.52 at mu = 0.3 (phi* = 0.314), 5 % below the capstan.

The contact model reaches this threshold within 10 % (holds at 0.9 phi*, slides at 1.1 phi*) when its
segments are short against the cable's bend at the edge: n = 40 (15 mm segments; sqrt(EI/T) = 30 mm),
checked here at 60, 240 and 1000 Hz at three placements. Coarser cables (n = 10, 20) still hook above
phi*: the segment across the edge stays straight and bends at a node beyond it, a lever that a chain of
straight segments holds (docs/concepts/contact.md, "Edges"; `python demos/edge_slide.py` prints the
table). These threshold tests pin the resolved case; they do not test a change of the contact law.

"""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.model import CableState
from bullet_dlo.core.spec import CableSpec

MU = 0.3
TABLE = (0.5, 0.1, 0.05)  # [m] half extents; the top face at z = 0, the edge along y at x = 0


def threshold(mu: float) -> float:
    """phi* = mu e / (1 + mu e), e = exp(mu pi / 2): the capstan over the edge (module docstring)."""
    e = mu * math.exp(mu * math.pi / 2)
    return e / (1.0 + e)


def soft_cable(n: int, mu: float = MU, youngs_modulus: float = 2e6) -> CableSpec:
    """0.6 m, 4 mm, 9 g (the capstan tests' cable), friction mu_s = mu_d = mu."""
    return CableSpec(length=0.6, diameter=0.004, mass=0.009, youngs_modulus=youngs_modulus, n_masses=n,
                     dynamic_friction=mu, static_friction=mu)


def layout(spec: CableSpec, phi: float, place: float, through: bool = False) -> tuple[np.ndarray, float]:
    """Nodes (n, 3) of a cable on the table with about ``phi`` of it beyond the edge, and that fraction.

    The last node on the table lies ``place`` segment lengths before the edge (0 < place < 1; 0: the edge
    under a node). ``through=False``: the next segment goes straight on across the edge and the rest hangs
    from its far node (as a cable pushed over an edge lies before it drapes). ``through=True``: the
    nodes follow the table and the side face around the corner point (r, r), so the segment across the
    corner cuts through the box's edge (a state a tunnelling step can leave)."""
    n, L, l, r = spec.n_masses, spec.length, spec.rest_length, spec.diameter / 2
    a = place * l
    i = round(((1.0 - phi) * L - a) / l)  # the last node on the table
    x = np.zeros((n, 3))
    for j in range(n):
        if through:
            s = (j - i) * l - a  # arc length past the edge along the L path
            x[j] = (r + s, 0.0, r) if s <= 0.0 else (r, 0.0, r - s)
        elif j <= i + 1:
            x[j] = (-a - (i - j) * l, 0.0, r)
        else:
            x[j] = (l - a, 0.0, r - (j - i - 1) * l)
    return x, 1.0 - (i * l + a) / L


def bracket(n: int, place: float, star: float) -> tuple[float, float]:
    """The hanging fractions a layout allows, 1 - (k + place) / (n - 1) for whole k, nearest 0.9 and 1.1
    times ``star``, one below it and one above."""
    phis = [1.0 - (k + place) / (n - 1) for k in range(n - 1)]
    return (min((p for p in phis if p < star), key=lambda p: abs(p - 0.9 * star)),
            min((p for p in phis if p > star), key=lambda p: abs(p - 1.1 * star)))


def hang(spec: CableSpec, phi: float, place: float, hz: float = 240.0, settle: float = 0.5, seconds: float = 1.0,
         through: bool = False, drag: float = 5.0):
    """Release the cable at rest (:func:`layout`), let it drape over the edge for ``settle`` [s], then watch it
    for ``seconds`` [s]. A drag of ``drag`` [1/s] times each mass damps the swing of the hanging part (no
    force at rest). Returns (the table end's travel towards the edge while watched [m], the actual phi,
    the cable; stable or not)."""
    x0, phi_true = layout(spec, phi, place, through)
    with BulletWorld(dt=1.0 / hz, ground=False) as world:
        world.add_box(TABLE, (-TABLE[0], 0.0, -TABLE[2]), friction=spec.static_friction)  # combined: mu
        cable = world.add_cable(spec, state=CableState(x0, np.zeros_like(x0)))
        cable.set_parameters(damp=drag * cable.model.arrays.mass)
        start = cable.x[0, 0]
        for k in range(round((settle + seconds) * hz)):
            world.step()
            if k + 1 == round(settle * hz):
                start = cable.x[0, 0]
            if not cable.stable or cable.x[0, 0] > 0.0:
                break  # unstable, or slid off the table
        return float(cable.x[0, 0] - start), phi_true, cable


HOLD, SLIDE = 0.002, 0.05  # [m] travel of the table end in the second after settling: held / sliding


@pytest.mark.parametrize("hz, place", [(60.0, 0.05), (240.0, 0.25), (1000.0, 0.75)])
def test_slides_over_the_edge_at_the_capstan_threshold(hz, place):
    spec = soft_cable(40)  # l = 15 mm, shorter than the bend sqrt(EI / T) = 30 mm at the edge
    star = threshold(MU)
    lo, hi = bracket(spec.n_masses, place, star)
    assert 0.85 * star < lo < star < hi < 1.15 * star  # the layout's phi steps by 1/39: near 0.9 and 1.1 phi*
    below, phi_lo, c_lo = hang(spec, lo, place, hz)
    above, phi_hi, c_hi = hang(spec, hi, place, hz)
    assert c_lo.stable and c_hi.stable, (c_lo.reason, c_hi.reason)
    assert phi_lo == pytest.approx(lo) and phi_hi == pytest.approx(hi)
    assert below < HOLD, f"phi {phi_lo:.3f} < phi* {star:.3f} slid {below * 1e3:.1f} mm"
    assert above > SLIDE, f"phi {phi_hi:.3f} > phi* {star:.3f} held ({above * 1e3:.1f} mm)"
