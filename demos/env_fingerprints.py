"""50-step fingerprints of both environments, for env-side changes that must not change a bit.

For each of TensionTracking-v0 and Routing-v0 (seed 3, actions from ``default_rng(0)``): one sha256 over
every observation, reward, float in the info, the cable's end forces and positions, both wrist sensors'
latest values and the sensor check, after each of 50 steps. Hashes depend on the machine: compare runs of
two code trees on one machine.

``--ik bullet`` runs ``Robot.track`` on PyBullet's IK (the solver before the compiled one), so that the
rest of a change can be compared bit for bit with older code. ``--house BASELINE`` instead runs
``demos/fingerprints.py --check BASELINE`` with that solver choice.

    python demos/env_fingerprints.py [--ik compiled|bullet] [--house BASELINE] [--grasp-difference]
"""
from __future__ import annotations

import argparse
import hashlib
import sys
from pathlib import Path

import numpy as np

ENVS = ("bullet_dlo/TensionTracking-v0", "bullet_dlo/Routing-v0")


def use_solver(solver: str) -> None:
    """Every Robot built from now on tracks with ``solver``."""
    from bullet_dlo.robots.arm import Robot

    post = Robot.__post_init__

    def with_solver(self):
        post(self)
        self.ik_solver = solver

    Robot.__post_init__ = with_solver


def env_fingerprint(env_id: str, steps: int = 50) -> str:
    import gymnasium as gym

    import bullet_dlo.envs  # noqa: F401  (registers the environments)

    env = gym.make(env_id)
    try:
        obs, _ = env.reset(seed=3)
        rng = np.random.default_rng(0)
        u, h = env.unwrapped, hashlib.sha256()

        def add(o):
            for k in sorted(o):
                h.update(np.ascontiguousarray(o[k]).tobytes())

        add(obs)
        for _ in range(steps):
            obs, reward, term, trunc, info = env.step(rng.uniform(-1, 1, env.action_space.shape))
            add(obs)
            h.update(np.float64(reward).tobytes())
            h.update(np.asarray(u.physics.cable.end_forces(), float).tobytes())
            h.update(np.asarray(u.physics.cable.x, float).tobytes())
            h.update(np.array([s.values for s in u.sensors]).tobytes())
            h.update(np.array([u.observation.check.worst, u.observation.check._sumsq]).tobytes())
            for k in sorted(info):
                if isinstance(info[k], float):
                    h.update(np.float64(info[k]).tobytes())
            if term or trunc:
                obs, _ = env.reset()
                add(obs)
        return h.hexdigest()
    finally:
        env.close()


def grasp_difference(robot: str = "panda") -> tuple[float, float]:
    """How far the run ``grasp/<robot>`` of demos/fingerprints.py ends with the compiled IK from where it ends
    with PyBullet's: largest difference of the grasp frames' positions and of the cable's nodes [m]."""
    from bullet_dlo.core.boundary import Move
    from bullet_dlo.core.spec import CableSpec
    from bullet_dlo.robots.arm import Robot
    from bullet_dlo.robots.dual_arm import DualArmConfig, DualArmScene

    post, out = Robot.__post_init__, {}
    for solver in ("bullet", "compiled"):
        use_solver(solver)
        cable = CableSpec(length=0.3, diameter=0.004, mass=0.03, youngs_modulus=126e6, n_masses=12, damping=0.01)
        with DualArmScene(DualArmConfig(robot=robot, cable=cable, dt=1e-3, integrator="bdf2")) as scene:
            scene.grasp()
            scene.follow_motion([Move("last", (0.0, 0.0, 0.03), 0.05, 0.2, rotation=(0.0, 0.3, 0.0))])
            scene.run(0.3)
            out[solver] = (np.array([r.grasp_pose()[0] for r in scene.physics.robots]), scene.cable.x.copy())
        Robot.__post_init__ = post
    (gb, xb), (gc, xc) = out["bullet"], out["compiled"]
    return float(np.abs(gb - gc).max()), float(np.abs(xb - xc).max())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ik", choices=("compiled", "bullet"), default="compiled")
    parser.add_argument("--house", metavar="BASELINE", help="run demos/fingerprints.py --check BASELINE instead")
    parser.add_argument("--grasp-difference", action="store_true",
                        help="how far grasp/panda ends with the compiled IK from where PyBullet's IK leaves it")
    args = parser.parse_args(argv)
    if args.grasp_difference:
        grip, cable = grasp_difference()
        print(f"grasp/panda, compiled vs PyBullet IK: grasp frames {grip * 1e3:.3f} mm, cable nodes {cable * 1e3:.3f} mm")
        return 0
    use_solver(args.ik)
    if args.house:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        import fingerprints

        return fingerprints.main(["--check", args.house])
    for env_id in ENVS:
        print(f"{env_fingerprint(env_id)}  {env_id}  (IK: {args.ik})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
