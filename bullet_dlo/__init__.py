"""bullet_dlo: mass-spring-damper cables with stable integrators (PyBullet-free numerical core).

Typical use::

    from bullet_dlo import CableSpec, CableModel, Move, simulate
    spec = CableSpec.lv2017(n_masses=20, damping=0.01)
    model = CableModel.straight(spec, ends=("clamped", "clamped"),
                                motion=[Move("last", (0, 0, 0.005), start=0.5, duration=0.1)])
    result = simulate(model, "implicit_euler", dt=1e-3, duration=2.0)
"""
from bullet_dlo._numba_cache import ensure_fresh_cache

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

__version__ = "0.2.0"

_aliases.install()


def __getattr__(name: str):
    """``bullet_dlo.Scene`` lives in the config layer (it reads YAML); import it on first use."""
    if name == "Scene":
        from bullet_dlo.config.scene import Scene

        return Scene
    raise AttributeError(f"module 'bullet_dlo' has no attribute {name!r}")


__all__ = [
    "CableSpec", "ParameterError", "preset", "preset_names", "CableModel", "CableState", "EndHolder", "Move",
    "INTEGRATORS", "Integrator", "NewtonOptions", "get_integrator", "simulate", "SimulationResult",
    "DetectorOptions", "critical_dt", "damping_bounds", "measured_critical_dt", "stiffness_spectrum",
    "solve_static", "Scene", "__version__",
]
