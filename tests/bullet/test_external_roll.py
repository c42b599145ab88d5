"""A section turned about the cable through ``set_external_pose``: its torsion, and the angular velocity it needs.

The energy check counts a holder's work from the velocities given with its poses. An independent check
(2026-12-07) rolled a round and a tube cable's last clamp by up to 6 rad in a zero-gravity world: with the
holder's angular velocity passed, the clamps read G J theta / L within 1e-3; with ``omega`` left at zero the run
stopped as "energy growth" once the roll passed 1.55-1.61 rad, whatever the stiffness, and nothing said why. Now
the cable warns, naming ``omega``, once a held section has turned 0.1 rad with it zero.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

TUBE = CableSpec(length=0.3, diameter=0.006, inner_diameter=0.004, mass=0.02, youngs_modulus=3e8, poisson_ratio=0.2,
                 n_masses=12, section="tube", damping_rate=5.0)
DT, RAMP, STEPS = 1e-3, 500, 800  # [s], steps of the roll, steps in all


def roll(turn: float, pass_omega: bool, mode: str = "clamped"):
    """The last end (held in ``mode``, the first alike) rolled by ``turn`` [rad] about the cable (x) at a constant
    rate over RAMP steps, then held: (stable, the ends' moments about x [N m] (2,), the warnings)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with BulletWorld(dt=DT, gravity=(0.0, 0.0, 0.0)) as world:
            cable = world.add_cable(TUBE, start=(0.0, 0.0, 0.5), integrator="bdf2")
            x0 = cable.x.copy()
            for end, node in ((0, 0), (1, -1)):
                cable.set_external_pose(end, x0[node], np.zeros(3), np.zeros(3), np.zeros(3), (1.0, 0.0, 0.0))
                cable.hold_externally(end, mode)
            for k in range(STEPS):
                a = turn * min(1.0, k / RAMP)
                rate = turn / (RAMP * DT) if k < RAMP and pass_omega else 0.0
                cable.set_external_pose(1, x0[-1], np.zeros(3), np.zeros(3), np.array([rate, 0.0, 0.0]),
                                        (1.0, 0.0, 0.0), (0.0, math.cos(a), math.sin(a)))
                world.step()
                if not cable.stable:
                    break
            return cable.stable, cable.end_moments()[:, 0], [str(w.message) for w in caught]


@pytest.mark.parametrize("turn", [4.5, -3.0])
def test_a_clamp_rolled_with_its_angular_velocity_reads_the_torsion(turn):
    stable, moments, caught = roll(turn, True)
    expected = TUBE.torsional_rigidity * turn / TUBE.length
    assert stable
    assert moments[0] == pytest.approx(expected, rel=1e-3) and moments[1] == pytest.approx(-expected, rel=1e-3)
    assert not [m for m in caught if "omega" in m]


def test_a_fork_rolled_through_set_external_pose_reads_the_torsion():
    """Forks (``hold_externally(end, "fork")``: position and roll held, direction free) take the roll as clamps do:
    G J theta / L at both ends; pinned ends feel nothing (the test can fail)."""
    stable, moments, _ = roll(2.0, True, "fork")
    expected = TUBE.torsional_rigidity * 2.0 / TUBE.length
    assert stable
    assert moments[0] == pytest.approx(expected, rel=1e-3) and moments[1] == pytest.approx(-expected, rel=1e-3)
    stable, moments, _ = roll(2.0, True, "pinned")
    assert stable and np.abs(moments).max() == 0.0


def test_a_clamp_rolled_with_omega_left_at_zero_is_told_why():
    stable, _, caught = roll(3.0, False)
    told = [m for m in caught if "omega = 0" in m]
    assert len(told) == 1 and "end 1" in told[0] and "angular velocity" in told[0]
    assert not stable  # (the check still stops the run: the roll's work is not counted)


def test_a_still_holder_s_jitter_with_omega_zero_is_not_taken_for_a_roll():
    """The warning counts the net turn since the last pose given with omega: a section jittering by +-0.05 rad for
    1000 poses is not a roll; one turned by 0.002 rad a pose is, once past 0.1 rad (no step is needed: the check is
    in ``set_external_pose``)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with BulletWorld(dt=DT, gravity=(0.0, 0.0, 0.0)) as world:
            cable = world.add_cable(TUBE, start=(0.0, 0.0, 0.5), integrator="bdf2")
            x0 = cable.x.copy()
            zero = np.zeros(3)
            cable.set_external_pose(1, x0[-1], zero, zero, zero, (1.0, 0.0, 0.0))
            cable.hold_externally(1, "clamped")
            for k in range(1000):
                a = 0.05 * (-1) ** k
                cable.set_external_pose(1, x0[-1], zero, zero, zero, (1.0, 0.0, 0.0), (0.0, math.cos(a), math.sin(a)))
            jitter = [str(w.message) for w in caught if "omega = 0" in str(w.message)]
            for k in range(100):
                a = 0.05 + 0.002 * (k + 1)
                cable.set_external_pose(1, x0[-1], zero, zero, zero, (1.0, 0.0, 0.0), (0.0, math.cos(a), math.sin(a)))
    assert jitter == []
    assert len([w for w in caught if "omega = 0" in str(w.message)]) == 1
