"""The benchmark's rod in PyElastica (Cosserat rod, explicit PositionVerlet stepping), truly clamped.

PyElastica's best public set-up for the cantilever, as its documentation and examples build one:

* ``CosseratRod.straight_rod`` along +x (normal +z) with n elements: a held stub element from
  x = -s to 0 (s = :data:`STUB` x the segment length, given through ``position=``) and the
  n - 1 elements of the rod on [0, L]; radius d / 2, density M / (A L), Young's modulus E and
  shear modulus E / (2 (1 + 0.3));
* **clamp**: PyElastica's own ``FixedConstraint`` on nodes 0 and 1 (the stub's ends) and the
  stub's directors (element 0): the rod is clamped at x = 0 with its tangent along +x, and the
  bending couple at x = 0 acts over the half Voronoi length of a clamped end. The tip deflection
  converges at second order in n (+0.30 % at n = 20). ``OneEndFixedBC`` on node 0 and the
  directors of the first *rod* element (the old adapter) holds that whole element straight, so
  the beam is clamped one element in: -2/n of the deflection;
* gravity on the nodal masses (the stub's share sits on the two held nodes, so the free nodes
  carry the same lumped masses as ours);
* damping: PyElastica's analytical uniform damping (v and omega times exp(-c dt) each step, as
  ``AnalyticalLinearDamper`` does), re-implemented so that it can change during a run: the same
  velocity damping rate c as ours.

Integrator: ``PositionVerlet``, the one PyElastica's examples use. It is explicit and needs small
steps: the largest stable step is about 1.5 r / sqrt(E / rho), set by the rotation of the short,
thick elements rather than by n (5e-7 s stable at n = 10, 20 and 40, 7e-7 s diverges, for
L = 0.3 m, d = 4 mm, E = 263 GPa). ``PEFRL`` (4th order, 4 force evaluations) was stable at
1e-6 s but not 1.5e-6 s, and cost 1.6x more per simulated second, so it is not swept.
Stepping is PyElastica's own ``stepper.step`` in a Python loop (what ``elastica.integrate``
does); the free mode reads the tip height once per step.
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


STUB = 1e-3
"""Length of the held stub element behind x = 0, as a fraction of the segment length [-]."""


def _build(spec: CableSpec) -> tuple[_Simulator, ea.CosseratRod, np.ndarray, np.ndarray]:
    """(simulator, rod, shared gravity (3,) [m/s^2], shared damping factor (1,)) for ``spec``, finalized."""
    sim = _Simulator()
    n, seg = spec.n_masses, spec.rest_length
    stub = STUB * seg
    position = np.zeros((3, n + 1))
    position[0, 0] = -stub
    position[0, 1:] = np.arange(n) * seg
    rod = ea.CosseratRod.straight_rod(
        n, np.array([-stub, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]),
        spec.length + stub, spec.diameter / 2.0, spec.density,
        youngs_modulus=spec.youngs_modulus, shear_modulus=spec.youngs_modulus / (2.0 * (1.0 + POISSON)),
        position=position,
    )
    sim.append(rod)
    sim.constrain(rod).using(ea.FixedConstraint, constrained_position_idx=(0, 1), constrained_director_idx=(0,))
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
        self.integrator = "PositionVerlet"
        self.note = (f"PositionVerlet; straight_rod n_elements={spec.n_masses} (a stub of {STUB:g} l behind x = 0 "
                     f"+ {spec.n_masses - 1}), radius=d/2, density=M/(A L)={spec.density:.6g} kg/m^3, "
                     f"shear_modulus=E/(2(1+{POISSON})), FixedConstraint on nodes 0, 1 + the stub's directors")

    def set_gravity(self, g: float) -> None:
        self._gravity[:] = (0.0, 0.0, -g)

    def set_damping(self, rate: float) -> None:
        self._factor[0] = math.exp(-rate * self.dt)

    def advance(self, k: int, trace: np.ndarray | None = None) -> None:
        """k steps; with ``trace`` (k,), the tip height [m] after each step."""
        step, sim, dt, t = self._stepper.step, self._sim, self.dt, self._t
        if trace is None:
            for _ in range(k):
                t = step(sim, t, dt)
        else:
            z = self._rod.position_collection[2]
            for i in range(k):
                t = step(sim, t, dt)
                trace[i] = z[-1]
        self._t = t

    def refresh(self) -> None:
        pass  # positions are the state

    def zero_velocities(self) -> None:
        self._rod.velocity_collection[:] = 0.0
        self._rod.omega_collection[:] = 0.0

    def positions(self) -> np.ndarray:
        """The n rod nodes (3, n) [m], the stub's first node left out."""
        return self._rod.position_collection[:, 1:]

    def tip_z(self) -> float:
        return float(self._rod.position_collection[2, -1])

    def diverged(self) -> bool:
        return False  # non-finite values and strain are checked by the caller
