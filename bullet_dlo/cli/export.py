"""``bullet-dlo export lerobot | robomimic DATASET OUT``: a dataset in another project's format.

See :mod:`bullet_dlo.data.lerobot` (LeRobot v3.0: captures and rollouts) and
:mod:`bullet_dlo.data.robomimic` (robomimic's HDF5: rollouts, which have actions). Bad input (DATASET not a capture
or rollout directory, OUT existing and not empty, pyarrow missing) ends with one ``error:`` line and
exit code 2 before anything is written.
"""
from __future__ import annotations

import argparse


def cmd_export_lerobot(args: argparse.Namespace) -> int:
    from bullet_dlo.data.lerobot import export_lerobot

    res = export_lerobot(args.dataset, args.target, fps=args.fps, cable_points=args.cable_points,
                         include_flagged=args.include_flagged, progress=not args.quiet)
    skipped = f"; {len(res.skipped)} episode(s) not exported (status not ok or NaN data)" if res.skipped else ""
    print(f"{res.episodes} episodes, {res.frames} frames at {res.fps} fps"
          f"{' with video' if res.video else ''} -> {res.out}{skipped}")
    for episode, why in res.skipped:
        if why not in ("flagged", "failed"):
            print(f"  not exported: episode {episode}: {why}")
    return 0


def cmd_export_robomimic(args: argparse.Namespace) -> int:
    from bullet_dlo.data.robomimic import export_robomimic

    res = export_robomimic(args.dataset, args.target, include_flagged=args.include_flagged)
    skipped = f"; {len(res.skipped)} episode(s) not exported (status not ok)" if res.skipped else ""
    print(f"{res.demos} demos, {res.samples} samples, obs {', '.join(res.obs_keys)} -> {res.out}{skipped}")
    return 0


def add_parsers(sub, common: argparse.ArgumentParser) -> None:
    """``export`` (with its format ``lerobot``) on ``sub`` (argparse subparsers)."""
    s = sub.add_parser("export", help="write a dataset in another format (LeRobot v3.0, robomimic)",
                       description="Write a capture or rollout directory in another project's format.")
    esub = s.add_subparsers(dest="export_format", required=True, metavar="FORMAT")
    e = esub.add_parser("lerobot", parents=[common], help="LeRobot v3.0 dataset (parquet + MP4, meta/info.json)",
                        description="Write DATASET (a capture or rollout directory) as a LeRobot v3.0 dataset into "
                                    "OUT (new or empty): meta/info.json, meta/stats.json, meta/tasks.parquet, "
                                    "meta/episodes/, data/, videos/ when frames were rendered; every episode's "
                                    "randomised parameters in meta/episodes (params/<name>). Needs pyarrow "
                                    "(pip install 'bullet-dlo[lerobot]').")
    e.add_argument("dataset", metavar="DATASET", help="capture or rollout directory")
    e.add_argument("target", metavar="OUT", help="output directory (must not exist, or be empty)")
    e.add_argument("--fps", type=int, default=None, help="frame rate of a capture's export [Hz] (default: the "
                   "camera rate if it rendered frames, else its record rate); rollouts use their control rate")
    e.add_argument("--cable-points", type=int, default=None, metavar="K",
                   help="cable as K points evenly spaced by node index, 2 <= K <= 10000 (needed when episodes differ "
                        "in node count; default: the nodes as recorded)")
    e.add_argument("--include-flagged", action="store_true", help="also export flagged episodes (default: ok only)")
    e.set_defaults(func=cmd_export_lerobot)
    r = esub.add_parser("robomimic", parents=[common], help="robomimic HDF5 (rollouts: obs, actions, rewards)",
                        description="Write DATASET (a rollout directory: robomimic needs the policy's actions) as one "
                                    "robomimic HDF5 file OUT: data/demo_<i>/{actions, rewards, dones, obs/<key>, "
                                    "next_obs/<key>} with the environment's observation keys flattened per step, "
                                    "data.attrs env_args naming the Gymnasium id, mask/train.")
    r.add_argument("dataset", metavar="DATASET", help="rollout directory (bullet-dlo rollouts)")
    r.add_argument("target", metavar="OUT", help="output file .hdf5 (must not exist)")
    r.add_argument("--include-flagged", action="store_true", help="also export flagged episodes (default: ok only)")
    r.set_defaults(func=cmd_export_robomimic)
