"""The benchmark's rod in PyElastica (Cosserat rod, explicit PositionVerlet stepping).

Model: ``CosseratRod.straight_rod`` with n - 1 elements from the origin along +x (normal +z),
radius d / 2, density M / (A L), Young's modulus E and shear modulus E / (2 (1 + 0.3));
``OneEndFixedBC`` on node 0 and element 0 (position and directors), gravity on the nodal
masses. Damping is PyElastica's analytical uniform damping (v and omega times exp(-c dt) each
step, like ``AnalyticalLinearDamper``), re-implemented so that it can change during a run.

PyElastica is explicit and needs small steps: in our tests the largest stable step was about
1.5 r / sqrt(E / rho), set by the rotation of the short, thick elements rather than by n
(5e-7 s stable at n = 10 and 20, 7e-7 s diverged at n = 10, for L = 0.3 m, d = 4 mm, E = 263 GPa).
"""
from __future__ import annotations

import math

import elastica as ea
import numpy as np

from bullet_dlo.bench.peers import POISSON
from bullet_dlo.core.spec import CableSpec


class _Simulator(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping):
    pass


class _SharedGravity(ea.GravityForces):
    """``GravityForces`` reading a shared 3-vector [m/s^2] that may change during the run."""

    def __init__(self, acc_gravity: np.ndarray) -> None:
        super().__init__(acc_gravity=acc_gravity)
        self.acc_gravity = acc_gravity  # share, do not copy


class _SharedDamper(ea.DamperBase):
    """Uniform velocity damping: v and omega times ``factor[0]`` each step (a shared 1-array)."""

    def __init__(self, factor: np.ndarray, **kwargs: object) -> None:
        super().__init__(**kwargs)
        self.factor = factor

    def dampen_rates(self, system: ea.CosseratRod, time: np.float64) -> None:
        f = self.factor[0]
        if f != 1.0:
            system.velocity_collection *= f
            system.omega_collection *= f


def _build(spec: CableSpec) -> tuple[_Simulator, ea.CosseratRod, np.ndarray, np.ndarray]:
    """(simulator, rod, shared gravity (3,) [m/s^2], shared damping factor (1,)) for ``spec``, finalized."""
    sim = _Simulator()
    rod = ea.CosseratRod.straight_rod(
        spec.n_masses - 1, np.zeros(3), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]),
        spec.length, spec.diameter / 2.0, spec.density,
        youngs_modulus=spec.youngs_modulus, shear_modulus=spec.youngs_modulus / (2.0 * (1.0 + POISSON)),
    )
    sim.append(rod)
    sim.constrain(rod).using(ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,))
    gravity, factor = np.zeros(3), np.ones(1)
    sim.add_forcing_to(rod).using(_SharedGravity, acc_gravity=gravity)
    sim.dampen(rod).using(_SharedDamper, factor=factor)
    sim.finalize()
    return sim, rod, gravity, factor


_WARM = False


def _warm_up() -> None:
    """Step a tiny throwaway rod so that Numba's compilation is not timed in the first run."""
    global _WARM
    if not _WARM:
        sim = _build(CableSpec(length=1.0, diameter=0.02, mass=0.3, youngs_modulus=1e6, n_masses=5))[0]
        stepper = ea.PositionVerlet()
        stepper.step(sim, stepper.step(sim, np.float64(0.0), 1e-6), 1e-6)
        _WARM = True


class PyElasticaRod:
    """:class:`bullet_dlo.bench.peers.PeerRod` for PyElastica."""

    name = "pyelastica"

    def __init__(self, spec: CableSpec, dt: float) -> None:
        _warm_up()
        self.dt = dt
        self._sim, self._rod, self._gravity, self._factor = _build(spec)
        self._stepper = ea.PositionVerlet()
        self._t = np.float64(0.0)
        self.warnings: list[str] = []
        self.note = (f"PositionVerlet; straight_rod n_elements={spec.n_masses - 1}, radius=d/2, "
                     f"density=M/(A L)={spec.density:.6g} kg/m^3, shear_modulus=E/(2(1+{POISSON})), "
                     "OneEndFixedBC on node 0 + element 0")

    def set_gravity(self, g: float) -> None:
        self._gravity[:] = (0.0, 0.0, -g)

    def set_damping(self, rate: float) -> None:
        self._factor[0] = math.exp(-rate * self.dt)

    def step(self) -> None:
        self._t = self._stepper.step(self._sim, self._t, self.dt)

    def refresh(self) -> None:
        pass  # positions are the state

    def zero_velocities(self) -> None:
        self._rod.velocity_collection[:] = 0.0
        self._rod.omega_collection[:] = 0.0

    def positions(self) -> np.ndarray:
        return self._rod.position_collection

    def tip_z(self) -> float:
        return float(self._rod.position_collection[2, -1])

    def diverged(self) -> bool:
        return False  # non-finite values and strain are checked by the caller
