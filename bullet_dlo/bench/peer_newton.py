"""The benchmark's rod in Newton (>= 1.8, on Warp): ``ModelBuilder.add_rod`` with ``SolverVBD``, truly clamped.

Newton's rod (``newton.Rod`` + ``ModelBuilder.add_rod``) is a chain of capsule bodies, one per
segment, joined at the nodes by ``ROD`` joints with stretch, shear, bend and twist springs. Rod
joints are integrated only by ``SolverVBD`` (Vertex / Augmented Vertex Block Descent: an implicit
step solved by a fixed number of block Gauss-Seidel sweeps over the bodies); ``SolverXPBD`` and
``SolverSemiImplicit`` refuse them, and Newton's cable examples and Isaac Lab's cable guide use
VBD. This is Newton's best public set-up for the cantilever, as its own examples build one
(``examples/vbd/example_cable_bend_stiffness.py``: a kinematic root body, 10-20 VBD iterations):

* **stiffness from the material**: ``newton.Rod(points, radius=d/2, youngs_modulus=E,
  poissons_ratio=0.3)``; ``add_rod`` then gives each joint Newton's own discretisation
  ``R / L_dual`` (R = EA, kGA with k = 0.9, EI, GJ; L_dual the mean length of the two adjacent
  segments): bend EI / l inside the rod. Passing ``bend_stiffness`` directly takes N m / rad
  *per joint* (EI / l, not EI), and ``stretch_stiffness`` defaults to 1e5 N/m with shear
  following it, a compliance that adds to the bending deflection (below);
* **clamp**: the first body is a stub from x = -s to 0 (s = :data:`STUB` x the segment length)
  with zero mass and inertia, which Newton's VBD holds kinematic (its examples' clamp); the n - 1
  rod segments span [0, L]. The joint at x = 0 gets bend EI / ((s + l) / 2) ~ 2 EI / l, the half
  dual length of a clamped end, so S1 converges at second order in n. A whole rod segment as the
  kinematic root (the examples' choice) clamps the beam one element in;
* masses: M / (n - 1) per segment body at its centre (the distributed weight), inertia of a solid
  cylinder of that segment (capsule caps left out);
* damping: the same uniform velocity damping rate c as ours, as PyElastica's analytical damper
  does it: body velocities times exp(-c dt) before each step (one Warp kernel launch per step);
  the joints' own (Rayleigh-like) damping stays 0;
* stretch and shear stiffness: Newton's material values times ``shear_scale`` (1: the material).
  VBD's fixed sweep count leaves a bias at equilibrium: each step starts from the inertial
  prediction (the rod dropped by g dt^2), and a few sweeps do not bring a stiff rod back. The
  bias grows like (stretch or shear stiffness) dt^2 / (segment mass x iterations): at n = 10
  with the material values the rod creeps without bound at 1 ms (+12,400 % after 1 s) and
  still creeps at 0.1 ms (+417 % after 0.066 s, +762 % after 1 s); +21 % at 2e-5 s. Softening stretch and shear (``shear_scale`` < 1) shrinks the bias and adds a
  physical shear deflection of about 1.3e-4 / shear_scale of the bending one (Timoshenko, this
  rod), +0.4 % at 0.03; a user tuning Newton would make that trade, so it is swept. With it
  Newton reaches 1 % on S1 at n = 20 and 2e-5 s (+0.25 %). Below that step Warp's float32
  round-off makes the errors wander (n = 5: +6.9 % at 2e-5 s, +9.4 % at 1e-5 s).

Stepping: :meth:`NewtonRod.advance` calls the damping kernel and ``solver.step`` per step (Warp
on the CPU runs each kernel on the calling thread; there is no CUDA graph without a GPU); the
free mode writes the tip height into a Warp array by one kernel launch per step and reads it
once per chunk. Device: ``"cpu"`` (a GPU, when present, is not used here, so that the CPU time
of the thread is the whole cost).
"""
from __future__ import annotations

import logging
import math

import numpy as np
import warp as wp

from bullet_dlo.bench.peers import POISSON
from bullet_dlo.core.spec import CableSpec

wp.config.log_level = logging.WARNING  # no banner nor one line per compiled module (the no-GPU warning stays)

import newton  # noqa: E402  (after Warp's log level)

STUB = 1e-3
"""Length of the kinematic stub body behind x = 0, as a fraction of the segment length [-]."""

ITERATIONS = 10
"""VBD iterations per step: SolverVBD's default and its cable examples' (10-20)."""

DEVICE = "cpu"


@wp.kernel
def _scale_velocities(qd: wp.array(dtype=wp.spatial_vector), factor: float):
    i = wp.tid()
    qd[i] = qd[i] * factor


@wp.kernel
def _record_tip_z(q: wp.array(dtype=wp.transform), body: int, half: float, out: wp.array(dtype=float), i: int):
    t = q[body]
    end = wp.transform_point(t, wp.vec3(0.0, 0.0, half))
    out[i] = end[2]


def _node_positions(body_q: np.ndarray, half: float) -> np.ndarray:
    """Segment end points (3, n) [m]: the start of the first rod body (x = 0), then each body's end."""
    q = body_q.astype(np.float64)
    p, v, w = q[:, :3], q[:, 3:6], q[:, 6:7]
    ez = np.zeros_like(p)
    ez[:, 2] = half
    t = 2.0 * np.cross(v, ez)
    axis = ez + w * t + np.cross(v, t)  # rotate (0, 0, half) by each quaternion (x, y, z, w)
    ends = p + axis
    return np.concatenate([(p[1] - axis[1])[None, :], ends[1:]], axis=0).T


def _build(spec: CableSpec, iterations: int, shear_scale: float):
    n, seg = spec.n_masses, spec.rest_length
    points = np.zeros((n + 1, 3))
    points[0, 0] = -STUB * seg
    points[1:, 0] = np.arange(n) * seg
    rod = newton.Rod(points, radius=spec.diameter / 2.0, youngs_modulus=spec.youngs_modulus, poissons_ratio=POISSON)
    builder = newton.ModelBuilder(gravity=(0.0, 0.0, 0.0))
    stretch = shear = None
    if shear_scale != 1.0:
        area = math.pi * spec.diameter ** 2 / 4.0
        stretch = shear_scale * spec.youngs_modulus * area / seg
        shear = shear_scale * 0.9 * spec.youngs_modulus / (2.0 * (1.0 + POISSON)) * area / seg
    bodies, _ = builder.add_rod(rod=rod, stretch_stiffness=stretch, shear_stiffness=shear)
    m, r = spec.mass / (n - 1), spec.diameter / 2.0
    it, ia = m * (3.0 * r * r + seg * seg) / 12.0, m * r * r / 2.0
    for k, body in enumerate(bodies):
        if k == 0:  # the stub: zero mass and inertia, held kinematic by VBD
            builder.body_mass[body] = 0.0
            builder.body_inv_mass[body] = 0.0
            builder.body_inertia[body] = wp.mat33(0.0)
            builder.body_inv_inertia[body] = wp.mat33(0.0)
        else:
            builder.body_mass[body] = m
            builder.body_inv_mass[body] = 1.0 / m
            builder.body_inertia[body] = wp.mat33(it, 0.0, 0.0, 0.0, it, 0.0, 0.0, 0.0, ia)
            builder.body_inv_inertia[body] = wp.mat33(1.0 / it, 0.0, 0.0, 0.0, 1.0 / it, 0.0, 0.0, 0.0, 1.0 / ia)
    builder.color()
    model = builder.finalize(device=DEVICE)
    solver = newton.solvers.SolverVBD(model, iterations=iterations)
    return model, solver, list(bodies)


_WARM = False


def _warm_up() -> None:
    """Step a tiny rod once so that loading Warp's compiled kernels is not timed in the first run."""
    global _WARM
    if not _WARM:
        rod = NewtonRod(CableSpec(length=1.0, diameter=0.02, mass=0.3, youngs_modulus=1e6, n_masses=5), 1e-3,
                        warm=False)
        rod.set_damping(1.0)
        rod.advance(2, np.empty(2))
        _WARM = True


class NewtonRod:
    """:class:`bullet_dlo.bench.peers.PeerRod` for Newton (``add_rod`` + ``SolverVBD`` on the CPU)."""

    name = "newton"

    def __init__(self, spec: CableSpec, dt: float, iterations: int = ITERATIONS, shear_scale: float = 1.0,
                 warm: bool = True) -> None:
        if iterations < 1:
            raise ValueError(f"VBD iterations must be >= 1, got {iterations}")
        if not 0.0 < shear_scale <= 1.0:
            raise ValueError(f"shear_scale must be in (0, 1], got {shear_scale}")
        if warm:
            _warm_up()
        self.dt = dt
        self.model, self.solver, self._bodies = _build(spec, iterations, shear_scale)
        self._s0, self._s1 = self.model.state(), self.model.state()
        self._control = self.model.control()
        self._half = 0.5 * spec.rest_length
        self._factor = 1.0
        self._trace = wp.zeros(100, dtype=float, device=DEVICE)
        self.warnings: list[str] = []
        self.integrator = f"VBD{iterations}" + ("" if shear_scale == 1.0 else f" shear x{shear_scale:g}")
        self.note = (f"SolverVBD iterations={iterations}; add_rod of newton.Rod(radius=d/2, youngs_modulus=E, "
                     f"poissons_ratio={POISSON}), stretch and shear x {shear_scale:g} of the material's; a kinematic "
                     f"stub body of {STUB:g} l behind x = 0 (clamp at x = 0) + {spec.n_masses - 1} segment bodies of "
                     "M/(n-1), solid-cylinder inertia; velocity damping exp(-c dt) per step; device cpu, float32")

    def set_gravity(self, g: float) -> None:
        self.model.set_gravity((0.0, 0.0, -g))
        self.solver.notify_model_changed(newton.ModelFlags.MODEL_PROPERTIES)

    def set_damping(self, rate: float) -> None:
        self._factor = math.exp(-rate * self.dt)

    def advance(self, k: int, trace: np.ndarray | None = None) -> None:
        """k steps; with ``trace`` (k,), the tip height [m] after each step (written on the device, read once)."""
        solver, control, dt, nb = self.solver, self._control, self.dt, self.model.body_count
        if trace is not None and self._trace.shape[0] < k:
            self._trace = wp.zeros(k, dtype=float, device=DEVICE)
        s0, s1 = self._s0, self._s1
        for i in range(k):
            if self._factor != 1.0:
                wp.launch(_scale_velocities, dim=nb, inputs=[s0.body_qd, self._factor], device=DEVICE)
            solver.step(s0, s1, control, None, dt)
            s0, s1 = s1, s0
            if trace is not None:
                wp.launch(_record_tip_z, dim=1, inputs=[s0.body_q, self._bodies[-1], self._half, self._trace, i],
                          device=DEVICE)
        self._s0, self._s1 = s0, s1
        if trace is not None:
            trace[:] = self._trace.numpy()[:k]

    def refresh(self) -> None:
        pass  # body poses are the state

    def zero_velocities(self) -> None:
        self._s0.body_qd.zero_()

    def positions(self) -> np.ndarray:
        """The n rod nodes (3, n) [m] (x = 0 and each segment's end), the stub left out."""
        return _node_positions(self._s0.body_q.numpy(), self._half)

    def tip_z(self) -> float:
        return float(self.positions()[2, -1])

    def diverged(self) -> bool:
        return not bool(np.isfinite(self._s0.body_qd.numpy()).all())
