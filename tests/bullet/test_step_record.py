"""The coupled step's recorder and collision filters after the per-step cost cuts (issue 24 items 4, 5).

- Recorded rows: the step's kernel writes the end loads and the energy of a recorded step; each row must
  equal the read-outs (:meth:`BulletCable.end_forces`, the core's ``mechanical_energy``) of the same state,
  bit for bit, for a free cable on a table and for one whose ends are held by moving external holders.
- The kernel writes each recorded row into the record's block of rows itself (no copies or appends in Python):
  every row, across full blocks and beside rows written from Python, equals the state it records, in order.
- A cable whose contacts the model owns keeps out of Bullet's contacts (its spheres neither touch each
  other nor the ground there) and still lies on the ground at one radius with supports equal to its weight.
"""
from __future__ import annotations

import numpy as np
import pybullet as pb
import pytest

from bullet_dlo.bullet import kernels
from bullet_dlo.bullet.recorder import CableRecord
from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.kernels.forces import mechanical_energy
from bullet_dlo.core.spec import CableSpec

G = 9.81


def check_rows_equal_readouts(world, cable, steps: int) -> None:
    for _ in range(steps):
        world.step()
        rec = cable.record
        assert np.array_equal(rec.end_forces[-1], cable.end_forces())
        assert rec.energy[-1] == mechanical_energy(cable.arrays, cable.x, cable.v, cable._cp.samples.dir[0])
        assert np.array_equal(rec.x[-1], cable.x) and rec.t[-1] == cable.t


def test_recorded_rows_equal_the_readouts_on_a_table():
    spec = CableSpec.lv2017(n_masses=10, damping=0.01)
    with BulletWorld(dt=1 / 240) as world:
        cable = world.add_cable(spec, start=(0.0, 0.0, 0.01))
        check_rows_equal_readouts(world, cable, 40)
        assert cable.contacts_last_step > 0


@pytest.mark.parametrize("record_every", [1, 3])
def test_recorded_rows_equal_the_readouts_with_moving_held_ends(record_every):
    spec = CableSpec.lv2017(n_masses=10, damping=0.01)
    with BulletWorld(dt=1e-3) as world:
        cable = world.add_cable(spec, start=(0.0, 0.0, 0.3), record_every=record_every)
        for end in (0, 1):
            cable.set_external_pose(end, cable.x[-end].copy(), np.zeros(3), np.zeros(3), np.zeros(3), [1, 0, 0])
            cable.hold_externally(end)

        def move() -> None:
            t = world.time
            pos = np.array([spec.length - 0.05 * np.sin(3 * t), 0.0, 0.3 + 0.02 * np.sin(5 * t)])
            vel = np.array([-0.15 * np.cos(3 * t), 0.0, 0.1 * np.cos(5 * t)])
            cable.set_external_pose(1, pos, vel, np.zeros(3), np.zeros(3), [1, 0, 0])

        world.before_step.append(move)
        for _ in range(30):
            world.step(record_every)
            rec = cable.record
            assert rec.t[-1] == cable.t
            assert np.array_equal(rec.end_forces[-1], cable.end_forces())
            assert rec.energy[-1] == mechanical_energy(cable.arrays, cable.x, cable.v, cable._cp.samples.dir[0])
        assert len(cable.record.t) == 31 and np.abs(cable.record.end_forces[-1]).max() > 0.1


def test_rows_written_by_the_kernel_keep_every_state_in_order(monkeypatch):
    """Blocks of 7 rows (n = 10): 40 recorded steps fill five blocks and part of a sixth; each row is the state
    (t, x, v) after its step and its end loads, the first row (written from Python) included; a record that
    replaces the cable's own keeps receiving the rows."""
    monkeypatch.setattr(kernels, "ROW_FLOATS", 7 * 6 * 10)
    spec = CableSpec.lv2017(n_masses=10, damping=0.01)
    with BulletWorld(dt=1 / 240) as world:
        cable = world.add_cable(spec, start=(0.0, 0.0, 0.01))
        assert cable.record.rows.t.shape[0] == 7
        seen = [(cable.t, cable.x.copy(), cable.v.copy(), cable.end_forces())]
        for _ in range(40):
            world.step()
            seen.append((cable.t, cable.x.copy(), cable.v.copy(), cable.end_forces()))
        rec = cable.record.arrays()
        assert len(cable.record) == 41 and rec["x"].shape == (41, 10, 3)
        assert np.array_equal(rec["t"], [s[0] for s in seen])
        assert np.array_equal(rec["x"], np.array([s[1] for s in seen]))
        assert np.array_equal(rec["v"], np.array([s[2] for s in seen]))
        assert np.array_equal(rec["end_forces"], np.array([s[3] for s in seen]))
        assert np.ptp(rec["x"][:, :, 2]) > 1e-3  # (the cable fell: the rows differ)
        cable.record = CableRecord()
        times = []
        for _ in range(3):
            world.step()
            times.append(cable.t)
        assert cable.record.t == times and times[0] > seen[-1][0]
        assert np.array_equal(cable.record.x[-1], cable.x)


def test_model_contact_cable_rests_on_the_ground_without_bullet_contacts():
    spec = CableSpec.lv2017(n_masses=30, damping=0.02)
    r = spec.diameter / 2
    with BulletWorld(dt=1 / 240) as world:
        cable = world.add_cable(spec, start=(0.0, 0.0, r + 0.02))  # dropped from 2 cm
        for _ in range(360):
            world.step()
            spheres = set(cable.body_ids)
            assert not [cp for cp in world.contacts() if cp[1] in spheres or cp[2] in spheres]
        assert cable.stable
        assert cable.x[:, 2] == pytest.approx(r, abs=1e-4)  # lying at one radius
        support = cable.contact_forces()["force"].sum(axis=0)
        assert support[2] == pytest.approx(spec.mass * G, rel=0.01)


def test_spawn_overlap_is_found_by_one_world_query():
    """The spawn check reads every contact once (a query per sphere cost 13 s at n = 1000): a cable laid into
    another one, or into a box, is still refused, naming the first overlapping sphere; one beside them is not."""
    from bullet_dlo.core.validate import ParameterError

    spec = CableSpec.lv2017(n_masses=20)
    with BulletWorld(dt=1 / 240) as world:
        world.add_box([0.05, 0.05, 0.05], [0.2, 0.0, 0.05], name="crate")
        world.add_cable(spec, start=(0.0, 0.1, 0.2), name="a", contact="bullet", integrator="symplectic_euler")
        with pytest.raises(ParameterError, match=r"'c' overlaps cable 'a' at spawn \(sphere 0 penetrates by 3.00 mm"):
            world.add_cable(spec, start=(0.001, 0.1, 0.2), name="c", contact="bullet", integrator="symplectic_euler")
        with pytest.raises(ParameterError, match=r"overlaps cable 'a' at spawn \(sphere 0 "):
            world.add_cable(spec, start=(0.0, 0.1, 0.2), direction=(0, 0, 1), name="d")
        with pytest.raises(ParameterError, match=r"overlaps crate at spawn \(sphere 10 "):
            world.add_cable(spec, start=(0.0, 0.0, 0.06), name="b")
        world.add_cable(spec, start=(0.0, 0.2, 0.2), name="e")  # beside them: accepted
        assert set(world.cables) == {"a", "e"}
