"""bullet_dlo: mass-spring-damper cables with stable integrators (PyBullet-free numerical core).

Typical use::

    from bullet_dlo import CableSpec, CableModel, Move, simulate
    spec = CableSpec.lv2017(n_masses=20, damping=0.01)
    model = CableModel.straight(spec, ends=("clamped", "clamped"),
                                motion=[Move("last", (0, 0, 0.005), start=0.5, duration=0.1)])
    result = simulate(model, "implicit_euler", dt=1e-3, duration=2.0)
"""
import importlib

from bullet_dlo import _interrupt

if _interrupt.is_command_line():  # before the heavy imports: a Ctrl-C while they load is one line
    _interrupt.quiet_interrupt()

from bullet_dlo._numba_cache import ensure_fresh_cache  # noqa: E402

ensure_fresh_cache()  # before any kernel loads from the on-disk cache

from bullet_dlo import _aliases  # noqa: E402
from bullet_dlo.core import (  # noqa: E402
    INTEGRATORS,
    CableModel,
    CableSpec,
    CableState,
    DetectorOptions,
    EndHolder,
    Integrator,
    Move,
    NewtonOptions,
    ParameterError,
    SimulationResult,
    critical_dt,
    damping_bounds,
    get_integrator,
    measured_critical_dt,
    preset,
    preset_names,
    simulate,
    solve_static,
    stiffness_spectrum,
)

__version__ = "0.3.0"

_aliases.install()

from bullet_dlo._gym_registration import register_when_gymnasium_loads  # noqa: E402

register_when_gymnasium_loads()  # the bullet_dlo/ Gymnasium ids, once Gymnasium is imported (never imports it)


def __getattr__(name: str):
    """Names loaded on first use: ``Scene`` (the config layer reads YAML) and the 0.1 module paths.

    ``import bullet_dlo; bullet_dlo.stability.critical_dt(...)`` worked in 0.1 and keeps working
    through the alias (with its DeprecationWarning); see :mod:`bullet_dlo._aliases`.
    """
    if name == "Scene":
        from bullet_dlo.config.scene import Scene

        return Scene
    if f"{__name__}.{name}" in _aliases.OLD_TO_NEW:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "CableSpec", "ParameterError", "preset", "preset_names", "CableModel", "CableState", "EndHolder", "Move",
    "INTEGRATORS", "Integrator", "NewtonOptions", "get_integrator", "simulate", "SimulationResult",
    "DetectorOptions", "critical_dt", "damping_bounds", "measured_critical_dt", "stiffness_spectrum",
    "solve_static", "Scene", "__version__",
]
