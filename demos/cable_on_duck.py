"""A cable laid across pybullet_data's duck mesh (duck.obj scaled 0.08, a static body made with PyBullet's own
createCollisionShape: its convex hull, or with --concave the triangle mesh), on the ground: every 0.5 s the range of
the supports over the cable's weight, its largest speed and kinetic energy (docs/concepts/contact.md, "A cable on a
finely faceted hull"). A cable at rest reads 1.0000 and a kinetic energy that decays to nothing: the hull does from
2-2.5 s on, on the hull and on the triangle mesh.

    python demos/cable_on_duck.py
    python demos/cable_on_duck.py --hz 60 240 1000 --n 12 33 --seconds 4 --concave
"""
from __future__ import annotations

import argparse
import os

import numpy as np
import pybullet as pb
import pybullet_data

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec


def duck(world: BulletWorld, concave: bool) -> tuple[int, np.ndarray, np.ndarray]:
    cid = world.client
    col = pb.createCollisionShape(pb.GEOM_MESH, fileName=os.path.join(pybullet_data.getDataPath(), "duck.obj"),
                                  meshScale=[0.08] * 3, flags=pb.GEOM_FORCE_CONCAVE_TRIMESH if concave else 0,
                                  physicsClientId=cid)
    body = pb.createMultiBody(0, col, -1, [0, 0, 0], pb.getQuaternionFromEuler((np.pi / 2, 0, 0.3)),
                              physicsClientId=cid)
    pb.performCollisionDetection(physicsClientId=cid)
    lo, hi = pb.getAABB(body, -1, physicsClientId=cid)
    return body, np.array(lo), np.array(hi)



def lay_across(world: BulletWorld, body: int, lo: np.ndarray, hi: np.ndarray, spec: CableSpec):
    """The cable laid straight along x, 2 mm above the duck's highest point on the line through its box's middle."""
    c = 0.5 * (lo + hi)
    xs = np.linspace(c[0] - 0.15, c[0] + 0.15, 61)
    rays = pb.rayTestBatch([[x, c[1], hi[2] + 0.1] for x in xs], [[x, c[1], lo[2] - 0.1] for x in xs],
                           physicsClientId=world.client)
    top = max(h[3][2] for h in rays if h[0] == body)
    return world.add_cable(spec, start=(c[0] - 0.15, c[1], top + spec.diameter / 2 + 2e-3), direction=(1, 0, 0))


def run(hz: float, n: int, seconds: float, concave: bool) -> None:
    spec = CableSpec.lv2017(n_masses=n, damping=0.02)
    with BulletWorld(dt=1.0 / hz, ground=True) as world:
        body, lo, hi = duck(world, concave)
        cable = lay_across(world, body, lo, hi, spec)
        weight = spec.mass * 9.81
        print(f"{'concave' if concave else 'hull'}, n {n}, {hz:.0f} Hz:")
        for k in range(round(seconds / 0.5)):
            sup, ke = [], []
            for _ in range(round(0.5 * hz)):
                world.step()
                sup.append(float(cable.contact_forces()["force"][:, 2].sum()) / weight)
                ke.append(0.5 * float((cable.model.arrays.mass[:, None] * cable.v ** 2).sum()))
            print(f"  t {0.5 * (k + 1):4.1f} s: supports {min(sup):.4f}-{max(sup):.4f} of the weight, largest speed "
                  f"{np.abs(cable.v).max():.2e} m/s, kinetic energy up to {max(ke):.2e} J, "
                  f"{'stable' if cable.stable else cable.reason}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hz", type=float, nargs="+", default=[240.0])
    parser.add_argument("--n", type=int, nargs="+", default=[33])
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--concave", action="store_true", help="the triangle mesh instead of its convex hull")
    args = parser.parse_args()
    for hz in args.hz:
        for n in args.n:
            run(hz, n, args.seconds, args.concave)


if __name__ == "__main__":
    main()
