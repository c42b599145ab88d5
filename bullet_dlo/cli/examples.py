"""``bullet-dlo examples DIR``: copy the example scene files and capture specs that ship with the package.

The README and the docs use paths such as ``demos/scenes/lv_study.yaml``; from a source checkout they
exist, from a pip install they do not. This copies them into ``DIR/demos/scenes`` and
``DIR/demos/specs`` so that every documented command runs from ``DIR``. Files already there are kept
(listed as kept), never overwritten.
"""
from __future__ import annotations

import argparse
import shutil
from pathlib import Path

KINDS = {"scenes": "demos/scenes", "specs": "demos/specs"}


def copy_examples(target: str | Path) -> tuple[list[Path], list[Path]]:
    """Copy every shipped example into ``target`` (created if needed); the files copied and those kept."""
    from bullet_dlo.assets import asset_dir
    from bullet_dlo.config.schema import output_file

    root = Path(target)
    copied, kept = [], []
    for kind, rel in KINDS.items():
        for src in sorted(asset_dir(kind).glob("*.yaml")):
            dst = root / rel / src.name
            if dst.exists():
                kept.append(dst)
                continue
            output_file("DIR", dst)  # a one-line error for a path that cannot be written, before any copy
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(src, dst)
            copied.append(dst)
    return copied, kept


def cmd_examples(args: argparse.Namespace) -> int:
    copied, kept = copy_examples(args.target)
    for path in copied:
        print(f"copied {path}")
    for path in kept:
        print(f"kept   {path} (already there)")
    print(f"\nfrom {Path(args.target).resolve()}, for example:\n"
          "  bullet-dlo simulate demos/scenes/lv_study.yaml --json out.json\n"
          "  bullet-dlo capture demos/specs/dr_small.yaml --out data/dr --episodes 4")
    return 0


def add_parsers(sub, common: argparse.ArgumentParser) -> None:
    """``examples`` on ``sub`` (argparse subparsers)."""
    s = sub.add_parser("examples", parents=[common], help="copy the example scene files and capture specs into DIR",
                       description="Copy the example scene files (demos/scenes/*.yaml) and capture specs "
                                   "(demos/specs/*.yaml) that ship with the package into DIR/demos/, so that the "
                                   "commands of the README and the docs run from DIR after a pip install. Files "
                                   "already in DIR are kept, never overwritten.")
    s.add_argument("target", metavar="DIR", help="folder to copy into (created if missing)")
    s.set_defaults(func=cmd_examples)


__all__ = ["add_parsers", "cmd_examples", "copy_examples"]
