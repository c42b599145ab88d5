"""Learn ``bullet_dlo/TensionTracking-v0`` from force feedback (SAC, stable-baselines3), against baselines.

The policy sees what a force-controlled cell would: the task vector (target tension now and its
change over the next 0.5 s, the tension the wrist sensors measure, the midpoint target relative to
the grippers), both wrist wrenches and the gripper offsets from their reset poses, scaled to
order one (:class:`ForceFeedback`). Every ``--eval-every`` steps it is evaluated (deterministic) on
fixed seeds, beside a random and the scripted proportional policy
(:func:`bullet_dlo.envs.tension.scripted_action`) on the same seeds. Writes, into ``--out``
(printed): ``curve.csv`` (steps, mean evaluation return of each policy), ``curve.png``, the
model ``sac_tension.zip`` and ``learned.mp4`` (an evaluation episode of the learned policy).

Needs the ``rl`` extra (``pip install -e .[rl]``, with the CPU build of torch). The full run
(30 minutes of training on a laptop's two cores)::

    python demos/train_tension.py --minutes 30

``--quick`` is a smoke test (a few hundred steps).
"""
from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

from bullet_dlo.envs.tension import TensionTrackingEnv, scripted_action
from bullet_dlo.render.video import VideoWriter

EPISODE_STEPS = 100  # control steps per episode (5 s at 20 Hz), as registered
EVAL_SEEDS = (1000, 1001, 1002)


class ForceFeedback(gym.ObservationWrapper):
    """The Dict observation as a flat vector of order one (25,): the task vector with the sensed tension
    error made explicit and every entry on its reward scale (tension target, its change, sensed tension
    / 5 N, error / 1 N; midpoint offset / 3 cm), the wrist wrenches / 10 N and the gripper offsets from
    their reset poses / 5 cm. Only what a force-controlled cell measures: no privileged cable state."""

    def __init__(self, env: TensionTrackingEnv):
        super().__init__(env)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (25,), np.float32)

    def observation(self, obs: dict) -> np.ndarray:
        target, change, sensed, *offset = obs["task"]
        task = [target / 5.0, change, sensed / 5.0, target - sensed, *(np.asarray(offset) / 0.03)]
        offsets = (obs["gripper_pos"] - self.env.unwrapped.home) / 0.05
        return np.concatenate([task, obs["wrench"].reshape(-1) / 10.0, offsets.reshape(-1)]).astype(np.float32)


MAX_SPEED = 0.01  # [m/s] gripper speed of a full action: the cable's axial stiffness (EA / L ~ 400-2000 N/m)
# turns the environment's default 0.05 m/s into up to 5 N of tension per control step, so exploration
# noise alone would swamp targets of 1-4 N; at 0.01 m/s a full action moves 0.5 mm per step


def make_env(render: bool = False, episode_steps: int = EPISODE_STEPS) -> gym.Env:
    env = TensionTrackingEnv(render_mode="rgb_array" if render else None, max_speed=MAX_SPEED)
    return ForceFeedback(gym.wrappers.TimeLimit(env, episode_steps))


def scripted(raw: dict) -> np.ndarray:
    """The scripted P-controller with its physical gains (per N, per m of gripper speed) as at the default speed."""
    scale = 0.05 / MAX_SPEED
    return scripted_action(raw, gain_tension=0.5 * scale, gain_position=20.0 * scale)


def evaluate(env: gym.Env, policy, seeds=EVAL_SEEDS) -> float:
    """Mean return over one episode per seed; ``policy(wrapped_obs, dict_obs)`` -> action."""
    returns = []
    for seed in seeds:
        obs, _ = env.reset(seed=seed)
        total, done = 0.0, False
        while not done:
            raw = env.unwrapped._observation()
            obs, r, term, trunc, _ = env.step(policy(obs, raw))
            total += r
            done = term or trunc
        returns.append(total)
    return float(np.mean(returns))


def baselines(env: gym.Env, seeds=EVAL_SEEDS) -> dict[str, float]:
    rng = np.random.default_rng(0)
    return {"random": evaluate(env, lambda o, raw: rng.uniform(-1, 1, 6).astype(np.float32), seeds),
            "scripted": evaluate(env, lambda o, raw: scripted(raw), seeds),
            "hold still": evaluate(env, lambda o, raw: np.zeros(6, np.float32), seeds)}


def record(env: gym.Env, policy, path: Path) -> Path:
    writer = VideoWriter(path, fps=env.unwrapped.metadata["render_fps"])
    obs, _ = env.reset(seed=EVAL_SEEDS[0])
    done = False
    while not done:
        writer.write(env.render())
        obs, _, term, trunc, _ = env.step(policy(obs, None))
        done = term or trunc
    writer.close()
    return writer.path


def plot(rows: list[dict], base: dict[str, float], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.plot([r["steps"] for r in rows], [r["sac"] for r in rows], "o-", label="SAC (learned)")
    for (name, value), style in zip(base.items(), (":", "--", "-.")):
        ax.axhline(value, ls=style, color="gray", label=name)
    ax.set_xlabel("environment steps (20 Hz control)")
    ax.set_ylabel("evaluation return (1 per step at best)")
    ax.set_title("TensionTracking-v0, force feedback")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=30.0, help="training budget [min] (wall clock)")
    parser.add_argument("--eval-every", type=int, default=2000, help="environment steps between evaluations")
    parser.add_argument("--out", default="out/train_tension")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quick", action="store_true", help="a smoke test: 20-step episodes, one round of 60 steps")
    args = parser.parse_args(argv)
    try:
        import torch
        from stable_baselines3 import SAC
    except ImportError as err:  # one line, not a traceback: the RL stack is an optional extra
        raise SystemExit(f"error: training needs PyTorch and Stable-Baselines3 ({err.name} is missing): "
                         'pip install -e ".[rl]"') from None

    torch.set_num_threads(1)  # the environment steps in this process too: one thread each, no oversubscription

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print(f"writing into {out.resolve()}")
    budget = 0.0 if args.quick else 60.0 * args.minutes  # quick: one round
    eval_every = 60 if args.quick else args.eval_every
    seeds = EVAL_SEEDS[:1] if args.quick else EVAL_SEEDS
    episode_steps = 20 if args.quick else EPISODE_STEPS
    env, eval_env = make_env(episode_steps=episode_steps), make_env(True, episode_steps)
    base = baselines(eval_env, seeds)
    print("baselines (mean evaluation return): " + ", ".join(f"{k} {v:.1f}" for k, v in base.items()))
    # gamma 0.95: a tracking reward pays now, a horizon of ~20 control steps (1 s) is plenty
    model = SAC("MlpPolicy", env, learning_starts=30 if args.quick else 1000, batch_size=128, gamma=0.95,
                policy_kwargs={"net_arch": [128, 128]}, seed=args.seed, verbose=0, device="cpu")

    def act(obs, raw):
        return model.predict(obs, deterministic=True)[0]

    rows, steps, tic = [], 0, time.perf_counter()
    while not rows or time.perf_counter() - tic < budget:
        model.learn(eval_every, reset_num_timesteps=False, progress_bar=False)
        steps += eval_every
        train_time = time.perf_counter() - tic
        rows.append({"steps": steps, "minutes": train_time / 60.0, "sac": evaluate(eval_env, act, seeds), **base})
        print(f"{steps:7d} steps, {train_time / 60:5.1f} min: SAC {rows[-1]['sac']:.1f}")
    with open(out / "curve.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    plot(rows, base, out / "curve.png")
    model.save(out / "sac_tension.zip")
    video = record(eval_env, act, out / "learned")
    print(f"wrote curve.csv, curve.png, sac_tension.zip, {video.name}")
    env.close()
    eval_env.close()


if __name__ == "__main__":
    main()
