"""The cable in PyBullet: same trajectory as the core without contacts, sensible contacts,
stable when stiff and coarse, clear errors. All in DIRECT mode."""
from __future__ import annotations

import json

import numpy as np
import pybullet as pb
import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.cli.main import main
from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError


def study_model(spec):
    return CableModel.straight(spec, ends=("clamped", "clamped"), motion=[Move("last", (0.0, 0.0, 0.005), 0.2, 0.1)])


# (integrator, Bullet step, integrator substeps per Bullet step, damping k_d)
ENGINE_CASES = [
    ("implicit_euler", 1e-3, 1, 0.01),
    ("bdf2", 1e-3, 1, 0.01),
    ("implicit_midpoint", 1e-3, 1, 0.01),
    ("symplectic_euler", 1e-3, 5, 0.01),  # 2e-4 s < 2.69e-4 s critical
    ("rk4", 1e-3, 3, 0.01),  # 3.3e-4 s < 3.8e-4 s critical
    ("explicit_euler", 1e-3, 100, 2.0),  # needs gamma >= dt omega^2: heavy damping, 1e-5 s
]


@pytest.mark.parametrize("integrator,dt,substeps,damping", ENGINE_CASES)
def test_no_contact_trajectory_matches_core(integrator, dt, substeps, damping):
    spec = CableSpec.lv2017(n_masses=10, damping=damping)
    model = study_model(spec)
    core = simulate(model, integrator, dt / substeps, 1.0)
    with BulletWorld(dt=dt) as world:
        cable = world.add_cable(model, integrator=integrator, substeps=substeps)
        world.run(1.0)
        assert cable.stable and core.stable
        assert cable.t == pytest.approx(1.0)
        assert np.max(np.abs(cable.x - core.final_state.x)) <= 1e-9
        assert np.max(np.abs(cable.bullet_positions() - core.final_state.x)) <= 1e-9  # Bullet's own bodies too
        assert np.max(np.abs(cable.end_forces() - core.end_forces[-1])) <= 1e-6


def test_cable_dropped_on_the_ground_comes_to_rest():
    spec = CableSpec.lv2017(n_masses=20, damping=0.02)
    r = spec.diameter / 2
    with BulletWorld(dt=1 / 240) as world:
        cable = world.add_cable(spec, start=(0.0, 0.0, 0.08), direction=(1.0, 0.3, 0.0), ends=("free", "free"))
        world.run(3.0)
        assert cable.stable
        z = cable.bullet_positions()[:, 2]
        assert np.all(np.abs(z - r) <= 1e-3)  # every sphere rests on the plane
        assert np.all(z >= r - 1e-3)  # none sinks into it
        assert np.max(np.abs(cable.v)) < 1e-2  # at rest
        assert cable.contacts_last_step >= 10  # resting on the ground: contacts touch it


def _box_clearance(world, cable, box):
    cid = world.client
    world.sync_bullet_spheres()  # parked proxy spheres: Bullet has them where the model is only after a sync
    return min(pb.getClosestPoints(b, box, 1.0, physicsClientId=cid)[0][8] for b in cable.body_ids)


def test_cable_drapes_over_a_box_edge_and_stays():
    spec = CableSpec.lv2017(n_masses=20, damping=0.02)
    r = spec.diameter / 2
    with BulletWorld(dt=1 / 240) as world:
        box = world.add_box((0.1, 0.1, 0.1), (0.0, 0.0, 0.1), name="table")
        # 0.2 m on the box top (z = 0.2), 0.1 m sticking out over the edge at x = 0.1
        cable = world.add_cable(spec, start=(-0.1, 0.0, 0.2 + r + 5e-4), direction=(1.0, 0.0, 0.0), ends=("free", "free"),
                                record_every=24)
        world.run(1.0)
        settled = cable.record.energy[-1]
        worst_clearance = _box_clearance(world, cable, box)
        for _ in range(4):
            world.run(1.0)
            worst_clearance = min(worst_clearance, _box_clearance(world, cable, box))
        assert cable.stable
        x = cable.x
        # the free part droops over the edge: 11.2 mm by Euler-Bernoulli beam theory with the cable lifting off
        # the table behind the edge (bound-constrained energy minimum); 12.6 mm here (n = 20, large deflection)
        assert 0.2 - 0.016 < x[-1, 2] < 0.2 - 0.008
        assert np.all(x[:8, 2] > 0.2)  # the rest still lies on the box
        assert worst_clearance > -1e-3  # no penetration beyond 1 mm
        energies = np.array(cable.record.energy)
        assert np.max(energies[len(energies) // 5:]) <= settled + 1e-3 * spec.mass * 9.81 * spec.length  # no growth


@pytest.mark.parametrize("dt", [1 / 60, 1 / 240, 1e-3])
def test_stiff_coarse_cable_stable_at_robot_rates(dt):
    spec = CableSpec.lv2017(n_masses=10, youngs_modulus=1002.6e6, damping=0.0)
    with BulletWorld(dt=dt) as world:
        cable = world.add_cable(study_model(spec), integrator="implicit_euler", record_every=50)
        world.run(10.0)
        assert cable.stable, (cable.reason, cable.time_to_instability)
        assert cable.x[-1, 2] == pytest.approx(0.505, abs=1e-12)  # the end made its 5 mm move
        f = cable.end_forces()
        assert f[0, 2] + f[1, 2] == pytest.approx(-spec.mass * 9.81, rel=0.05)


def test_bad_input_gives_clear_errors():
    spec = CableSpec.lv2017(n_masses=10)
    with pytest.raises(ParameterError, match="dt must be a finite number > 0"):
        BulletWorld(dt=0.0)
    with pytest.raises(ParameterError, match="dt"):
        BulletWorld(dt=-1e-3)
    with pytest.raises(ParameterError, match="solver_residual must be a finite number > 0"):
        BulletWorld(dt=1e-3, solver_residual=-1e-9)
    with pytest.raises(ParameterError, match="solver_residual"):
        BulletWorld(dt=1e-3, solver_residual=float("nan"))
    with BulletWorld(dt=1e-3) as world:
        with pytest.raises(ParameterError, match="overlaps the ground at spawn"):
            world.add_cable(spec, start=(0.0, 0.0, 0.001))
        world.add_box((0.05, 0.05, 0.05), (0.1, 0.0, 0.3), name="crate")
        with pytest.raises(ParameterError, match="overlaps crate at spawn"):
            world.add_cable(spec, start=(0.0, 0.0, 0.3))
        world.add_cable(spec, start=(0.0, 0.0, 0.6), name="a")
        with pytest.raises(ParameterError, match="a cable named 'a' already exists"):
            world.add_cable(spec, start=(0.0, 0.5, 0.6), name="a")
        with pytest.raises(ParameterError, match="integrator must be one of"):
            world.add_cable(spec, start=(0.0, 1.0, 0.6), name="b", integrator="verlet")
        with pytest.raises(ParameterError, match="not found"):
            world.add_urdf("no_such_robot.urdf")
        with pytest.raises(ParameterError, match="half_extents must be > 0"):
            world.add_box((0.0, 0.1, 0.1), (0.0, 0.0, 1.0))
        assert len(world.cables) == 1  # failed spawns leave nothing behind
        assert pb.getNumBodies(physicsClientId=world.client) == 1 + 1 + 10  # ground, crate, cable a


def test_cli_bullet_engine_writes_the_same_keys(tmp_path):
    scene = tmp_path / "s.yaml"
    scene.write_text("""
cable: {preset: lv2017, n_masses: 10, damping: 0.01}
layout: {start: [0, 0, 0.5], direction: [1, 0, 0]}
ends: {first: clamped, last: clamped}
motion: [{end: last, displacement: [0, 0, 0.005], start: 0.1, duration: 0.1}]
dt: 0.001
duration: 0.5
""")
    outs = {}
    for engine in ("core", "bullet"):
        out = tmp_path / f"{engine}.json"
        assert main(["simulate", str(scene), "--engine", engine, "--json", str(out)]) == 0
        outs[engine] = json.loads(out.read_text())
    assert set(outs["core"]) == set(outs["bullet"]) and outs["bullet"]["engine"] == "bullet"
    diff = np.abs(np.array(outs["core"]["final_positions"]) - np.array(outs["bullet"]["final_positions"]))
    assert diff.max() < 1e-9


def test_scene_obstacles_are_validated(tmp_path, capsys):
    scene = tmp_path / "s.yaml"
    scene.write_text("""
cable: {preset: lv2017}
bullet: {obstacles: [{type: pyramid, position: [0, 0, 0]}]}
""")
    assert main(["simulate", str(scene), "--engine", "bullet"]) == 2
    assert "bullet.obstacles[0].type must be one of box, cylinder, urdf" in capsys.readouterr().err


def test_a_gripper_clamp_has_the_clamp_damper_of_a_scene_clamp():
    """A cable clamped by external holders (grippers) at fixed poses moves exactly as one whose ends are
    clamped from the start: the clamp's Kelvin-Voigt damper comes with the grip (it used to be left out,
    so a gripped cable's bending modes decayed too slowly and its clamp moments missed the damping)."""
    spec = CableSpec.lv2017(n_masses=8, damping=0.0, internal_damping=0.02)
    runs = []
    for external in (False, True):
        with BulletWorld(dt=1 / 240) as world:
            cable = world.add_cable(spec, start=(0.0, 0.0, 0.5), ends=("free", "free") if external else
                                    ("clamped", "clamped"))
            if external:
                x0 = cable.x.copy()
                for end, node in ((0, 0), (1, -1)):
                    cable.set_external_pose(end, x0[node], np.zeros(3), np.zeros(3), np.zeros(3), (1.0, 0.0, 0.0))
                    cable.hold_externally(end, "clamped")
            moments = []
            for _ in range(120):  # 0.5 s of the cable sagging and ringing between the clamps
                world.step()
                moments.append(cable.end_moments()[0])
            runs.append((cable.x.copy(), np.array(moments)))
    (x_scene, m_scene), (x_grip, m_grip) = runs
    assert np.abs(m_scene).max() > 1e-4  # the clamps carry a moment
    assert np.allclose(x_grip, x_scene, atol=1e-9)
    assert np.allclose(m_grip, m_scene, atol=1e-6 * np.abs(m_scene).max())
