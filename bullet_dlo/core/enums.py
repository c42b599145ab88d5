"""The closed sets of names, one enum each: the one vocabulary of scene files, capture specs, the API and the CLI.

Every enum is a ``str`` enum, so a YAML string, an old string comparison (``spec.section == "tube"``)
and a dictionary lookup by the plain name all keep working: ``Section.TUBE == "tube"``. Membership is
checked once where user input enters (:func:`choice`, used by :mod:`bullet_dlo.config` and the typed
specs' ``__post_init__``), with one error line naming the key and listing the allowed values.

Open sets stay strings: robot names (the files in ``robots/``) and cable presets.
The core layer owns this module because the core already needs most of these sets (sections,
end modes, integrators); it imports nothing but the standard library and :mod:`.validate`.
"""
from __future__ import annotations

from enum import Enum
from typing import Any, TypeVar

from bullet_dlo.core.validate import ParameterError

E = TypeVar("E", bound="NamedSet")


class NamedSet(str, Enum):
    """A closed set of names; a member equals (and hashes as) its name, and ``str()`` gives the name."""

    def __str__(self) -> str:
        return str(self.value)

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """The allowed names, in their documented order."""
        return tuple(m.value for m in cls)


class IntegratorName(NamedSet):
    """Time integrators of the cable (:data:`bullet_dlo.core.integrators.INTEGRATORS`)."""

    EXPLICIT_EULER = "explicit_euler"
    SYMPLECTIC_EULER = "symplectic_euler"
    RK4 = "rk4"
    IMPLICIT_EULER = "implicit_euler"
    BDF2 = "bdf2"
    IMPLICIT_MIDPOINT = "implicit_midpoint"
    GAUSS_LEGENDRE = "gauss_legendre"


class EndMode(NamedSet):
    """How a cable end is held: ``free``, ``pinned`` (position), ``fork`` (position and the roll about the
    holder's axis, the direction free: a fork support, a ball joint whose roll is locked) or ``clamped``
    (position, tangent and roll). Only a cable with a material frame feels a roll."""

    FREE = "free"
    PINNED = "pinned"
    FORK = "fork"
    CLAMPED = "clamped"

    @property
    def holds_roll(self) -> bool:
        """Whether the holder holds the section's roll about its axis (a twist spring at the end node)."""
        return self in (EndMode.FORK, EndMode.CLAMPED)

    @property
    def holder(self) -> str:
        """What holds an end in this mode, for messages: ``free end``, ``pin``, ``fork`` or ``clamp``."""
        return {"free": "free end", "pinned": "pin", "fork": "fork", "clamped": "clamp"}[self.value]


class Section(NamedSet):
    """Cable cross-section shape (:class:`~bullet_dlo.core.spec.CableSpec`)."""

    ROUND = "round"
    TUBE = "tube"
    RECTANGLE = "rectangle"


class Discretisation(NamedSet):
    """How mass and bending stiffness are lumped: ``default`` (second order) or ``paper`` (Lv et al. 2017)."""

    DEFAULT = "default"
    PAPER = "paper"


class MotionType(NamedSet):
    """Kinds of prescribed end motion (``motion:`` entries)."""

    MOVE = "move"
    WAYPOINTS = "waypoints"
    SINE = "sine"


class InitialShape(NamedSet):
    """A scene's ``initial:`` shape: ``straight`` or ``static`` (equilibrium under gravity)."""

    STRAIGHT = "straight"
    STATIC = "static"


class ToleranceTarget(NamedSet):
    """What ``tolerance.target`` converges: the end ``forces`` (and moments), the ``shape``, or ``both``."""

    FORCES = "forces"
    SHAPE = "shape"
    BOTH = "both"


class SelfCollision(NamedSet):
    """``bullet.self_collision``: which of the cable's own segments collide."""

    NEIGHBOURS = "neighbours"
    NONE = "none"
    ALL = "all"


class Sync(NamedSet):
    """``bullet.sync``: when the cable's Bullet bodies are moved to its nodes."""

    CONTACTS = "contacts"
    ALWAYS = "always"


class Contact(NamedSet):
    """How the cable meets Bullet bodies: ``model`` (in the cable's implicit step), ``bullet`` or ``auto``."""

    AUTO = "auto"
    MODEL = "model"
    BULLET = "bullet"


class ObstacleType(NamedSet):
    """``bullet.obstacles[k].type``."""

    BOX = "box"
    CYLINDER = "cylinder"
    URDF = "urdf"


class GripKind(NamedSet):
    """How a gripper holds its cable end: ``clamp`` (rigid) or ``friction`` (pinched, may slip)."""

    CLAMP = "clamp"
    FRICTION = "friction"


class Payload(NamedSet):
    """How the wrist sensors know the tool below them: from the ``urdf`` or ``calibrated``."""

    URDF = "urdf"
    CALIBRATED = "calibrated"


class ArmStart(NamedSet):
    """The cable's shape when the grippers take it: ``settled`` (static) or ``straight``."""

    SETTLED = "settled"
    STRAIGHT = "straight"


class Engine(NamedSet):
    """What steps a scene: the numerical ``core``, ``bullet`` (a PyBullet world), or the dual-``arms`` scene."""

    CORE = "core"
    BULLET = "bullet"
    ARMS = "arms"


class Dist(NamedSet):
    """Distributions of a capture spec's ``sample:`` entries."""

    UNIFORM = "uniform"
    LOG_UNIFORM = "log_uniform"
    NORMAL = "normal"
    CHOICE = "choice"
    FIXED = "fixed"


class UnstablePolicy(NamedSet):
    """A capture spec's ``policy:`` for draws whose step is unstable."""

    REJECT = "reject"
    IMPLICIT = "implicit"
    SUBSTEPS = "substeps"


class Renderer(NamedSet):
    """Bullet renderers: ``auto``, ``tiny`` (CPU) or ``egl`` (GPU)."""

    AUTO = "auto"
    TINY = "tiny"
    EGL = "egl"


class FitStart(NamedSet):
    """Where ``fit``'s model starts: ``auto`` (the recording's first shape when it has one, else static),
    the ``static`` equilibrium, ``straight``, or the ``recorded`` first shape."""

    AUTO = "auto"
    STATIC = "static"
    STRAIGHT = "straight"
    RECORDED = "recorded"


class ResidualKind(NamedSet):
    """What a recording holds that ``fit`` can compare: end ``force`` [N], end ``moment`` [N m], ``linear``
    (joint torques or any signal linear in the end loads), ``marker`` positions [m]."""

    FORCE = "force"
    MOMENT = "moment"
    LINEAR = "linear"
    MARKER = "marker"


class RecordingHold(NamedSet):
    """How a recording's cable end is held: ``clamped`` (pose recorded) or ``free``."""

    CLAMPED = "clamped"
    FREE = "free"


class StripModel(NamedSet):
    """The beam_handling strip in ``validate beam``: one 3-D ``rectangle`` run, or two planar isotropic ``planes``."""

    RECTANGLE = "rectangle"
    PLANES = "planes"


class RolloutPolicy(NamedSet):
    """The built-in policies of ``rollouts`` (a ``package.module:function`` names a user's own)."""

    RANDOM = "random"
    SCRIPTED = "scripted"
    ZERO = "zero"


def choice(key: str, value: Any, enum: type[E], *, lower: bool = False) -> E:
    """``value`` as a member of ``enum`` (``lower``: the name in any case); ParameterError naming ``key`` and
    listing the allowed names otherwise. The one membership check of every closed set."""
    if isinstance(value, enum):
        return value
    name = value.lower() if lower and isinstance(value, str) else value
    try:
        return enum(name)
    except ValueError:
        raise ParameterError(f"{key} must be one of {', '.join(enum.names())}, got {value!r}") from None


def name_of(key: str, value: Any, enum: type[NamedSet], *, lower: bool = False) -> str:
    """:func:`choice` as the plain name (what dataclass fields store, so YAML, JSON and HDF5 attributes
    write it as a string; it equals the enum member)."""
    return str(choice(key, value, enum, lower=lower).value)


ENUMS: tuple[type[NamedSet], ...] = (IntegratorName, EndMode, Section, Discretisation, MotionType, InitialShape,
                                    ToleranceTarget, SelfCollision, Sync, Contact, ObstacleType, GripKind, Payload,
                                    ArmStart, Engine, Dist, UnstablePolicy, Renderer, FitStart, ResidualKind,
                                    RecordingHold, StripModel, RolloutPolicy)
"""Every closed set of this module."""

__all__ = ["NamedSet", "choice", "name_of", "ENUMS", *(e.__name__ for e in ENUMS)]
