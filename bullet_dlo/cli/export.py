"""``bullet-dlo export lerobot DATASET OUT``: a capture or rollout directory as a LeRobot v3.0 dataset.

See :mod:`bullet_dlo.data.lerobot` for the layout and the features. Bad input (DATASET not a capture
or rollout directory, OUT existing and not empty, pyarrow missing) ends with one ``error:`` line and
exit code 2 before anything is written.
"""
from __future__ import annotations

import argparse


def cmd_export_lerobot(args: argparse.Namespace) -> int:
    from bullet_dlo.data.lerobot import export_lerobot

    res = export_lerobot(args.dataset, args.target, fps=args.fps, cable_points=args.cable_points,
                         include_flagged=args.include_flagged, progress=not args.quiet)
    skipped = f"; {len(res.skipped)} episode(s) not exported (status not ok)" if res.skipped else ""
    print(f"{res.episodes} episodes, {res.frames} frames at {res.fps} fps"
          f"{' with video' if res.video else ''} -> {res.out}{skipped}")
    return 0


def add_parsers(sub, common: argparse.ArgumentParser) -> None:
    """``export`` (with its format ``lerobot``) on ``sub`` (argparse subparsers)."""
    s = sub.add_parser("export", help="write a dataset in another format (LeRobot v3.0)",
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
                   help="cable as K points evenly spaced by node index (needed when episodes differ in node count; "
                        "default: the nodes as recorded)")
    e.add_argument("--include-flagged", action="store_true", help="also export flagged episodes (default: ok only)")
    e.set_defaults(func=cmd_export_lerobot)
