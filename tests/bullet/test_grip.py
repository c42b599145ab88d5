"""Friction grip of a cable end: it holds below 2 mu_s F_n, slips there, and slides against 2 mu_d F_n.

A cable hangs from a friction grip (gripper axis vertical, fixed); its lower end is pulled down
by a force ramped slowly from 0. The grip carries the weight W plus the pull P (quasi-static:
the ramp adds 0.3 % of the capacity per step), so the closed form says: the end stays put while
W + P < 2 mu_s F_n, starts slipping at W + P = 2 mu_s F_n, and while it slides the grip's force
is 2 mu_d F_n.
"""
from __future__ import annotations

import numpy as np
import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError

G = 9.81
RAMP = 0.75  # [N/s] pull ramp
DT = 1.0 / 240.0


def _hanging(normal_force, mu_s, mu_d, reach=0.5, integrator="implicit_euler"):
    world = BulletWorld(dt=DT)
    spec = CableSpec.lv2017(n_masses=10, damping=0.02)
    cable = world.add_cable(spec, start=(0.0, 0.0, 1.0), direction=(0.0, 0.0, -1.0), record_every=10**9,
                            integrator=integrator)
    cable.set_external_pose(0, cable.x[0].copy(), np.zeros(3), np.zeros(3), np.zeros(3), (0.0, 0.0, -1.0))
    cable.grip_with_friction(0, normal_force, mu_s, mu_d, reach=reach)
    return world, cable, spec.mass * G


def _pull(world, cable, duration, settle=0.2):
    """Ramp the pull on the last node; rows (t [s], pull [N], grip force up [N], slip [m], sliding, sensor [N])."""
    rows = []
    for k in range(int(round(duration / DT))):
        t = k * DT
        pull = max(0.0, RAMP * (t - settle))
        cable.set_external_force(-1, (0.0, 0.0, -pull))
        world.step()
        g = cable.grip_state()
        rows.append((t, pull, g["force"][0, 2], g["slip"][0], g["sliding"][0], -cable.end_forces()[0, 2]))
    return np.array(rows, dtype=float)


@pytest.mark.parametrize("normal_force, mu_s, mu_d, integrator", [(1.0, 0.5, 0.3, "implicit_euler"),
                                                                  (2.0, 0.4, 0.35, "implicit_euler"),
                                                                  (1.0, 0.5, 0.3, "bdf2")])
def test_grip_holds_below_and_slips_at_two_mu_fn(normal_force, mu_s, mu_d, integrator):
    world, cable, weight = _hanging(normal_force, mu_s, mu_d, integrator=integrator)
    cap_s, cap_d = 2 * mu_s * normal_force, 2 * mu_d * normal_force
    duration = 0.2 + (cap_s - weight) / RAMP + 0.3
    with world:
        r = _pull(world, cable, duration)
        assert cable.stable
    t, pull, grip, slip, sliding, sensor = r.T
    moved = np.abs(slip - slip[0]) > 1e-4
    assert moved.any(), "the end never slipped"
    onset = int(np.argmax(moved))
    # holds: no slip and the grip carries the weight plus the pull (balance of forces) below the onset
    settled = (t > 0.1) & (np.arange(len(t)) < onset - 1)
    assert np.allclose(grip[settled], weight + pull[settled], rtol=0.01)
    assert np.all(sliding[:onset - 1] == 0)
    # slips at 2 mu_s F_n within 5 %
    assert abs(weight + pull[onset] - cap_s) <= 0.05 * cap_s
    # slides: the grip force saturates at 2 mu_d F_n within 5 %, the end keeps moving down
    after = slice(onset + 2, None)
    assert np.all(sliding[after] == 1)
    assert np.allclose(grip[after], cap_d, rtol=0.05)
    assert np.all(np.diff(slip[after]) > 0.0)
    # the holder feels the reaction (what a wrist sensor reads)
    assert np.allclose(sensor, grip)
    assert grip.max() <= 1.05 * cap_s


def test_end_leaves_the_gripper_after_its_reach():
    world, cable, weight = _hanging(0.5, 0.3, 0.2, reach=0.01)  # capacity 0.3 N ~ the weight: slips at once
    with world:
        r = _pull(world, cable, 0.5, settle=0.0)
        state = cable.grip_state()
        assert not state["active"][0]
        assert not cable.ext.active[0]
        assert np.allclose(cable.end_forces()[0], 0.0)
        assert cable.stable
    assert r[:, 3].max() > 0.01
    assert cable.x[0, 2] < 1.0 - 0.05  # falling free


@pytest.mark.parametrize("args, word", [((0.0, 0.5, 0.3), "normal force"), ((1.0, 0.3, 0.5), "grip_dynamic_friction"),
                                        ((1.0, -0.1, 0.0), "grip_static_friction"), ((1.0, 0.5, 0.3, 0.0), "reach")])
def test_bad_grip_parameters_are_refused(args, word):
    with BulletWorld(dt=DT) as world:
        cable = world.add_cable(CableSpec.lv2017(n_masses=6), record_every=10**9)
        with pytest.raises(ParameterError, match=word):
            cable.grip_with_friction(0, *args)


def test_grip_needs_an_implicit_integrator():
    with BulletWorld(dt=DT) as world:
        cable = world.add_cable(CableSpec.lv2017(n_masses=6), integrator="symplectic_euler", substeps=20,
                                record_every=10**9)
        with pytest.raises(ParameterError, match="implicit"):
            cable.grip_with_friction(0, 1.0, 0.5, 0.3)
