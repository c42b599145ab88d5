"""Reading parsed YAML sections: mappings, allowed keys, named choices, errors that name the key.

Scene files and capture specs are checked with these helpers only, so every message has the
same shape: ``<section.key>: <what is wrong>`` on one line. Values themselves are checked by
the ``check_*`` helpers of :mod:`bullet_dlo.core.validate`, the same ones the runtime classes use.
"""
from __future__ import annotations

from typing import Any, Callable, Iterable, Mapping, TypeVar

from bullet_dlo.core.validate import ParameterError

T = TypeVar("T")


def section(value: Any, key: str) -> Mapping[str, Any]:
    """``value`` as a mapping (None and a missing section are empty); ParameterError naming ``key`` otherwise."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ParameterError(f"{key} must be a mapping, got {type(value).__name__}")
    return value


def only_keys(data: Mapping[str, Any], allowed: Iterable[str], where: str) -> None:
    """Refuse keys of ``data`` outside ``allowed``, naming them and the allowed ones."""
    allowed = tuple(allowed)
    unknown = sorted(set(data) - set(allowed), key=str)
    if unknown:
        raise ParameterError(f"unknown key(s) {', '.join(map(str, unknown))} in {where}; allowed: {', '.join(allowed)}")


def one_of(key: str, value: Any, allowed: Iterable[str]) -> str:
    """``value`` as one of the names in ``allowed``; ParameterError naming ``key`` and the names otherwise."""
    allowed = tuple(allowed)
    if value not in allowed:
        raise ParameterError(f"{key} must be one of {', '.join(allowed)}, got {value!r}")
    return str(value)


def keyed(where: str, fn: Callable[..., T], *args: Any, **kwargs: Any) -> T:
    """Call ``fn``; a ParameterError or TypeError it raises is re-raised prefixed with ``where``."""
    try:
        return fn(*args, **kwargs)
    except (ParameterError, TypeError) as err:
        raise ParameterError(f"{where}: {err}") from None
