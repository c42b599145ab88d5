"""Where a command's outputs go: the picture beside the numbers, and one closing line naming every file.

Every command that writes numbers also writes the picture a person would rather look at: ``--plot
PNG`` names it; without it the picture goes beside the first numbers file the command writes
(``run.json`` -> ``run.png``); ``--no-plot`` leaves it out. A command that writes no file prints its
numbers only. The last line a command prints lists what it wrote, as absolute paths.
"""
from __future__ import annotations

import argparse
from pathlib import Path


def add_plot_options(parser: argparse.ArgumentParser, what: str) -> None:
    """``--plot PNG`` and ``--no-plot`` on ``parser``; ``what``: what the picture shows (for --help)."""
    parser.add_argument("--plot", metavar="OUT.png", help=f"write {what} to this PNG (default: beside the first "
                        "numbers file written, same name with .png; none when no file is written)")
    parser.add_argument("--no-plot", action="store_true", help="do not write the picture")


def plot_path(args: argparse.Namespace, *outputs: str | None) -> Path | None:
    """The PNG the command writes: ``--plot``, else the first of ``outputs`` given with its suffix set to .png,
    else None; None with ``--no-plot``."""
    from bullet_dlo.core.validate import ParameterError

    if getattr(args, "no_plot", False):
        return None
    if getattr(args, "plot", None):
        path = Path(args.plot)
        if path.suffix.lower() != ".png":
            raise ParameterError(f"--plot must end in .png, got {args.plot!r}")
        return path
    first = next((o for o in outputs if o), None)
    return None if first is None else Path(first).with_suffix(".png")


def print_outputs(*paths: str | Path | None) -> None:
    """One closing line: every file written (absolute paths), or nothing when none was."""
    written = [str(Path(p).resolve()) for p in paths if p]
    if written:
        print("outputs: " + ", ".join(written))
