"""Reading parsed YAML sections: mappings, allowed keys, named choices, errors that name the key.

Scene files and capture specs are checked with these helpers only, so every message has the
same shape: ``<section.key>: <what is wrong>`` on one line. Values themselves are checked by
the ``check_*`` helpers of :mod:`bullet_dlo.core.validate`, the same ones the runtime classes use.
Also here: the one table of cable bounds (:data:`CABLE_BOUNDS`), the caps on work (:data:`LIMITS`)
and the checks of output paths, all applied before any work starts.
"""
from __future__ import annotations

import math
import os
from pathlib import Path
from enum import Enum
from typing import Any, Callable, Iterable, Mapping, TypeVar

from bullet_dlo.core.enums import Discretisation, NamedSet, Section, name_of
from bullet_dlo.core.spec import SECTION_MAX
from bullet_dlo.core.validate import ParameterError, check_friction_order

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


def one_of(key: str, value: Any, allowed: Iterable[str] | type[NamedSet]) -> str:
    """``value`` as one of the names in ``allowed`` (an enum of :mod:`bullet_dlo.core.enums`, or an open set
    such as the robot names); ParameterError naming ``key`` and listing the names otherwise."""
    if isinstance(allowed, type) and issubclass(allowed, Enum):
        return name_of(key, value, allowed)
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


# ----- one table of bounds -----------------------------------------------------------------------
# Physical bounds of a cable, shared by scene files and capture specs (a capture spec's ranges,
# config.capture.PARAMETERS, are narrower robot-scene ranges inside these; tests/config checks it).
CABLE_BOUNDS: dict[str, tuple[float, float]] = {
    "length": (1e-3, 1e3),  # [m]
    "diameter": (1e-5, 1.0),  # [m], and at most DIAMETER_PER_LENGTH x the length
    "mass": (1e-6, 1e4),  # [kg]
    "youngs_modulus": (1e3, 1e13),  # [Pa] soft rubber 1e6, steel 2e11; 1e13 is stiffer than diamond
    "n_masses": (2, 100_000),
    "damping": (0.0, 1e4),  # [N s/m]
    "dynamic_friction": (0.0, 10.0),  # [-] Coulomb coefficients
    "static_friction": (0.0, 10.0),  # [-]
    "poisson_ratio": (0.0, 0.4999),  # G = E / (2 (1 + nu)): the twist springs G J / l0
    "shear_modulus": (0.0, 1e13),  # [Pa] G itself (0: from E and nu); a stranded cable's is far below E / 3
    "inner_diameter": (0.0, 1.0),  # [m] tube bore, below the diameter
    "width": (0.0, SECTION_MAX),  # [m] rectangle width (along the section axis d1)
    "thickness": (0.0, SECTION_MAX),  # [m] rectangle thickness (along d2)
}
CABLE_NAMES: dict[str, type[NamedSet]] = {"section": Section, "discretisation": Discretisation}
CABLE_FLAGS = ("twist",)  # true or false (a material frame: twist springs, the grippers' roll)
DIAMETER_PER_LENGTH = 0.5  # a cable is slender: its diameter is at most half its length

# Caps on work, applied to values from files and from command-line flags alike.
LIMITS: dict[str, float] = {
    "steps": 1e10,  # time steps of one run (duration / dt x substeps)
    "episodes": 1_000_000,  # episodes of one capture
    "workers": 1024,  # worker processes of one capture
    "substeps": 10_000,  # integrator steps per Bullet step
    "pixels": 8192,  # frame width or height [px]
}


SECTION_DIMENSIONS = {"inner_diameter": "tube", "width": "rectangle", "thickness": "rectangle"}  # key: its section


def _check_section_dimensions(data: Mapping[str, Any], where: str) -> None:
    """A section's own dimensions in their real ranges (a tube's bore in (0, diameter), a rectangle's width and
    thickness in (0, 1] m), a tube's bore given, and no dimension of another section; one line naming the key."""
    from bullet_dlo.core.validate import _float

    shape = str(data.get("section", "round")).lower()
    for key, owner in SECTION_DIMENSIONS.items():
        if key not in data:
            if shape == owner == "tube":
                raise ParameterError(f"{where}.inner_diameter missing: a tube needs its bore, in (0, diameter) [m] "
                                     f"(a solid section is round, with twist: true for a frame)")
            continue
        if shape != owner:
            allowed = "(0, diameter)" if owner == "tube" else f"(0, {CABLE_BOUNDS[key][1]}]"
            raise ParameterError(f"{where}.{key} is for section: {owner} only (section is {shape}); with section: "
                                 f"{owner} it is in {allowed} [m]")
        lo, hi = CABLE_BOUNDS[key]
        if key == "inner_diameter":
            diameter = data.get("diameter")
            top = f"diameter = {diameter}" if isinstance(diameter, (int, float)) else "the diameter"
            v = _float(f"{where}.{key}", data[key], f"a number in (0, {top})")
            ok = math.isfinite(v) and lo < v <= hi and (not isinstance(diameter, (int, float)) or v < diameter)
            if not ok:
                raise ParameterError(f"{where}.{key} must be in (0, {top}) [m] for section: tube, got {data[key]!r}")
        else:
            v = _float(f"{where}.{key}", data[key], f"a number in (0, {hi}]")
            if not (math.isfinite(v) and 0.0 < v <= hi):
                raise ParameterError(f"{where}.{key} must be in (0, {hi}] [m] for section: rectangle, got {data[key]!r}")


def check_cable(data: Mapping[str, Any], where: str = "cable") -> None:
    """Check the numbers of a parsed cable mapping against :data:`CABLE_BOUNDS` (keys it has only;
    the cable class checks the rest), each error naming ``<where>.<key>`` and its range."""
    from bullet_dlo.core.validate import check_in_range, check_int

    for key, names in CABLE_NAMES.items():
        if key in data:
            one_of(f"{where}.{key}", str(data[key]).lower() if key == "section" else data[key], names)
    for key, (lo, hi) in CABLE_BOUNDS.items():
        if key in data and key not in SECTION_DIMENSIONS:
            if key == "n_masses":
                check_int(f"{where}.{key}", data[key], int(lo), int(hi))
            else:
                check_in_range(f"{where}.{key}", data[key], lo, hi)
    _check_section_dimensions(data, where)
    _check_friction_order(data, where)
    for key in CABLE_FLAGS:
        if key in data and not isinstance(data[key], bool):
            raise ParameterError(f"{where}.{key} must be true or false, got {data[key]!r}")
    if "diameter" in data and "length" in data and float(data["diameter"]) > DIAMETER_PER_LENGTH * float(data["length"]):
        raise ParameterError(f"{where}.diameter = {data['diameter']} m must be at most {DIAMETER_PER_LENGTH} x "
                             f"{where}.length ({data['length']} m)")


def _check_friction_order(data: Mapping[str, Any], where: str) -> None:
    """Coulomb friction slips at or below the force it holds: ``dynamic_friction <= static_friction`` (the
    cable's default static_friction when the mapping leaves it out)."""
    from dataclasses import fields

    from bullet_dlo.core.spec import CableSpec

    if "dynamic_friction" not in data:
        return
    default = {f.name: f.default for f in fields(CableSpec)}["static_friction"]
    dynamic, static = float(data["dynamic_friction"]), float(data.get("static_friction", default))
    hint = "" if "static_friction" in data else " (its default; give static_friction too)"
    check_friction_order(dynamic, static, f"{where}.", hint)


# ----- output paths ------------------------------------------------------------------------------
def _existing_ancestor(path: Path) -> Path:
    """The nearest part of ``path`` (itself or a parent) that exists."""
    p = path
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def _path_fits(name: str, p: Path) -> None:
    """Refuse a path the file system cannot hold (a component over 255 bytes, the whole over 4096)."""
    longest = max((len(part.encode()) for part in p.parts), default=0)
    if longest > 255 or len(str(p.absolute()).encode()) > 4096:
        raise ParameterError(f"{name} is too long for the file system (a name of at most 255 bytes, a path of at "
                             f"most 4096)")


def output_dir(name: str, path: str | os.PathLike) -> Path:
    """``path`` as a folder this process can create or write into, checked before any work starts;
    ParameterError naming the option ``name`` otherwise (a file, a folder under a file, read-only)."""
    p = Path(path)
    _path_fits(name, p)
    if p.exists() and not p.is_dir():
        raise ParameterError(f"{name} {str(p)!r} is a file; give a folder")
    base = _existing_ancestor(p.absolute())
    if not base.is_dir():
        raise ParameterError(f"{name} {str(p)!r} lies under the file {str(base)!r}; give a folder")
    if not _can_write_in(base):
        raise ParameterError(f"{name} {str(p)!r} cannot be written ({str(base)!r} is not writable)")
    return p


def _can_write_in(folder: Path) -> bool:
    """True if a file can be created in ``folder`` (tried: os.access says yes to root on /proc)."""
    import tempfile

    try:
        with tempfile.TemporaryFile(dir=folder):
            return True
    except OSError:
        return False


def output_file(name: str, path: str | os.PathLike) -> Path:
    """``path`` as a file this process can create or replace, checked before any work starts;
    ParameterError naming the option ``name`` otherwise (a folder, under a file, read-only)."""
    p = Path(path)
    _path_fits(name, p)
    if p.is_dir():
        raise ParameterError(f"{name} {str(p)!r} is a folder; give a file name")
    if p.exists() and not os.access(p, os.W_OK):
        raise ParameterError(f"{name} {str(p)!r} cannot be written (read-only)")
    output_dir(name, p.parent)
    return p
