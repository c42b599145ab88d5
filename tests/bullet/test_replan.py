"""A re-planned step (the end conditions or the world changed after the coming step was planned) is a whole step.

BDF2 stores its history when it plans a step; planning the same step again used that history as if it were the
step before (x_prev = x), which made the re-planned step advance 2h/3 instead of h: a cable falling freely lost a
third of a step of its fall at each re-plan. Closed form: free fall, z drops by g t^2 / 2.
"""
from __future__ import annotations

import numpy as np
import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

G = 9.81


@pytest.mark.parametrize("replans", [0, 1, 3])
def test_a_falling_cable_falls_by_the_closed_form_through_re_plans(replans):
    spec = CableSpec.lv2017(n_masses=12, damping=0.0)
    dt, steps = 1e-3, 100
    with BulletWorld(dt=dt, ground=False) as world:
        cable = world.add_cable(spec, start=(0.0, 0.0, 1.0), integrator="bdf2", ends=("free", "free"))
        z0 = cable.x[:, 2].mean()
        for k in range(steps):
            if k in (50, 60, 70)[:replans]:
                cable.add_point_mass(3, 1e-3)  # re-plans the coming step (free fall does not depend on mass)
            world.step()
        assert cable.stable, cable.reason
        t = steps * dt
        drop = z0 - cable.x[:, 2].mean()
        # the first step (implicit Euler) and each re-planned one put BDF2 off by 0.75 g dt^2 (7e-6 m); a re-planned
        # step of 2 dt / 3 lost g t dt / 3 (1.6e-4 m at t = 0.05 s)
        assert drop == pytest.approx(0.5 * G * t * t, abs=(1 + replans) * G * dt * dt)
