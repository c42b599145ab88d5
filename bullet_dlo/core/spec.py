"""Cable specification: the physical parameters of a cable and what follows from them.

Everything is SI: metres, kilograms, seconds, pascals, newtons.

A :class:`CableSpec` is immutable and validated on construction; every bad value raises
:class:`ParameterError` naming the field and the allowed range. Discretised quantities
(rest length, spring constants, point masses) are derived here so that every layer
(core, Bullet, datasets) agrees on them.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace
from typing import Any, Mapping

import numpy as np

from bullet_dlo.core.enums import Discretisation, Section, name_of
from bullet_dlo.core.validate import (
    ParameterError,
    check_friction_order,
    check_in_range,
    check_int,
    check_nonnegative,
    check_positive,
    renamed_keys,
)

DISCRETISATIONS = Discretisation.names()
SECTIONS = Section.names()
SECTION_MAX = 1.0  # [m] a rectangle's width and thickness at most (scene files share it: config.schema)
RENAMED: dict[str, str] = {"friction": "dynamic_friction"}
"""Deprecated cable parameter names -> their names now (accepted with a DeprecationWarning for one release)."""


@dataclass(frozen=True)
class CableSpec:
    """Physical cable parameters (SI) and how the cable is discretised.

    Attributes:
        length: cable length L [m], > 0.
        diameter: cross-section diameter d [m], > 0.
        mass: total mass M [kg], > 0.
        youngs_modulus: Young's modulus E [Pa], > 0.
        n_masses: number of point masses n, >= 2.
        damping: the paper's viscous damping k_d [N s/m] per average point mass, >= 0 (see
            :meth:`damping_coefficients`). Its meaning depends on n: every mode decays at k_d n / (2M),
            so refining the cable changes the physics. Kept for ``discretisation: paper`` (Lv et al.)
            and old scene files; use ``damping_rate`` and ``internal_damping`` instead.
        damping_rate: mass-proportional drag c [1/s], F_i = -c m_i v_i, in [0, 1e4]. The same at any
            n: a free mass's velocity (and the cable's rigid motion) decays as exp(-c t); an
            oscillating mode's amplitude decays as exp(-c t / 2).
        internal_damping: Kelvin-Voigt retardation time tau [s], in [0, 1]: stretch and bending
            stresses get E tau d(strain)/dt and E I tau d(curvature)/dt. Mode k (angular frequency
            omega_k) decays as exp(-tau omega_k^2 t / 2) (damping ratio omega_k tau / 2: high
            modes are damped more); rigid translation and rotation are not damped.
        dynamic_friction: dynamic (sliding) Coulomb friction coefficient mu_d [-] against the
            environment and other cables, in [0, static_friction] (``friction`` before 0.4: still accepted,
            deprecated).
        static_friction: static Coulomb friction coefficient mu_s [-], >= dynamic_friction.
        poisson_ratio: Poisson's ratio nu [-], in [0, 0.5) (used by contact and shear-aware layers).
        shear_modulus: G [Pa] of the twist springs G J / l0, > 0; 0 (default): E / (2 (1 + nu)), the
            isotropic solid's. A stranded cable, a rope or a sheathed bundle twists far more easily than
            its E says: give (or fit) G itself.
        discretisation: ``"default"`` (ends lumped with half a segment of mass, clamp nodes
            with the half-segment bending stiffness 2EI/l0: second-order static convergence)
            or ``"paper"`` (Lv et al. 2017: m_i = M/n, k_b = EI/l0 at every bending node).
        section: cross-section shape: ``"round"`` (solid, diameter ``diameter``; the default),
            ``"tube"`` (outer diameter ``diameter``, inner diameter ``inner_diameter``) or
            ``"rectangle"`` (``width`` along the section's first axis d1, ``thickness`` along d2).
            For a rectangle the contact with bodies presses at the section's edge or face (docs/concepts/contact.md,
            "Flat sections") and ``diameter`` is the round envelope of the other contact layers (self-contact, other
            cables, edge wraps, the Bullet spheres; give the thickness).
        inner_diameter: inner diameter of a tube [m], in (0, diameter); 0 for other sections.
        width: rectangle width b [m] (along d1), > 0 for a rectangle; 0 for other sections.
        thickness: rectangle thickness h [m] (along d2), > 0 for a rectangle; 0 for other sections.
        twist: give the cable a material frame (a twist angle per segment, twist springs G J / l0,
            the held ends' roll as a boundary condition; see :mod:`bullet_dlo.core.kernels.twist`).
            Off by default: a round cable without it is today's model, result for result. A
            non-round section always has it (:attr:`twist_enabled`).
        drag_coefficient: quadratic (Morison-type) fluid drag coefficient C_d [-], in [0, 1000]; 0 (the
            default) switches the law off, result for result. Per segment of length l0 the surrounding
            fluid pushes with f = -1/2 rho_f C_d w l0 |v_n| v_n, v_n the segment's velocity normal to it
            (round and tube: the cross-flow component; rectangle: the component along the face normal
            d2), shared equally by its two nodes (:mod:`bullet_dlo.core.kernels.drag`).
        fluid_density: density rho_f of the surrounding fluid [kg/m^3], in [0, 1e4]; default air at
            20 degC, 1.204 (water: 998).
        drag_width: projected width w [m] of the drag law, >= 0; 0 (default): the section's own (the
            diameter of a round or tube section, the width of a rectangle). A strip modelled as a round
            cable moving in its weak plane (face first) gives its width here.
    """

    length: float
    diameter: float
    mass: float
    youngs_modulus: float
    n_masses: int = 10
    damping: float = 0.0
    damping_rate: float = 0.0
    internal_damping: float = 0.0
    dynamic_friction: float = 0.2
    static_friction: float = 0.3
    poisson_ratio: float = 0.3
    discretisation: str = "default"
    section: str = "round"
    inner_diameter: float = 0.0
    width: float = 0.0
    thickness: float = 0.0
    twist: bool = False
    shear_modulus: float = 0.0
    drag_coefficient: float = 0.0
    fluid_density: float = 1.204
    drag_width: float = 0.0

    def __post_init__(self) -> None:
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731 (frozen dataclass)
        set_("length", check_positive("length", self.length))
        set_("diameter", check_positive("diameter", self.diameter))
        set_("mass", check_positive("mass", self.mass))
        set_("youngs_modulus", check_positive("youngs_modulus", self.youngs_modulus))
        set_("n_masses", check_int("n_masses", self.n_masses, 2, 100_000))
        set_("damping", check_nonnegative("damping", self.damping))
        set_("damping_rate", check_in_range("damping_rate", self.damping_rate, 0.0, 1e4))
        set_("internal_damping", check_in_range("internal_damping", self.internal_damping, 0.0, 1.0))
        set_("dynamic_friction", check_nonnegative("dynamic_friction", self.dynamic_friction))
        set_("static_friction", check_nonnegative("static_friction", self.static_friction))
        check_friction_order(self.dynamic_friction, self.static_friction, hint=" (give static_friction too)")
        set_("poisson_ratio", check_in_range("poisson_ratio", self.poisson_ratio, 0.0, 0.5, open_hi=True))
        set_("shear_modulus", check_nonnegative("shear_modulus", self.shear_modulus))
        set_("drag_coefficient", check_in_range("drag_coefficient", self.drag_coefficient, 0.0, 1e3))
        set_("fluid_density", check_in_range("fluid_density", self.fluid_density, 0.0, 1e4))
        set_("drag_width", check_in_range("drag_width", self.drag_width, 0.0, 1e3))
        set_("discretisation", name_of("discretisation", self.discretisation, Discretisation))
        self._check_section(set_)

    def _check_section(self, set_: Any) -> None:
        """Validate the section fields: each shape takes its own dimensions and no others."""
        section = name_of("section", self.section, Section, lower=True)
        set_("section", section)
        if not isinstance(self.twist, (bool, np.bool_)):
            raise ParameterError(f"twist must be true or false, got {self.twist!r}")
        set_("twist", bool(self.twist))
        inner = check_nonnegative("inner_diameter", self.inner_diameter)
        if section == "rectangle":  # (a rectangle needs both: "> 0" in the message, not ">= 0")
            for name in ("width", "thickness"):
                if not 0.0 < check_positive(name, getattr(self, name)) <= SECTION_MAX:
                    raise ParameterError(f"{name} must be in (0, {SECTION_MAX}] [m] for section: rectangle, got "
                                         f"{getattr(self, name)!r}")
        width = check_nonnegative("width", self.width)
        thick = check_nonnegative("thickness", self.thickness)
        if section == "tube":
            if not 0.0 < inner < self.diameter:  # (0: a solid section is round; twist: true gives it a frame)
                raise ParameterError(f"inner_diameter must be in (0, diameter = {self.diameter}) [m] for section: tube "
                                     f"(a solid one is round, with twist: true for a frame), got {inner}")
        elif inner != 0.0:
            raise ParameterError(f"inner_diameter is for section: tube only (section is {section})")
        if section != "rectangle" and (width != 0.0 or thick != 0.0):
            raise ParameterError(f"width and thickness are for section: rectangle only (section is {section})")
        set_("inner_diameter", inner)
        set_("width", width)
        set_("thickness", thick)

    @property
    def friction(self) -> float:
        """Deprecated name of :attr:`dynamic_friction` [-] (read-only alias, kept for one release)."""
        import warnings

        warnings.warn("CableSpec.friction is deprecated; use CableSpec.dynamic_friction", DeprecationWarning,
                      stacklevel=2)
        return self.dynamic_friction

    # ----- derived continuum quantities -------------------------------------------------
    @property
    def area(self) -> float:
        """Cross-section area A [m^2]: pi d^2 / 4 (round), pi (d^2 - d_i^2) / 4 (tube), b h (rectangle)."""
        if self.section == "tube":
            return math.pi * (self.diameter**2 - self.inner_diameter**2) / 4.0
        if self.section == "rectangle":
            return self.width * self.thickness
        return math.pi * self.diameter**2 / 4.0

    @property
    def second_moments(self) -> tuple[float, float]:
        """Second moments of area (I1, I2) [m^4] about the section's axes d1 and d2.

        round: pi d^4 / 64 each; tube: pi (d^4 - d_i^4) / 64 each; rectangle (width b along d1,
        thickness h along d2): I1 = b h^3 / 12 (bending through the thickness), I2 = h b^3 / 12.
        """
        if self.section == "rectangle":
            b, h = self.width, self.thickness
            return b * h**3 / 12.0, h * b**3 / 12.0
        if self.section == "tube":
            i = math.pi * (self.diameter**4 - self.inner_diameter**4) / 64.0
            return i, i
        i = math.pi * self.diameter**4 / 64.0
        return i, i

    @property
    def second_moment(self) -> float:
        """Mean second moment of area I = (I1 + I2) / 2 [m^4]; pi d^4 / 64 for a round section."""
        if self.section == "round":
            return math.pi * self.diameter**4 / 64.0
        i1, i2 = self.second_moments
        return 0.5 * (i1 + i2)

    @property
    def polar_moment(self) -> float:
        """Polar moment of area J_p = I1 + I2 [m^4] (the section's rotational inertia per length is rho J_p)."""
        i1, i2 = self.second_moments
        return i1 + i2

    @property
    def torsion_constant(self) -> float:
        """Saint-Venant torsion constant J [m^4] (torque = G J dtheta/ds).

        round: pi d^4 / 32; tube: pi (d^4 - d_i^4) / 32; rectangle with long side a and short side c:
        a c^3 / 3 (1 - 0.63 c/a + 0.052 (c/a)^5) (Roark; within 0.5 % of the series solution for every
        aspect ratio; thin strips: a c^3 / 3 (1 - 0.63 c/a)).
        """
        if self.section == "rectangle":
            a, c = max(self.width, self.thickness), min(self.width, self.thickness)
            r = c / a
            return a * c**3 / 3.0 * (1.0 - 0.63 * r + 0.052 * r**5)
        return self.polar_moment

    @property
    def effective_shear_modulus(self) -> float:
        """G [Pa]: ``shear_modulus`` when given, else E / (2 (1 + nu))."""
        return self.shear_modulus or self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))

    @property
    def torsional_rigidity(self) -> float:
        """G J [N m^2]."""
        return self.effective_shear_modulus * self.torsion_constant

    @property
    def bending_rigidities(self) -> tuple[float, float]:
        """(E I1, E I2) [N m^2] about the section's axes d1, d2."""
        i1, i2 = self.second_moments
        return self.youngs_modulus * i1, self.youngs_modulus * i2

    @property
    def twist_enabled(self) -> bool:
        """Whether the model carries a material frame: ``twist`` asked for it or the section is not round."""
        return self.twist or self.section != "round"

    @property
    def linear_density(self) -> float:
        """Mass per length rho*A [kg/m]."""
        return self.mass / self.length

    @property
    def density(self) -> float:
        """Volumetric density rho [kg/m^3]."""
        return self.mass / (self.area * self.length)

    @property
    def bending_rigidity(self) -> float:
        """EI [N m^2]."""
        return self.youngs_modulus * self.second_moment

    @property
    def axial_rigidity(self) -> float:
        """EA [N]."""
        return self.youngs_modulus * self.area

    # ----- discretisation -----------------------------------------------------------------
    @property
    def rest_length(self) -> float:
        """Segment rest length l0 = L / (n - 1) [m]."""
        return self.length / (self.n_masses - 1)

    @property
    def k_stretch(self) -> float:
        """Linear spring constant k_s = E A / l0 [N/m]."""
        return self.axial_rigidity / self.rest_length

    @property
    def k_bend(self) -> float:
        """Bending spring constant k_b = E I / l0 at interior nodes [N m/rad^2]."""
        return self.bending_rigidity / self.rest_length

    @property
    def k_bend_clamp(self) -> float:
        """Bending spring constant at a clamped end node [N m/rad^2].

        The clamp node represents half a segment of cable, so its discrete curvature is the
        turning angle over l0/2: k = 2 E I / l0 (default). The paper uses E I / l0.
        """
        return self.k_bend * (2.0 if self.discretisation == "default" else 1.0)

    def point_masses(self) -> np.ndarray:
        """Point masses m_i [kg], shape (n,), summing to M.

        default: trapezoidal lumping (ends carry half a segment, M/(2(n-1))), which loads a
        cantilever with exactly the right moments; paper: uniform M/n.
        """
        n = self.n_masses
        if self.discretisation == "paper":
            return np.full(n, self.mass / n)
        m = np.full(n, self.mass / (n - 1))
        m[0] *= 0.5
        m[-1] *= 0.5
        return m

    def damping_coefficients(self) -> np.ndarray:
        """Per-mass viscous drag c_i [N s/m], shape (n,): F_i = -c_i v_i.

        c_i = gamma m_i with gamma = :attr:`mass_damping_rate`: every mass decays at the same
        rate; with uniform masses (``paper``) and no ``damping_rate``, c_i = k_d exactly as in Lv et al.
        """
        return self.mass_damping_rate * self.point_masses()

    @property
    def mass_damping_rate(self) -> float:
        """gamma = c_i / m_i [1/s], the same for every mass: ``damping_rate`` + k_d n / M."""
        return self.damping_rate + self.damping * self.n_masses / self.mass

    @property
    def k_twist(self) -> float:
        """Twist spring constant k_t = G J / l0 at interior nodes [N m/rad] (2 G J / l0 at a clamp)."""
        return self.torsional_rigidity / self.rest_length

    @property
    def segment_inertia(self) -> float:
        """Rotational inertia of one segment about its axis, rho J_p l0 [kg m^2]."""
        return self.density * self.polar_moment * self.rest_length

    @property
    def stretch_damping(self) -> float:
        """Kelvin-Voigt segment damper c_s = k_s tau = E A tau / l0 [N s/m]."""
        return self.k_stretch * self.internal_damping

    @property
    def projected_width(self) -> float:
        """Width w [m] the drag law sees: ``drag_width``, else the diameter (round, tube) or width (rectangle)."""
        if self.drag_width > 0.0:
            return self.drag_width
        return self.width if self.section == "rectangle" else self.diameter

    @property
    def drag_constant(self) -> float:
        """Quadratic drag constant of one segment, k = 1/2 rho_f C_d w l0 [kg/m] (|f| = k |v_n|^2)."""
        return 0.5 * self.fluid_density * self.drag_coefficient * self.projected_width * self.rest_length

    # ----- convenience --------------------------------------------------------------------
    def with_(self, **changes: Any) -> "CableSpec":
        """Return a copy with some fields changed (validated again; deprecated names are taken with a warning)."""
        return replace(self, **renamed_keys(changes, RENAMED, stacklevel=3))

    def to_dict(self) -> dict[str, Any]:
        """Plain dict of the fields (for JSON/YAML/HDF5 attributes).

        The section fields, ``twist`` and the drag law's fields appear only when they differ from their
        defaults, so an old spec's dict (and every digest of it) is unchanged.
        """
        data = asdict(self)
        for key, default in _SECTION_DEFAULTS.items():
            if data[key] == default:
                del data[key]
        return data

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "CableSpec":
        """Build from a mapping; unknown keys raise ParameterError naming them.

        A ``preset`` key starts from a named preset and the other keys override it. Deprecated names
        (:data:`RENAMED`: ``friction``) are taken with a DeprecationWarning naming the new one.
        """
        data = renamed_keys(data, RENAMED)
        names = {f.name for f in fields(cls)}
        base: dict[str, Any] = {}
        if "preset" in data:
            base = preset(str(data.pop("preset"))).to_dict()
        unknown = sorted(set(data) - names)
        if unknown:
            raise ParameterError(
                f"unknown cable parameter(s) {', '.join(unknown)}; allowed: preset, {', '.join(sorted(names))}"
            )
        base.update(data)
        missing = [k for k in ("length", "diameter", "mass", "youngs_modulus") if k not in base]
        if missing:
            raise ParameterError(f"cable parameter(s) {', '.join(missing)} missing (or give preset: lv2017)")
        return cls(**base)

    @classmethod
    def lv2017(cls, **overrides: Any) -> "CableSpec":
        """Lv et al. 2017, Table 2: L 0.3 m, d 4 mm, M 30 g, E 126 MPa, nu 0.3, mu 0.2/0.3."""
        return preset("lv2017").with_(**overrides) if overrides else preset("lv2017")


_SECTION_DEFAULTS: dict[str, Any] = {"section": "round", "inner_diameter": 0.0, "width": 0.0, "thickness": 0.0,
                                      "twist": False, "shear_modulus": 0.0,
                                      "drag_coefficient": 0.0, "fluid_density": 1.204, "drag_width": 0.0}

_PRESETS: dict[str, dict[str, Any]] = {
    "lv2017": dict(
        length=0.3, diameter=0.004, mass=0.03, youngs_modulus=126.0e6, n_masses=10,
        damping=0.0, damping_rate=0.0, internal_damping=0.0, dynamic_friction=0.2, static_friction=0.3, poisson_ratio=0.3,
    ),
}


def preset(name: str) -> CableSpec:
    """A named cable preset (``lv2017``); unknown names raise ParameterError listing the known ones."""
    key = str(name).lower()
    if key not in _PRESETS:
        raise ParameterError(f"unknown cable preset {name!r}; known presets: {', '.join(sorted(_PRESETS))}")
    return CableSpec(**_PRESETS[key])


def preset_names() -> list[str]:
    """Names accepted by :func:`preset`."""
    return sorted(_PRESETS)


_dataclass_init = CableSpec.__init__


def _init(self: CableSpec, *args: Any, friction: Any = None, **kwargs: Any) -> None:
    """The dataclass constructor, also taking the deprecated keyword ``friction`` (now ``dynamic_friction``)."""
    if friction is not None:
        kwargs = renamed_keys({**kwargs, "friction": friction}, RENAMED, stacklevel=3)
    _dataclass_init(self, *args, **kwargs)


_init.__doc__ = _dataclass_init.__doc__
_init.__signature__ = __import__("inspect").signature(_dataclass_init)  # type: ignore[attr-defined]
CableSpec.__init__ = _init  # type: ignore[method-assign]

__all__ = ["CableSpec", "ParameterError", "preset", "preset_names", "DISCRETISATIONS", "SECTIONS", "RENAMED"]
