"""The numerical core: cable spec, model, forces, integrators, stability, statics, engine.

Plain NumPy + Numba; never imports PyBullet, YAML, HDF5, plotting or video libraries (a
test holds it to that). Numba kernels live in :mod:`bullet_dlo.core.kernels`.
"""
from bullet_dlo.core.boundary import EndHolder, Move
from bullet_dlo.core.engine import DetectorOptions, SimulationResult, simulate
from bullet_dlo.core.integrators import INTEGRATORS, Integrator, NewtonOptions, get_integrator
from bullet_dlo.core.model import CableControl, CableModel, CableState
from bullet_dlo.core.spec import CableSpec, preset, preset_names
from bullet_dlo.core.stability import critical_dt, damping_bounds, measured_critical_dt, stiffness_spectrum
from bullet_dlo.core.statics import solve_static
from bullet_dlo.core.validate import ParameterError

__all__ = [
    "CableSpec", "ParameterError", "preset", "preset_names", "CableModel", "CableState", "CableControl", "EndHolder",
    "Move",
    "INTEGRATORS", "Integrator", "NewtonOptions", "get_integrator", "simulate", "SimulationResult",
    "DetectorOptions", "critical_dt", "damping_bounds", "measured_critical_dt", "stiffness_spectrum",
    "solve_static",
]
