"""``resolve`` on target ``forces`` judges the end moments too (issue 22: a wrist sensor reads both).

Before, only the end forces were compared: a scene whose clamps are loaded by moments (a clamp rolled about the
cable, torsion) got the error estimate of its forces, zero for a pure torsion, and the fewest masses tried.
"""
from __future__ import annotations

import math

import numpy as np

from bullet_dlo.analysis.resolve import N_MASSES, ResolveProblem, resolve_masses
from bullet_dlo.core.engine import SimulationResult
from bullet_dlo.core.model import CableState
from bullet_dlo.core.spec import CableSpec

M0 = 0.02  # the clamp's moment [N m] the discretisation converges to
C = 3.0  # its second-order error: M(n) = M0 (1 + C / n^2)


def _run(with_moments: bool):
    """A stand-in scene: the forces the same at every n (the cable's weight at each end), the last clamp's
    moment about the cable M(n) (a second-order discretisation)."""

    def run(cable: CableSpec, integrator: str, dt: float, duration: float) -> SimulationResult:
        t = np.linspace(0.0, duration, 201)
        n = cable.n_masses
        forces = np.zeros((t.size, 2, 3))
        forces[:, :, 2] = -0.5 * cable.mass * 9.81
        moments = np.zeros((t.size, 2, 3))
        moments[:, 1, 0] = M0 * (1.0 + C / n**2)
        x = np.zeros((t.size, n, 3))
        x[:, :, 0] = np.linspace(0.0, cable.length, n)
        return SimulationResult(integrator, dt, True, None, None, t.size, 0.0, t, x, np.zeros_like(x), forces,
                                np.zeros(t.size), CableState(x[-1], np.zeros((n, 3))),
                                end_moment_history=moments if with_moments else None)

    return run


def test_resolve_on_forces_refines_n_until_the_moments_converge():
    tol = 0.02
    cable = CableSpec.lv2017(n_masses=5)

    def estimate(n: int) -> float:  # resolve's estimate from the closed form: 4/3 of the difference to 2n - 1
        fine = M0 * (1.0 + C / (2 * n - 1) ** 2)
        return 4.0 / 3.0 * abs(M0 * (1.0 + C / n**2) - fine) / math.sqrt(2.0) / fine  # (RMS over the two ends)

    expected = next(n for n in N_MASSES if estimate(n) <= 0.5 * tol)
    assert expected == 20  # (the law is chosen so that the answer is inside the candidates)
    n, _ = resolve_masses(ResolveProblem(cable, 0.5, _run(True)), tol, "forces", rollout=0.5)
    assert n == expected
    # without recorded moments (an engine that does not record them) the forces alone decide, as before
    n, _ = resolve_masses(ResolveProblem(cable, 0.5, _run(False)), tol, "forces", rollout=0.5)
    assert n == N_MASSES[0]
