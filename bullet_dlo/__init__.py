"""bullet_dlo: mass-spring-damper cables with stable integrators (PyBullet-free numerical core).

Typical use::

    from bullet_dlo import CableSpec, CableModel, Move, simulate
    spec = CableSpec.lv2017(n_masses=20, damping=0.01)
    model = CableModel.straight(spec, ends=("clamped", "clamped"),
                                motion=[Move("last", (0, 0, 0.005), start=0.5, duration=0.1)])
    result = simulate(model, "implicit_euler", dt=1e-3, duration=2.0)
"""
from ._numba_cache import ensure_fresh_cache

ensure_fresh_cache()  # before any kernel loads from the on-disk cache

from .boundary import EndHolder, Move  # noqa: E402
from .integrators import INTEGRATORS, Integrator, NewtonOptions, get_integrator
from .model import CableModel, CableState
from .params import CableSpec, ParameterError, preset, preset_names
from .scene import Scene
from .simulate import DetectorOptions, SimulationResult, simulate
from .stability import critical_dt, damping_bounds, measured_critical_dt, stability_report, stiffness_spectrum
from .statics import solve_static

__version__ = "0.1.0"

__all__ = [
    "CableSpec", "ParameterError", "preset", "preset_names", "CableModel", "CableState", "EndHolder", "Move",
    "INTEGRATORS", "Integrator", "NewtonOptions", "get_integrator", "simulate", "SimulationResult",
    "DetectorOptions", "critical_dt", "damping_bounds", "measured_critical_dt", "stability_report",
    "stiffness_spectrum", "solve_static", "Scene", "__version__",
]
