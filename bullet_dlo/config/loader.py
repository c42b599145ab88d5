"""The one YAML reader of scene files, capture specs and robot descriptions.

Every failure to turn a path into parsed data (missing file, a directory, bytes that are
not UTF-8, invalid YAML, a Python object tag) becomes one :class:`ParameterError` line that
names the file and, for syntax errors, the line and column. Only ``yaml.safe_load`` is
used: a file can hold plain data, never Python objects. Only regular files are read (a FIFO or
device would block or never end), at most :data:`MAX_BYTES`, and the parsed document, with its
YAML aliases expanded, may hold at most :data:`MAX_NODES` values (a few hundred bytes of nested
aliases expand to billions: the "billion laughs" bomb, which would hang every later check).
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Mapping

import yaml

from bullet_dlo.core.validate import ParameterError

MAX_BYTES = 1_000_000
"""Largest YAML file read [bytes]: scene files and specs are a few kilobytes."""
MAX_NODES = 1_000_000
"""Most values (mapping entries, list items, scalars) of one document with its aliases expanded."""


def expanded_size(data: Any, budget: int = MAX_NODES) -> int:
    """Values in ``data`` counting every alias' copy (the size every traversal pays), stopping past ``budget``."""
    count, stack = 0, [data]
    while stack and count <= budget:
        item = stack.pop()
        count += 1
        if isinstance(item, Mapping):
            stack.extend(item.values())
        elif isinstance(item, (list, tuple)):
            stack.extend(item)
    return count


def load_yaml(path: str | os.PathLike, what: str = "file") -> Any:
    """Parse the YAML file at ``path``; ``what`` names it in errors (``scene file``, ``capture spec``).

    Returns whatever the file holds (a mapping for every schema of this package; None when empty).
    """
    name = f"{what} {str(path)!r}"
    p = Path(path)
    if not p.exists():
        raise ParameterError(f"{name} does not exist")
    if p.is_dir():
        raise ParameterError(f"{name} is a directory, not a YAML file")
    if not p.is_file():
        raise ParameterError(f"{name} is not a regular file (a FIFO, socket or device); give a YAML file")
    if p.stat().st_size > MAX_BYTES:
        raise ParameterError(f"{name} is {p.stat().st_size} bytes; at most {MAX_BYTES} are read")
    try:
        text = p.read_bytes().decode("utf-8")
    except UnicodeDecodeError as err:
        raise ParameterError(f"{name} is not UTF-8 text (byte {err.start} is {err.object[err.start]:#04x})") from None
    except OSError as err:
        raise ParameterError(f"{name} cannot be read: {err.strerror}") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise ParameterError(f"{name} is not valid YAML{_where(err)}: {_problem(err)}") from None
    if expanded_size(data) > MAX_NODES:
        raise ParameterError(f"{name} expands to more than {MAX_NODES} values (nested YAML aliases?); "
                             f"write the values out")
    return data


def load_mapping(path: str | os.PathLike, what: str = "file") -> Mapping[str, Any]:
    """:func:`load_yaml` for files that must hold a mapping of keys (scene files, capture specs);
    an empty file is an empty mapping, a list or a scalar raises ParameterError naming the file."""
    data = load_yaml(path, what)
    if data is None:
        return {}
    if not isinstance(data, Mapping):
        raise ParameterError(f"{what} {str(path)!r} must hold a mapping of keys (key: value lines), "
                             f"got a {type(data).__name__}")
    return data


def _where(err: yaml.YAMLError) -> str:
    mark = getattr(err, "problem_mark", None)
    return "" if mark is None else f" (line {mark.line + 1}, column {mark.column + 1})"


def _problem(err: yaml.YAMLError) -> str:
    problem = getattr(err, "problem", None) or str(err).splitlines()[0]
    if isinstance(err, yaml.constructor.ConstructorError) and "python/" in problem:
        return "Python object tags (!!python/...) are not allowed; write plain values"
    if isinstance(err, yaml.constructor.ConstructorError):
        return f"{problem}; only standard YAML tags are allowed"
    return problem
