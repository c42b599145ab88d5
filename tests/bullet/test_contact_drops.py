"""Drops onto the ground, a box and pegs at robot rates: no false alarm, no tunnelling, nothing left moving.

Before the contact model: n = 10 fell straight through a 10 mm peg (33 mm segments, 4 mm
spheres), and 3 of 9 drops on the box and 7 of 9 on the peg were stopped by the energy check.
A representative grid runs here; ``demos/contact_demo.py --drops`` runs all 108 combinations.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

Q_AXIS_Y = (math.sin(math.pi / 4), 0.0, 0.0, math.cos(math.pi / 4))
PEG_Z = 0.06  # [m] peg axis height: the cable drapes over it onto the ground


def drop(target: str, integrator: str, hz: float, n: int, peg_radius: float = 0.008, duration: float = 2.0):
    """Drop an Lv cable (damping 0.02) 5 cm onto ``target``; returns (cable, tunnelled, worst gap [m])."""
    spec = CableSpec.lv2017(n_masses=n, damping=0.02)
    r = spec.diameter / 2
    with BulletWorld(dt=1.0 / hz) as world:
        if target == "ground":
            top = 0.0

            def through(x):
                return x[:, 2] < -r
        elif target == "box":
            world.add_box((0.1, 0.1, 0.1), (0, 0, 0.1))
            top = 0.2

            def through(x):
                return (np.abs(x[:, 0]) < 0.1 - 2 * r) & (x[:, 2] < top - r)
        else:
            world.add_cylinder(peg_radius, 0.2, (0, 0, PEG_Z), Q_AXIS_Y)
            top = PEG_Z + peg_radius

            def through(x):  # a node right by the peg below its axis: the cable passed it
                return (np.abs(x[:, 0]) < 0.5 * spec.rest_length) & (x[:, 2] < PEG_Z)
        cable = world.add_cable(spec, start=(-0.15, 0, top + r + 0.05), direction=(1, 0, 0), integrator=integrator)
        tunnelled, worst_gap = False, 0.0
        for _ in range(int(duration * hz)):
            world.step()
            if not cable.stable:
                break
            tunnelled |= bool(through(cable.x).any())
            gaps = cable.contact_forces()["gap"]
            worst_gap = min(worst_gap, float(gaps.min()) if gaps.size else 0.0)
    return cable, tunnelled, worst_gap


GRID = [
    ("ground", "implicit_euler", 60, 80), ("ground", "bdf2", 1000, 10), ("ground", "implicit_midpoint", 240, 40),
    ("box", "implicit_euler", 1000, 20), ("box", "bdf2", 60, 40), ("box", "implicit_midpoint", 240, 80),
    ("peg", "implicit_euler", 240, 40), ("peg", "bdf2", 60, 80), ("peg", "implicit_midpoint", 1000, 20),
]


@pytest.mark.parametrize("target,integrator,hz,n", GRID)
def test_drop_no_false_alarm_no_tunnelling_comes_to_rest(target, integrator, hz, n):
    cable, tunnelled, worst_gap = drop(target, integrator, hz, n)
    assert cable.stable, (cable.reason, cable.time_to_instability)
    assert not tunnelled
    assert worst_gap > -1e-4  # penetration below 0.1 mm (microns at 240 Hz)
    assert np.max(np.abs(cable.v)) < 5e-3  # nothing left moving (slowest: n = 10 swinging on a peg)
    assert cable.contact_forces()["force"].sum(axis=0)[2] == pytest.approx(cable.model.spec.mass * 9.81, rel=0.05)


@pytest.mark.parametrize("hz", [60, 240, 1000])
@pytest.mark.parametrize("peg_radius", [0.008, 0.020])
def test_coarse_cable_does_not_pass_a_thin_peg(hz, peg_radius):
    # n = 10: 33 mm segments, far longer than the peg is thick; the segments' capsules catch it
    cable, tunnelled, _ = drop("peg", "implicit_euler", hz, 10, peg_radius=peg_radius, duration=1.0)
    assert cable.stable, cable.reason
    assert not tunnelled
    touching = cable.contact_forces()
    on_peg = touching["node"][touching["normal_force"] > 0]
    assert np.any(on_peg[:, 0] != on_peg[:, 1])  # a segment interior carries the cable on the peg
