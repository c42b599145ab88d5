"""MJCF capsules given by ``fromto`` (issue 23): PyBullet's getCollisionShapeData kills the process on them
(SIGSEGV: it reads a btMultiSphereShape as a btCapsuleShapeZ, bullet_dlo/bullet/shape_data.py), and the
contact model asked it for every link of every body when a cable was added. Each scene runs in a
subprocess, so that a crash is this test's failure, not a dead pytest worker.

Fails before (main at ae76f92): the subprocess dies with SIGSEGV (return code -11) as soon as the cable is
added. Now the capsule is a PROBE row (Bullet's narrow phase measures it) and the cable rests on it as on
the same capsule loaded with ``URDF_USE_IMPLICIT_CYLINDER`` (an exact CAPSULE row on the project's geometry):
the capsule carries the cable's weight within 1 %, the centre line stays outside the capsule (by the cable
radius), and the two rest shapes agree to 0.1 mm.
"""
from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.bullet

CAPSULE_RADIUS = 0.05  # [m] pybullet_data's mjcf/capsule_fromto*.xml: size 0.05, axis from -0.1 to 0.1, at z = 1
HALF_LENGTH = 0.1  # [m]

DRAPE = r"""
import json, sys
import numpy as np, pybullet as pb, pybullet_data
from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec
name, flag, hz, n = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
with BulletWorld(dt=1 / hz) as world:
    cid = world.client
    bodies = pb.loadMJCF(pybullet_data.getDataPath() + "/mjcf/" + name,
                         flags=pb.URDF_USE_IMPLICIT_CYLINDER if flag else 0, physicsClientId=cid)
    cap = bodies[-1]
    pb.changeDynamics(cap, -1, mass=0, physicsClientId=cid)  # held in place (the file's free joint is ignored)
    spec = CableSpec.lv2017(n_masses=n, damping=0.02)
    across = (0, 1, 0) if "fromtoX" in name else (1, 0, 0)  # the cable across the capsule's axis, on top
    start = [-0.15 * a for a in across]
    cable = world.add_cable(spec, start=(start[0], start[1], 1.05 + spec.diameter / 2), direction=across)
    world.run(2.0)
    print("\nRESULT " + json.dumps({"stable": cable.stable, "x": cable.x.tolist(), "weight": spec.mass * 9.81,
          "force": cable.body_forces().get(cap, np.zeros(3)).tolist(), "radius": spec.diameter / 2,
          "kind": int(cable._contact_set.shapes.kind[list(cable._contact_set.body_ids).index(cap)])}))
"""


def run_script(code: str, *args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True,
                          timeout=600, cwd=ROOT)


def result(proc: subprocess.CompletedProcess) -> dict:
    assert proc.returncode == 0, (f"the process died ({-proc.returncode}: {signal.Signals(-proc.returncode).name})"
                                  if proc.returncode < 0 else proc.stderr[-2000:])
    return json.loads(proc.stdout.split("RESULT ", 1)[1])


def clearance(x: np.ndarray, axis: int) -> float:
    """The centre line's (nodes and 50 points on every segment) smallest distance [m] to the capsule's axis
    (the segment +-HALF_LENGTH along ``axis`` through (0, 0, 1))."""
    t = np.linspace(0.0, 1.0, 51)[:, None, None]
    p = (x[:-1][None] * (1 - t) + x[1:][None] * t).reshape(-1, 3)
    q = np.zeros_like(p)
    q[:, 2] = 1.0
    q[:, axis] = np.clip(p[:, axis], -HALF_LENGTH, HALF_LENGTH)
    return float(np.linalg.norm(p - q, axis=1).min())


@pytest.mark.parametrize("name,hz,n", [("capsule_fromtoY.xml", 240, 20), ("capsule_fromtoY.xml", 60, 10),
                                       ("capsule_fromtoY.xml", 1000, 40), ("capsule_fromtoX.xml", 240, 20)])
def test_a_cable_rests_on_an_mjcf_fromto_capsule(name, hz, n):
    """The cable laid across the capsule (its ends hang either side): no crash, the capsule carries the
    weight, the centre line stays a cable radius outside it, and the rest shape is the one on the exact
    capsule (the same file loaded with URDF_USE_IMPLICIT_CYLINDER)."""
    probed = result(run_script(DRAPE, name, 0, hz, n))
    exact = result(run_script(DRAPE, name, 1, hz, n))
    assert probed["kind"] == 4 and exact["kind"] == 3  # PROBE (Bullet's narrow phase) vs CAPSULE (exact geometry)
    for r in (probed, exact):
        assert r["stable"]
        assert -r["force"][2] == pytest.approx(r["weight"], rel=0.01)  # the capsule carries the cable
    axis = 0 if "fromtoX" in name else 1
    x = np.array(probed["x"])
    assert clearance(x, axis) > CAPSULE_RADIUS + 0.9 * probed["radius"]  # outside, resting on the surface
    assert clearance(x, axis) < CAPSULE_RADIUS + 1.1 * probed["radius"]  # and on it (not fallen off)
    assert np.abs(x - np.array(exact["x"])).max() < 1e-4  # [m] the same rest shape as on the exact capsule


READ = r"""
import json, os, pybullet as pb, pybullet_data
from bullet_dlo.bullet import shape_data
from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec
d = pybullet_data.getDataPath()
out = {}
with BulletWorld(dt=1 / 240) as world:
    cid = world.client
    def links(b):
        return range(-1, pb.getNumJoints(b, physicsClientId=cid))
    safe = {"box": world.add_box((0.1, 0.2, 0.05), (1, 0, 0.05)),
            "cylinder": world.add_cylinder(0.02, 0.1, (1, 1, 0.3)),
            "capsule": pb.createMultiBody(0.1, pb.createCollisionShape(pb.GEOM_CAPSULE, radius=0.02, height=0.1,
                                                                       physicsClientId=cid),
                                          -1, [2, 0, 0.5], pb.getQuaternionFromEuler([0.3, 0.5, 0.2]),
                                          physicsClientId=cid),
            "mjcf_capsule": pb.loadMJCF(d + "/mjcf/capsule.xml", physicsClientId=cid)[1],
            "mjcf_fromto_flag": pb.loadMJCF(d + "/mjcf/capsule_fromtoY.xml", flags=pb.URDF_USE_IMPLICIT_CYLINDER,
                                            physicsClientId=cid)[1],
            "mjcf_cylinder_fromto": pb.loadMJCF(d + "/mjcf/cylinder_fromtoY.xml", physicsClientId=cid)[1],
            "panda": pb.loadURDF(d + "/franka_panda/panda.urdf", [3, 0, 0], useFixedBase=True, physicsClientId=cid)}
    # every link PyBullet can describe: the same answer, and read in this process where no capsule can hide
    out["same"] = {k: all(shape_data.collision_shapes(cid, b, l) == pb.getCollisionShapeData(b, l, physicsClientId=cid)
                          for l in links(b)) for k, b in safe.items()}
    out["direct"] = {k: all(shape_data._readable(cid, b, l) for l in links(b))
                     for k, b in safe.items() if k in ("box", "cylinder", "capsule", "mjcf_capsule", "panda")}
    crashing = {"fromtoX": pb.loadMJCF(d + "/mjcf/capsule_fromtoX.xml", physicsClientId=cid)[1],
                "fromtoY": pb.loadMJCF(d + "/mjcf/capsule_fromtoY.xml", physicsClientId=cid)[1],
                "fromtoZ": pb.loadMJCF(d + "/mjcf/capsule_fromtoZ.xml", physicsClientId=cid)[1]}
    humanoid = pb.loadMJCF(d + "/mjcf/humanoid_symmetric.xml", physicsClientId=cid)[0]
    crashing.update({f"humanoid{l}": humanoid for l in links(humanoid)})
    # never asked in this process; the forked copy that asks dies of SIGSEGV, so nothing is described
    out["never_direct"] = {k: not shape_data._readable(cid, b, -1) for k, b in crashing.items() if "humanoid" not in k}
    out["undescribed"] = {k: shape_data.collision_shapes(cid, b, -1) == () for k, b in crashing.items()
                          if "humanoid" not in k}
    out["fork_died"] = {k: shape_data._read_in_fork(cid, b, -1) is None for k, b in crashing.items()
                        if "humanoid" not in k}
    # the humanoid's limbs (fromto capsules on child links) with a cable in the world: it steps
    cable = world.add_cable(CableSpec.lv2017(n_masses=10), start=(-0.15, 0, 2.5), direction=(1, 0, 0))
    world.run(0.1)
    out["stepped"] = cable.steps
print("\nRESULT " + json.dumps(out))
"""


def test_collision_shapes_reads_what_pybullet_can_and_never_asks_for_a_multi_sphere():
    """collision_shapes answers as getCollisionShapeData for boxes, cylinders, capsules (direct, URDF, MJCF,
    MJCF fromto with the flag), an MJCF fromto cylinder and the Panda; the project's own bodies and the
    Panda are read directly (no fork); the fromto capsules without the flag are never read in the process
    (the forked copy that reads one dies), are described as nothing (the contact model probes them), and a
    world holding the MJCF humanoid steps with a cable in it."""
    out = result(run_script(READ))
    assert all(out["same"].values()), out["same"]
    assert all(out["direct"].values()), out["direct"]
    assert all(out["never_direct"].values()) and len(out["never_direct"]) == 3, out["never_direct"]
    assert all(out["undescribed"].values()), out["undescribed"]
    assert all(out["fork_died"].values()), out["fork_died"]  # the crash is real: the copy that asks dies
    assert out["stepped"] == 24


def test_the_forked_reader_runs_no_finalizer_of_the_parents_garbage(monkeypatch):
    """The copy that reads a link's shapes collects no garbage: a finalizer that joins a thread the copy does
    not have (PyAV's scaler after a video test, seen as a CI hang) would block it until FORK_TIMEOUT at every
    link. The copy answers with its collector's state; the parent's collector is on again afterwards.

    Fails before (32f8385): the copy's collector was on."""
    import gc

    import pybullet as pb

    from bullet_dlo.bullet import shape_data

    monkeypatch.setattr(pb, "getCollisionShapeData", lambda body, link, physicsClientId: gc.isenabled())
    assert gc.isenabled()
    assert shape_data._read_in_fork(0, 0, -1) is False  # the copy's collector was off
    assert gc.isenabled()
