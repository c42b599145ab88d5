"""MkDocs hook: the docstrings write units in brackets, ``[fx fy fz mx my mz] [N, N m]``.

Markdown reads ``[text] [label]`` as a reference link, and mkdocs-autorefs then warns that it
cannot find the cross-reference ``N, N m``. Those are units, not references: this filter drops
that one warning when the would-be target is a list of SI units, and nothing else, so
``mkdocs build --strict`` still fails on every other warning (and on a real broken reference).
"""
from __future__ import annotations

import logging
import re

UNIT = r"(?:N|m|s|kg|Pa|J|W|Hz|rad|deg|K|1/s|m/s|m/s\^2|rad/s|N m|N/m|N s/m|kg/m\^3|mm|us|ms)"
UNITS = re.compile(rf"{UNIT}(?:\s*,\s*{UNIT})*")
TARGET = re.compile(r"Could not find cross-reference target '([^']*)'")


class UnitBrackets(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        m = TARGET.search(record.getMessage())
        return not (m and UNITS.fullmatch(m.group(1).strip()))


def on_startup(command, dirty) -> None:  # noqa: ARG001 (MkDocs hook signature)
    logging.getLogger("mkdocs.plugins.mkdocs_autorefs._internal.plugin").addFilter(UnitBrackets())


def on_files(files, config):
    """Serve ``demos/gallery/`` (the pictures the demos write) as ``gallery/`` without copying them into docs/."""
    from pathlib import Path

    from mkdocs.structure.files import File

    demos = Path(config["docs_dir"]).parent / "demos"
    for path in sorted((demos / "gallery").glob("*")):
        if path.suffix in (".png", ".mp4", ".csv", ".json"):
            files.append(File(f"gallery/{path.name}", str(demos), config["site_dir"], config["use_directory_urls"]))
    return files
