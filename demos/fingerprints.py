"""Fingerprints of a fixed set of short runs: one sha256 per run, for refactors that must not change a bit.

Each run hashes the bytes of its final x [m], v [m/s], the recorded end forces [N] and moments [N m], the
energy [J] and (Bullet cables) the contact forces [N]. Hashes depend on the machine (CPU, compiler, library
builds): save a baseline on this machine from the unmodified code, then check every change against it:

    python demos/fingerprints.py --save /work/notes/house-model-fingerprints.json   # before
    python demos/fingerprints.py --check /work/notes/house-model-fingerprints.json  # after each change

``--only NAME`` runs one fingerprint (a substring of its name). Exit code 1 when a check differs.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import math
import sys
from typing import Callable

import numpy as np


def _digest(*arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(np.asarray(a, dtype=float))
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _cable_arrays(cable) -> list:
    rec = cable.record.arrays()
    out = [cable.x, cable.v, rec["end_forces"], rec["energy"], cable.end_forces(), cable.end_moments()]
    cf = cable.contact_forces()
    out += [cf[k] for k in sorted(cf)]
    out += [cable.grip_state()[k] for k in sorted(cable.grip_state())]
    return out


def core_run(integrator: str) -> Callable[[], str]:
    def run() -> str:
        from bullet_dlo.core.boundary import Move
        from bullet_dlo.core.engine import simulate
        from bullet_dlo.core.model import CableModel
        from bullet_dlo.core.spec import CableSpec
        spec = CableSpec.lv2017(n_masses=12, damping=0.02)
        model = CableModel.straight(spec, ends=("clamped", "pinned"),
                                    motion=[Move("last", (-0.05, 0.0, 0.02), 0.0, 0.1)])
        dt = 2e-5 if integrator == "symplectic_euler" else 1e-3
        r = simulate(model, integrator, dt, 0.15, record_every=10)
        return _digest(r.final_state.x, r.final_state.v, r.end_forces, r.energy, r.end_moments)
    return run


def bullet_free() -> str:
    from bullet_dlo.bullet.world import BulletWorld
    from bullet_dlo.core.spec import CableSpec
    with BulletWorld(dt=1 / 240) as world:
        c = world.add_cable(CableSpec.lv2017(n_masses=12, damping=0.02), start=(0, 0, 0.5),
                            ends=("clamped", "free"), integrator="bdf2", record_every=4)
        world.run(0.2)
        return _digest(*_cable_arrays(c))


def bullet_table_ends_moving() -> str:
    from bullet_dlo.bullet.world import BulletWorld
    from bullet_dlo.core.boundary import Move
    from bullet_dlo.core.spec import CableSpec
    spec = CableSpec.lv2017(n_masses=16, damping=0.02)
    r = spec.diameter / 2
    with BulletWorld(dt=1 / 240) as world:
        world.add_box((0.1, 0.1, 0.05), (0, 0, 0.05))
        motion = [Move("first", (0.02, 0.0, 0.0), 0.0, 0.15), Move("last", (-0.03, 0.01, 0.0), 0.0, 0.15,
                                                                      rotation=(0.0, 0.0, 0.3))]
        c = world.add_cable(spec, start=(-0.15, 0.0, 0.1 + r), direction=(1, 0, 0), ends=("pinned", "clamped"),
                            motion=motion, record_every=4)
        world.run(0.25)
        return _digest(*_cable_arrays(c))


def bullet_coil_self_contact() -> str:
    from bullet_dlo.bullet.world import BulletWorld
    from bullet_dlo.core.model import CableState
    from bullet_dlo.core.spec import CableSpec
    n = 40
    spec = CableSpec.lv2017(length=0.6, mass=0.06, n_masses=n, damping=0.02)
    r = spec.diameter / 2
    h = r + 0.01
    path = np.array([(-0.1, 0, r), (0.1, 0, r), (0.1, 0.1, h), (0, 0.1, h), (0, -0.1, h)])
    with BulletWorld(dt=1 / 240) as world:
        c = world.add_cable(spec, state=CableState.along(path, spec.rest_length, n), self_collision="all",
                            record_every=4)
        world.run(0.3)
        return _digest(*_cable_arrays(c))


def bullet_crossing() -> str:
    from bullet_dlo.bullet.world import BulletWorld
    from bullet_dlo.core.spec import CableSpec
    spec = CableSpec.lv2017(n_masses=16, damping=0.02)
    r, L = spec.diameter / 2, spec.length
    with BulletWorld(dt=1 / 240) as world:
        low = world.add_cable(spec, start=(-L / 2, 0, r), direction=(1, 0, 0), name="low", record_every=4)
        up = world.add_cable(spec, start=(0, -L / 2, 3 * r + 0.01), direction=(0, 1, 0), name="up", record_every=4)
        world.run(0.3)
        return _digest(*_cable_arrays(low), *_cable_arrays(up))


def bullet_grip_slips() -> str:
    from bullet_dlo.bullet.world import BulletWorld
    from bullet_dlo.core.spec import CableSpec
    dt = 1 / 240
    with BulletWorld(dt=dt) as world:
        spec = CableSpec.lv2017(n_masses=10, damping=0.02)
        c = world.add_cable(spec, start=(0.0, 0.0, 1.0), direction=(0.0, 0.0, -1.0), record_every=4)
        c.set_external_pose(0, c.x[0].copy(), np.zeros(3), np.zeros(3), np.zeros(3), (0.0, 0.0, -1.0))
        c.grip_with_friction(0, 0.3, 0.5, 0.3, reach=0.5)
        slips = []
        for k in range(150):
            c.set_external_force(-1, (0.0, 0.0, -4.0 * k * dt))  # a pull ramp past 2 mu_s F_n
            world.step()
            slips.append(c.grip_state()["slip"].copy())
        c.release(0)
        world.run(0.05)
        return _digest(*_cable_arrays(c), np.array(slips))


def bullet_rectangle_rolled() -> str:
    from bullet_dlo.bullet.world import BulletWorld
    from bullet_dlo.core.spec import CableSpec
    spec = CableSpec(length=0.3, mass=0.03, youngs_modulus=126e6, n_masses=12, damping=0.01, section="rectangle",
                     width=0.006, thickness=0.002, diameter=0.006)
    with BulletWorld(dt=1e-3, gravity=(0.0, 0.0, -9.81)) as world:
        c = world.add_cable(spec, start=(0.0, 0.0, 0.5), integrator="bdf2", record_every=10)
        x0 = c.x.copy()
        for end, node in ((0, 0), (1, -1)):
            c.set_external_pose(end, x0[node], np.zeros(3), np.zeros(3), np.zeros(3), (1.0, 0.0, 0.0))
            c.hold_externally(end, "clamped")
        for k in range(150):
            a = 0.5 * math.pi * min(1.0, k / 100)
            c.set_external_pose(1, x0[-1], np.zeros(3), np.zeros(3), np.zeros(3), (1.0, 0.0, 0.0),
                                (0.0, math.cos(a), math.sin(a)))
            world.step()
        c.release(1)
        c.hold_externally(1, "pinned")
        world.run(0.03)
        return _digest(*_cable_arrays(c), c.twist.theta, c.twist.omega)


def grasp(robot: str, grip: str = "clamp") -> Callable[[], str]:
    def run() -> str:
        from bullet_dlo.core.boundary import Move
        from bullet_dlo.core.spec import CableSpec
        from bullet_dlo.robots.dual_arm import DualArmConfig, DualArmScene
        cable = CableSpec(length=0.3, diameter=0.004, mass=0.03, youngs_modulus=126e6, n_masses=12, damping=0.01)
        with DualArmScene(DualArmConfig(robot=robot, cable=cable, dt=1e-3, integrator="bdf2", grip=grip)) as scene:
            scene.grasp()
            scene.follow_motion([Move("last", (0.0, 0.0, 0.03), 0.05, 0.2, rotation=(0.0, 0.3, 0.0))])
            scene.run(0.3)
            wrench = np.array([s.rows for s in scene.sensors], dtype=float)
            return _digest(*_cable_arrays(scene.cable), wrench)
    return run


def routing() -> str:
    import gymnasium as gym
    import bullet_dlo.envs  # noqa: F401  (registers the environments)
    env = gym.make("bullet_dlo/Routing-v0")
    try:
        obs, _ = env.reset(seed=3)
        out = [obs]
        rng = np.random.default_rng(0)
        for _ in range(5):
            obs, reward, term, trunc, _ = env.step(rng.uniform(-1, 1, env.action_space.shape))
            out += [obs, [reward]]
        flat = [np.concatenate([np.ravel(o[k]) for k in sorted(o)]) if isinstance(o, dict) else np.ravel(o)
                for o in out]
        return _digest(*flat)
    finally:
        env.close()


RUNS: dict[str, Callable[[], str]] = {
    "core/implicit_euler": core_run("implicit_euler"),
    "core/bdf2": core_run("bdf2"),
    "core/implicit_midpoint": core_run("implicit_midpoint"),
    "core/symplectic_euler": core_run("symplectic_euler"),
    "bullet/free": bullet_free,
    "bullet/box_ends_moving": bullet_table_ends_moving,
    "bullet/coil_self_contact": bullet_coil_self_contact,
    "bullet/crossing": bullet_crossing,
    "bullet/grip_slips": bullet_grip_slips,
    "bullet/rectangle_rolled": bullet_rectangle_rolled,
    "grasp/kuka": grasp("kuka"),
    "grasp/panda": grasp("panda"),
    "grasp/kuka_friction": grasp("kuka", "friction"),
    "envs/routing": routing,
}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    g = p.add_mutually_exclusive_group()
    g.add_argument("--save", metavar="FILE")
    g.add_argument("--check", metavar="FILE")
    p.add_argument("--only", default="")
    a = p.parse_args(argv)
    want = json.load(open(a.check)) if a.check else {}
    got, bad = {}, 0
    for name, run in RUNS.items():
        if a.only not in name:
            continue
        got[name] = run()
        flag = ""
        if a.check:
            flag = "  same" if want.get(name) == got[name] else "  DIFFERS"
            bad += flag == "  DIFFERS"
        print(f"{got[name]}  {name}{flag}", flush=True)
    if a.save:
        with open(a.save, "w") as f:
            json.dump(got, f, indent=1)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
