"""How fast the dual-arm step and the environments run, against Bullet's own step.

1. The dual-arm step (arms, cable, wrist sensors, grasp coupling: ``world.step`` of a
   :class:`~bullet_dlo.robots.dual_arm.DualArmPhysics` with both ends clamped) against a bare
   ``stepSimulation`` of the same world, in interleaved blocks (Bullet's state saved before each
   bare block and restored after it, so both always step the same world), medians, at n = 10
   and 40 masses for both robots; then where the rest of the time goes (per-step hooks timed).
2. Each environment's step against its physical floor (Bullet's bare step of the same world times the
   physics steps per control step), interleaved in CPU time of the thread, and where the env step goes;
   ``bullet_dlo/TensionTracking-v0`` steps per second on one core (random actions).
3. An AsyncVectorEnv over 2 worker processes against one environment in this process.

Prints ratios and rates; writes nothing. ``--quick`` for a short run (smoke test).

    python demos/env_speed.py [--quick] [--robots panda kuka] [--masses 10 40] [--python-too] [--envs-only] [--env-steps N]
    python demos/env_speed.py --resets N
"""
from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np
import pybullet as pb

from bullet_dlo.core.spec import CableSpec
from bullet_dlo.robots.dual_arm import DualArmObservation, DualArmPhysics, DualArmSpec

BLOCK = 24  # physics steps per timed block (0.1 s at 240 Hz: the bare cable spheres fall 5 cm, no contact)
CLOCK = time.thread_time  # CPU time of this thread: other jobs on a shared machine inflate wall time, not this


def build(robot: str, n: int) -> DualArmPhysics:
    """The dual-arm scene, sensors on, both ends clamped, settled for 0.25 s."""
    physics = DualArmPhysics(DualArmSpec(robot=robot, cable=CableSpec.lv2017(n_masses=n, damping=0.02)))
    DualArmObservation(physics, record=False)
    physics.clamp(0)
    physics.clamp(1)
    physics.world.step(60)
    return physics


def step_vs_bare(physics: DualArmPhysics, blocks: int) -> tuple[float, float]:
    """Median CPU time [s] per simulated second of the dual-arm step and of the bare Bullet step."""
    world, cid = physics.world, physics.world.client
    full, bare = [], []
    for _ in range(blocks):
        tic = CLOCK()
        world.step(BLOCK)
        full.append(CLOCK() - tic)
        state = pb.saveState(physicsClientId=cid)
        tic = CLOCK()
        world.step_bare(BLOCK)
        bare.append(CLOCK() - tic)
        pb.restoreState(stateId=state, physicsClientId=cid)
        pb.removeState(state, physicsClientId=cid)
    per_second = 1.0 / (BLOCK * world.dt)
    return statistics.median(full) * per_second, statistics.median(bare) * per_second


def breakdown(physics: DualArmPhysics, steps: int) -> dict[str, float]:
    """CPU time [us] per step of each part of the dual-arm step (hooks wrapped with timers)."""
    world, cable = physics.world, physics.cable
    spent: dict[str, float] = {}

    def timed(name, fn):
        def run(*args):
            tic = CLOCK()
            out = fn(*args)
            spent[name] = spent.get(name, 0.0) + CLOCK() - tic
            return out
        return run

    # the phases of the dual-arm step (BulletWorld.step, DualArmPhysics.load/read), each behind a timer
    parts = [(physics, "_apply_cable_wrench", "grasp coupling (robots/dual_arm/physics.py)"),
             (physics, "_follow_grippers", "grasp coupling (robots/dual_arm/physics.py)"),
             (cable, "apply_forces", "cable step (bullet/cable.py)"),
             (cable, "sync_after_step", "cable step (bullet/cable.py)")]
    if physics.observation is not None:
        parts.append((physics.observation, "read_sensors", "wrist sensors (robots/sensors.py)"))
    for obj, name, label in parts:
        setattr(obj, name, timed(label, getattr(obj, name)))
    step_simulation = pb.stepSimulation
    pb.stepSimulation = timed("Bullet stepSimulation", step_simulation)
    try:
        tic = CLOCK()
        world.step(steps)
        total = CLOCK() - tic
    finally:
        pb.stepSimulation = step_simulation
        for obj, name, _ in parts:
            delattr(obj, name)
    out = {k: v / steps * 1e6 for k, v in spent.items()}
    out["rest (world loop, contact query, timers)"] = total / steps * 1e6 - sum(out.values())
    return out


def reset_time(resets: int) -> float:
    """Median wall time [s] of a TensionTracking reset (a new scene: world, arms, settling, cable), after a first one."""
    from bullet_dlo.envs.tension import TensionTrackingEnv

    env = TensionTrackingEnv()
    env.reset(seed=0)
    times = []
    for seed in range(1, resets + 1):
        tic = time.perf_counter()
        env.reset(seed=seed)
        times.append(time.perf_counter() - tic)
    env.close()
    return statistics.median(times)


def resets_vs_episodes(resets: int, steps: int = 50) -> None:
    """Each environment's reset (a new scene: world, arms, settling, cable) in CPU time of this thread: median and
    range of ``resets`` resets after a first one, beside its episode's steps (the median of ``steps`` random env
    steps times the episode's length): the reset's share of an episode."""
    import gymnasium as gym

    import bullet_dlo.envs  # noqa: F401 - registers the environments

    print(f"load average {os.getloadavg()[0]:.2f}; resets in CPU time of this thread, median (range) of {resets}")
    for env_id in ENVS:
        env = gym.make(env_id)
        env.reset(seed=0)
        times = []
        for seed in range(1, resets + 1):
            tic = CLOCK()
            env.reset(seed=seed)
            times.append(CLOCK() - tic)
        rng = np.random.default_rng(0)
        per_step = []
        for _ in range(steps):
            tic = CLOCK()
            _, _, term, trunc, _ = env.step(rng.uniform(-0.2, 0.2, env.action_space.shape).astype(np.float32))
            per_step.append(CLOCK() - tic)
            if term or trunc:
                env.reset(seed=seed + 1)
        length = env.spec.max_episode_steps
        env.close()
        reset, step = statistics.median(times), statistics.median(per_step)
        print(f"  {env_id}: reset {reset * 1e3:.1f} ms ({min(times) * 1e3:.1f}-{max(times) * 1e3:.1f}); an episode of "
              f"{length} steps at {step * 1e3:.2f} ms: the reset is {reset / (reset + length * step):.0%} of it")


def env_rate(steps: int) -> tuple[float, float]:
    """Control steps per second of one TensionTracking env on this core, and simulated seconds per wall second."""
    from bullet_dlo.envs.tension import TensionTrackingEnv

    env = TensionTrackingEnv()
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    tic = time.perf_counter()
    for _ in range(steps):
        env.step(rng.uniform(-0.2, 0.2, 6).astype(np.float32))
    wall = time.perf_counter() - tic
    env.close()
    return steps / wall, steps * env.control_dt / wall


ENVS = ("bullet_dlo/TensionTracking-v0", "bullet_dlo/Routing-v0")


def env_vs_floor(env_id: str, steps: int) -> dict[str, float]:
    """One env step against its physical floor, interleaved, in CPU time of this thread [s].

    The floor is Bullet's bare ``stepSimulation`` of the same world times the physics steps per control
    step (Bullet's state saved before each bare block and restored after it). Also the split of the env
    step (per-part CPU time [s], hooks wrapped with timers): Bullet, cable, sensors, IK, observation.
    Returns medians, the 10/90 % range of the ratio and env steps per CPU-second.
    """
    import gymnasium as gym

    import bullet_dlo  # noqa: F401  (registers the ids)

    env = gym.make(env_id)
    env.reset(seed=0)
    env.action_space.seed(0)
    u = env.unwrapped
    world, cid = u.physics.world, u.physics.world.client
    full, bare = [], []
    for _ in range(steps):
        action = env.action_space.sample()
        tic = CLOCK()
        _, _, term, trunc, _ = env.step(action)
        full.append(CLOCK() - tic)
        state = pb.saveState(physicsClientId=cid)
        tic = CLOCK()
        world.step_bare(u.substeps)
        bare.append(CLOCK() - tic)
        pb.restoreState(stateId=state, physicsClientId=cid)
        pb.removeState(state, physicsClientId=cid)
        if term or trunc:
            env.reset()
    ratios = np.array(full) / np.array(bare)
    split = env_split(u, max(10, steps // 2))
    env.close()
    return {"env": statistics.median(full), "floor": statistics.median(bare), "ratio": float(np.median(ratios)),
            "lo": float(np.percentile(ratios, 10)), "hi": float(np.percentile(ratios, 90)), **split}


def env_split(u, steps: int, warm: int = 5) -> dict[str, float]:
    """CPU time [s] per env step of its parts: medians over ``steps`` env steps (after ``warm`` untimed ones, so
    that a kernel compiled for a new episode is not counted), hooks wrapped with timers; the rest (the env's own
    Python, reward, world loop) is each step's total minus its parts. Wrapping adds a little to every part."""
    physics = u.physics
    spent: dict[str, float] = {}

    def timed(name, fn):
        def run(*args, **kwargs):
            tic = CLOCK()
            out = fn(*args, **kwargs)
            spent[name] = spent.get(name, 0.0) + CLOCK() - tic
            return out
        return run

    for _ in range(warm):
        if any(u.step(u.action_space.sample())[2:4]):
            u.reset()
    parts = [(physics.cable, "apply_forces", "cable step"), (physics.cable, "sync_after_step", "cable step"),
             (physics, "_apply_cable_wrench", "grasp coupling"), (physics, "_follow_grippers", "grasp coupling"),
             (u, "_observation", "observation")]
    if physics.observation is not None:
        parts.append((physics.observation, "read_sensors", "wrist sensors"))
    parts += [(robot, "track", "IK (Robot.track)") for robot in physics.robots]
    for obj, name, label in parts:
        setattr(obj, name, timed(label, getattr(obj, name)))
    # inside the cable step (shown apart, not subtracted again): the contact model's detection, the solver's kernel
    from bullet_dlo.bullet.contact import ContactSet

    inner = [(ContactSet, "update", "  cable step: contact detection (ContactSet.update)"),
             (physics.cable.solver, "step", "  cable step: solver kernel (CableSolver.step)")]
    saved_inner = [getattr(obj, name) for obj, name, _ in inner]
    for obj, name, label in inner:
        setattr(obj, name, timed(label, getattr(obj, name)))
    step_simulation = pb.stepSimulation
    pb.stepSimulation = timed("Bullet stepSimulation", step_simulation)
    rows: list[dict[str, float]] = []
    try:
        for _ in range(steps):
            action = u.action_space.sample()
            spent.clear()
            tic = CLOCK()
            _, _, term, trunc, _ = u.step(action)
            total = CLOCK() - tic
            row = {f"part: {k}": v for k, v in spent.items()}
            row["part: rest (env Python, reward, world loop)"] = total - sum(v for k, v in spent.items()
                                                                               if not k.startswith(" "))
            row["total"] = total
            rows.append(row)
            if term or trunc:
                break  # a new episode's world: the hooks are on the old one's objects
    finally:
        pb.stepSimulation = step_simulation
        for obj, name, _ in parts:
            delattr(obj, name)
        for (obj, name, _), fn in zip(inner, saved_inner):
            if obj is ContactSet:
                setattr(obj, name, fn)
            else:
                delattr(obj, name)
    keys = {k for r in rows for k in r}
    return {k: statistics.median(r.get(k, 0.0) for r in rows) for k in keys}


def envs_vs_floor(env_steps: int) -> None:
    """Part 2 printed: each environment's step against its physical floor, and the split of the env step."""
    print(f"env step vs its physical floor (Bullet's bare step x physics steps per control step), interleaved, "
          f"CPU time of this thread, {env_steps} steps, load average {os.getloadavg()[0]:.2f}")
    for env_id in ENVS:
        r = env_vs_floor(env_id, env_steps)
        print(f"{env_id}: env step {r['env'] * 1e6:.0f} us, floor {r['floor'] * 1e6:.0f} us, ratio {r['ratio']:.2f} "
              f"(10-90 %: {r['lo']:.2f}-{r['hi']:.2f}), {1 / r['env']:.0f} env steps per CPU-second; split:")
        arm = sum(r.get(f"part: {k}", 0.0) for k in ("wrist sensors", "grasp coupling", "observation",
                                                      "IK (Robot.track)"))
        for k in sorted((k for k in r if k.startswith("part: ")), key=lambda k: (k.startswith("part:  "), -r[k])):
            print(f"  {r[k] * 1e6:8.1f} us  {100 * r[k] / r['total']:5.1f} %  {k[6:]}")
        print(f"  {arm * 1e6:8.1f} us  {100 * arm / r['total']:5.1f} %  arm side (sensors, coupling, observation, IK)")
        print(f"  {r['total'] * 1e6:8.1f} us  (median of the timed steps' totals)")
    print(f"load average {os.getloadavg()[0]:.2f}")


def ik_cost(robot: str = "panda", solves: int = 300) -> dict[str, float]:
    """CPU time [us] of one ``Robot.track`` solve (a target 1 cm away) per IK solver, interleaved in blocks of 10,
    and the position error [m] each leaves, measured by PyBullet's forward kinematics on the twin."""
    from bullet_dlo.config.robot import load_robot_spec
    from bullet_dlo.robots.arm import Robot

    client = pb.connect(pb.DIRECT)
    arm = Robot.load(load_robot_spec(robot), client, (0.0, 0.0, 0.0), visuals=False)
    try:
        pos, quat = arm.grasp_pose()
        target = pos + np.array([0.006, -0.005, 0.006])
        times: dict[str, list[float]] = {solver: [] for solver in Robot.IK_SOLVERS}
        out = {}
        for _ in range(solves // 10):
            for solver in Robot.IK_SOLVERS:
                arm.ik_solver = solver
                tic = CLOCK()
                for _ in range(10):
                    q = arm.track(target, quat)
                times[solver].append((CLOCK() - tic) / 10)
        for solver in Robot.IK_SOLVERS:
            arm.ik_solver = solver
            arm._set_twin(arm.track(target, quat))
            out[solver] = (statistics.median(times[solver]) * 1e6,
                           float(np.linalg.norm(arm.grasp_pose(kinematic=True)[0] - target)))
        return out
    finally:
        arm.close()
        pb.disconnect(client)


def make_env():
    from bullet_dlo.envs.tension import TensionTrackingEnv

    return TensionTrackingEnv()


def vector_rate(steps: int, workers: int = 2) -> float:
    """Environment steps per second (all workers together) of an AsyncVectorEnv."""
    import gymnasium as gym

    envs = gym.vector.AsyncVectorEnv([make_env] * workers)
    envs.reset(seed=list(range(workers)))
    rng = np.random.default_rng(0)
    envs.step(rng.uniform(-0.2, 0.2, (workers, 6)).astype(np.float32))  # workers warmed up
    tic = time.perf_counter()
    for _ in range(steps):
        envs.step(rng.uniform(-0.2, 0.2, (workers, 6)).astype(np.float32))
    wall = time.perf_counter() - tic
    envs.close()
    return steps * workers / wall


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="short run (a smoke test, noisy numbers)")
    parser.add_argument("--robots", nargs="+", default=["panda", "kuka"])
    parser.add_argument("--masses", nargs="+", type=int, default=[10, 40])
    parser.add_argument("--python-too", action="store_true",
                        help="also time each case through PyBullet's Python API (the path without a C compiler)")
    parser.add_argument("--envs-only", action="store_true",
                        help="only part 2: each environment's step against its physical floor, and its split")
    parser.add_argument("--env-steps", type=int, default=None, help="env steps of part 2 (default 150; 10 with --quick)")
    parser.add_argument("--resets", type=int, default=None,
                        help="instead: each environment's reset, N times, against its episode's steps")
    args = parser.parse_args(argv)
    if args.resets is not None:
        resets_vs_episodes(args.resets)
        return
    blocks, env_steps = (5, 10) if args.quick else (60, 150)
    if args.env_steps is not None:
        env_steps = args.env_steps
    if args.envs_only:
        envs_vs_floor(env_steps)
        return

    print(f"load average {os.getloadavg()[0]:.2f}; "
          f"dual-arm step vs bare stepSimulation, same world, {blocks} interleaved blocks of {BLOCK} steps, "
          "medians of CPU time per simulated second; native: Bullet's C API from compiled code "
          "(bullet_dlo.bullet.native), python: PyBullet's Python API (BULLET_DLO_NATIVE=0)")
    print(f"{'robot':6} {'n':>3} {'path':>7} {'dual-arm s/s':>13} {'bare s/s':>9} {'ratio':>6}")
    parts = None
    for robot in args.robots:
        for n in args.masses:
            for path in ("native", "python") if args.python_too else ("native",):
                os.environ["BULLET_DLO_NATIVE"] = "1" if path == "native" else "0"
                physics = build(robot, n)
                try:
                    if path == "native" and not physics.world.native_handle():
                        path = "python"  # no C compiler here: the fallback is what runs
                    full, bare = step_vs_bare(physics, blocks)
                    print(f"{robot:6} {n:3d} {path:>7} {full:13.4f} {bare:9.4f} {full / bare:6.2f}")
                    if parts is None:
                        parts = (robot, n, breakdown(physics, BLOCK * blocks))
                finally:
                    physics.close()
    os.environ.pop("BULLET_DLO_NATIVE", None)
    robot, n, times = parts
    print(f"\nwhere a dual-arm step goes ({robot}, n = {n}), us per step:")
    for name, us in sorted(times.items(), key=lambda kv: -kv[1]):
        print(f"  {us:7.1f}  {name}")

    print()
    envs_vs_floor(env_steps)

    print("\nRobot.track, one solve per arm and control step (panda, a target 1 cm away), median CPU time:")
    for solver, (us, err) in ik_cost().items():
        print(f"  {solver:9} {us:7.1f} us, lands {err * 1e6:.2f} um from the target (PyBullet's forward kinematics)")

    rate, sim_rate = env_rate(env_steps)
    print(f"\nTensionTracking-v0 on one core: {rate:.0f} env steps/s ({sim_rate:.1f} simulated s per wall s); "
          f"a reset takes {reset_time(3 if args.quick else 10):.3f} s")
    vec = vector_rate(env_steps // 2 if args.quick else env_steps)
    print(f"AsyncVectorEnv, 2 processes: {vec:.0f} env steps/s together, {vec / rate:.2f}x one env in-process")


if __name__ == "__main__":
    main()
