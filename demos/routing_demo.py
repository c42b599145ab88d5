"""Routing-v0 baselines: the scripted taut-string policy (RoutingPolicy) against random actions.

    python demos/routing_demo.py            # 10 seeds each, episode limit of the registration
    python demos/routing_demo.py --quick    # 2 seeds, a smoke run

Prints and writes ``routing_baselines.json``: per policy the success rate, mean return and mean
episode length over the seeds, and per episode the pegs' wrap angles and how it ended (success,
overload, instability). The scripted policy reads the observation only (peg and clip positions,
route sides, the grippers' poses and the right wrist's force).
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from bullet_dlo._gym_registration import ENV_IDS
from bullet_dlo.envs.routing import RoutingEnv, RoutingPolicy

EPISODE_STEPS = ENV_IDS["bullet_dlo/Routing-v0"][1]


def run_episode(env: RoutingEnv, seed: int, policy: str, steps: int) -> dict:
    """One episode of ``policy`` ("scripted" or "random", the latter seeded by ``seed``) after ``reset(seed)``."""
    obs, info = env.reset(seed=seed)
    scripted, rng = RoutingPolicy(), np.random.default_rng(seed)
    total, k = 0.0, 0
    for k in range(1, steps + 1):
        action = scripted(obs) if policy == "scripted" else rng.uniform(-1, 1, 4).astype(np.float32)
        obs, reward, terminated, _, info = env.step(action)
        total += reward
        if terminated:
            break
    return {"seed": seed, "pegs": len(env.route.pegs), "success": bool(info["is_success"]), "return": total,
            "steps": k, "wraps_deg": np.degrees(info["wraps"]).round(1).tolist(), "overload": info["overload"],
            "unstable": info["unstable"], "threaded": info["threaded"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=10, help="episodes per policy (seeds 0 .. seeds - 1)")
    parser.add_argument("--quick", action="store_true", help="2 seeds: a smoke run")
    parser.add_argument("--out", default="out/routing_demo", help="output folder")
    args = parser.parse_args()
    seeds = range(2 if args.quick else args.seeds)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    env = RoutingEnv()
    summary = {}
    try:
        for policy in ("scripted", "random"):
            t0 = time.perf_counter()
            episodes = [run_episode(env, seed, policy, EPISODE_STEPS) for seed in seeds]
            summary[policy] = {"success_rate": float(np.mean([e["success"] for e in episodes])),
                               "mean_return": float(np.mean([e["return"] for e in episodes])),
                               "mean_steps": float(np.mean([e["steps"] for e in episodes])),
                               "wall_s": time.perf_counter() - t0, "episodes": episodes}
            s = summary[policy]
            print(f"{policy:8s}: success {s['success_rate']:.0%} over {len(episodes)} seeds, mean return "
                  f"{s['mean_return']:.1f}, mean length {s['mean_steps']:.0f} steps, {s['wall_s']:.1f} s")
    finally:
        env.close()
    (out / "routing_baselines.json").write_text(json.dumps(summary, indent=1))
    print(f"outputs written to {out.resolve()}")


if __name__ == "__main__":
    main()
