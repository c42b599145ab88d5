"""Static equilibrium by damped Newton (Levenberg-Marquardt) on the banded stiffness.

Solves F_elastic(x) + m g + f_ext = 0 on the free nodes with the held ends at their start
poses. A cable with a material frame (issue 22) is solved with its twist condensed: at every iterate the
reference frames are transported to the positions and the twist angles put in equilibrium with them
(:func:`~bullet_dlo.core.kernels.twist.twist_solve`), so the forces are the gradient of the energy there
and the potential that Newton's steps must lower is the energy minimised over the twist. Used to start
runs from a settled cable (the study's "settle" phase without simulating it) and to measure
discretisation error against beam theory without any integrator in the loop.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_banded

from bullet_dlo.core.kernels.banded import HALF, assemble_system, band_solve
from bullet_dlo.core.kernels.forces import force_jacobian, internal_energy, total_forces
from bullet_dlo.core.kernels.twist import TwistState, theta_gradient, twist_ready, twist_solve, update_frames
from bullet_dlo.core.model import CableModel, CableState, KernelArrays, ModelArrays


@dataclass
class StaticResult:
    """Equilibrium positions x [m] (n, 3), residual force [N] (max over free nodes), iterations, and the
    material frame's state in equilibrium with them (``twist``; None for a cable without one)."""

    x: np.ndarray
    residual: float
    iterations: int
    converged: bool
    twist: TwistState | None = None

    def state(self) -> CableState:
        """The equilibrium at rest, t = 0, with its twist state (twist angles and reference frames as solved,
        so a twist of more than half a turn between the clamps keeps its turns)."""
        return CableState(self.x.copy(), np.zeros_like(self.x), 0.0, None if self.twist is None else self.twist.copy())


def _potential(a: ModelArrays, x: np.ndarray, dirs: np.ndarray) -> float:
    """Elastic + gravitational + external-force potential [J] at positions x [m], (n, 3)."""
    e = internal_energy(a, x, dirs)
    return float(e - np.sum(a.mass[:, None] * a.gravity[None, :] * x) - np.sum(a.f_ext * x))


class _CondensedTwist:
    """The twist angles of a cable with a material frame, kept in equilibrium with the positions of the
    accepted iterates and of each trial (put back when a trial is rejected), and the stiffness of the joint
    (positions, twist angles) system for Newton's step.

    The stiffness is the central difference of the energy's gradient (the elastic forces and dE/dtheta
    [N m]) with the frames transported to each perturbed state, so it includes the terms the analytic
    position Jacobian leaves out (the anisotropic bending's curvature terms, the frames' spin, the coupling
    of twist and bending: see :func:`~bullet_dlo.core.kernels.twist.add_twist_jacobian`). Those terms are
    of the order of the bending stress times E I_strong / l0, which for a strip bent far about its weak
    axis dwarfs its weak stiffness: with the analytic matrix (and the plain update x + dx) a hanging plastic
    ribbon's static solve did not converge in 3000 iterations; with this one (and :func:`_advance`) it takes
    8-77 at n = 21. Everything is local (a node's
    forces and a segment's twist moment reach two nodes each way), so nodes ``STRIDE`` apart are perturbed
    together: 4 x STRIDE pairs of gradient evaluations give the banded stiffness, O(n).
    """

    STRIDE = 5  # nodes perturbed together; their effects (two nodes each way) do not overlap
    HALF = 11  # half-bandwidth of the interleaved layout (x_i, theta_i) per node: 4 x 2 + 3

    def __init__(self, a: KernelArrays, x: np.ndarray, dirs: np.ndarray, free: np.ndarray, length: float):
        self.a, self.dirs, self.free = a, dirs, free
        twist_ready(a, x, dirs)  # frames built from x, twist angles in equilibrium with the clamps
        self.saved = self.arrays_copy()
        n = x.shape[0]
        self.f = np.zeros((n, 3))
        self.grad = np.zeros(n - 1)
        self.hdiag = np.zeros(n - 1)
        self.zeros_v = np.zeros((n, 3))
        self.h_x = 1e-6 * length / (n - 1)  # [m]: central differences, error ~h^2 against round-off ~eps/h
        self.h_theta = 1e-6  # [rad]

    def _arrays(self) -> tuple[np.ndarray, ...]:
        """The twist state's arrays a static solve changes: twist angles, reference frames and twists."""
        a = self.a
        return a.tw_theta, a.tw_ref, a.tw_tan, a.tw_mref

    def arrays_copy(self) -> tuple[np.ndarray, ...]:
        return tuple(arr.copy() for arr in self._arrays())

    def settle(self, x: np.ndarray) -> None:
        """Transport the frames to x [m] and put the twist angles in equilibrium there (the DER forces are
        the energy's gradient only where the frames were transported)."""
        update_frames(self.a, x, self.dirs)
        twist_solve(self.a, x, self.dirs, 1.0, False, self.a.tw_mref)

    def keep(self) -> None:
        self.saved = self.arrays_copy()

    def restore(self) -> None:
        for dst, src in zip(self._arrays(), self.saved):
            dst[:] = src

    def _gradient(self, x: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """dE/d(x, theta) at (x [m], theta [rad]), frames transported from the kept state, in the interleaved
        layout (4n,): -F_x [N], dE/dtheta [N m] (0 in the last node's slot); the kept state is put back."""
        a, n = self.a, x.shape[0]
        a.tw_theta[:] = theta
        update_frames(a, x, self.dirs)
        total_forces(a, x, self.zeros_v, self.dirs, self.f)
        theta_gradient(a, x, self.dirs, a.tw_theta, self.grad, self.hdiag)
        self.restore()
        g = np.zeros((n, 4))
        g[:, :3] = -self.f
        g[:-1, 3] = self.grad
        return g.reshape(-1)

    def theta_residual(self, x: np.ndarray) -> np.ndarray:
        """dE/dtheta [N m] (n-1,) at x [m] and the kept twist angles (0 up to the twist solve's tolerance)."""
        theta_gradient(self.a, x, self.dirs, self.a.tw_theta, self.grad, self.hdiag)
        return self.grad.copy()

    def newton_step(self, x: np.ndarray, r: np.ndarray, mu: float) -> np.ndarray:
        """The positions' part [m] (n, 3) of the regularised Newton step (K + mu D) dz = -dE/dz of the joint
        system at x with the kept twist angles; r: the forces [N] (n, 3), 0 on held nodes; mu [1/s^2] times
        D = diag(masses [kg], segments' spin inertias [kg m^2])."""
        n, a = x.shape[0], self.a
        ab = self.stiffness(x)
        ab[self.HALF, :].reshape(n, 4)[:, :3] += (mu * a.mass * self.free)[:, None]
        ab[self.HALF, :].reshape(n, 4)[:-1, 3] += mu * a.tw_inertia
        rhs = np.zeros((n, 4))
        rhs[:, :3] = r
        rhs[:-1, 3] = -self.theta_residual(x)
        dz = solve_banded((self.HALF, self.HALF), ab, rhs.reshape(-1))
        return dz.reshape(n, 4)[:, :3].copy()

    def stiffness(self, x: np.ndarray) -> np.ndarray:
        """The joint stiffness d2E/d(x, theta)^2 at x [m] and the kept twist angles, as the band of
        :func:`scipy.linalg.solve_banded` ((2 HALF + 1, 4n)), held nodes and the last node's empty slot as
        identity rows and columns."""
        n, half = x.shape[0], self.HALF
        theta0 = self.saved[0]
        ab = np.zeros((2 * half + 1, 4 * n))
        for first in range(self.STRIDE):
            nodes = np.arange(first, n, self.STRIDE)
            for comp in range(4):
                step = self.h_theta if comp == 3 else self.h_x
                cols = nodes[nodes < n - 1] if comp == 3 else nodes
                g = []
                for sign in (1.0, -1.0):
                    xp, tp = x.copy(), theta0.copy()
                    if comp == 3:
                        tp[cols] += sign * step
                    else:
                        xp[cols, comp] += sign * step
                    g.append(self._gradient(xp, tp))
                column = (g[0] - g[1]) / (2.0 * step)
                for i in cols:
                    col = 4 * i + comp
                    lo, hi = max(0, 4 * (i - 2)), min(4 * n, 4 * (i + 3))
                    ab[half + np.arange(lo, hi) - col, col] = column[lo:hi]
        fixed = np.repeat(~self.free, 4) & (np.arange(4 * n) % 4 < 3)  # held positions (their segments turn)
        fixed[4 * n - 1] = True  # the last node has no segment
        for col in np.flatnonzero(fixed):
            lo, hi = max(0, col - half), min(4 * n, col + half + 1)
            ab[half + np.arange(lo, hi) - col, col] = 0.0  # the column
            for row in range(lo, hi):
                ab[half + col - row, row] = 0.0  # the row
            ab[half, col] = 1.0
        return ab


def solve_static(
    model: CableModel,
    x_start: np.ndarray | None = None,
    f_ext: np.ndarray | None = None,
    *,
    tol: float = 1e-10,
    max_iter: int = 200,
) -> StaticResult:
    """Equilibrium of ``model`` under gravity (and ``f_ext`` [N], (n, 3)) from ``x_start``.

    tol: convergence when the largest free-node force is below tol * (M |g| + sum |f_ext|) [N],
    or when a near-Newton step (regularisation at most its starting value) moves no node by more
    than the position round-off, 1e3 * eps * (|x| + L) [m]: the forces of stiff or finely
    discretised cables cannot be evaluated more precisely (their round-off grows like n^3; at
    n = 1000 it is ~5e-5 N, a sixth of a node's weight). A residual below some force floor is
    never taken for convergence by itself: the start, with no step taken, is not converged.

    Damped Newton at the full load first (at most ``max_iter`` iterations). A linearised step cannot
    follow a large rotation of a nearly inextensible cable (a soft cantilever drooping from straight),
    so where that does not converge the load is applied in steps from the unloaded equilibrium
    (continuation): each step solved by the same Newton from the last equilibrium (at most ``max_iter``
    iterations), the step doubled after a success and halved after a failure, down to 1e-4 of the load.
    ``iterations`` counts every Newton iteration.
    """
    newton = _Newton(model, x_start, f_ext, tol)
    x0, frame0 = newton.x.copy(), newton.mark()
    x, res, iterations, converged = newton.solve(newton.x, 1.0, max_iter)
    if not converged:
        x, res, more, converged = _continuation(newton, x0, frame0, max_iter)
        iterations += more
    twist = newton.twist.copy() if newton.frame is not None else None
    return StaticResult(x, res, iterations, converged, twist)


def _continuation(newton: "_Newton", x0: np.ndarray, frame0: tuple | None, max_iter: int
                  ) -> tuple[np.ndarray, float, int, bool]:
    """The load applied in steps (see :func:`solve_static`) from start positions x0 [m] and twist state
    ``frame0``; returns positions, residual [N], iterations, converged (at the full load)."""
    newton.back_to(frame0)
    x, res, iterations, converged = newton.solve(x0, 0.0, max_iter)
    done, step = 0.0, 0.25
    while converged and done < 1.0:
        mark = newton.mark()
        load = min(1.0, done + step)
        x_try, res, used, converged = newton.solve(x, load, max_iter)
        iterations += used
        if converged:
            x, done, step = x_try, load, 2.0 * step
        elif step > 1e-4:
            newton.back_to(mark)
            step, converged = 0.5 * step, True
        else:
            x = x_try
    newton.set_load(1.0)
    return x, res, iterations, converged and done == 1.0


def _advance(x: np.ndarray, dx: np.ndarray, free: np.ndarray) -> np.ndarray:
    """x + dx [m] with each segment turned to the direction of e + de and given the length the step predicts to
    first order, |e| + t . de (the plain sum also lengthens a turning segment by |de|^2 / 2|e|, which a
    nearly inextensible cable meets with its stretch stiffness: a large rotation's Newton step then raises the
    energy however right its direction). Chained from the first node; where the last node is held, the
    chain's miss at it is spread along the arc length."""
    e, de = np.diff(x, axis=0), np.diff(dx, axis=0)
    length = np.linalg.norm(e, axis=1)
    grown = length + np.einsum("ij,ij->i", e, de) / length
    turned = e + de
    turned /= np.linalg.norm(turned, axis=1)[:, None]
    y = np.empty_like(x)
    y[0] = x[0] + dx[0]
    y[1:] = y[0] + np.cumsum(grown[:, None] * turned, axis=0)
    if not free[-1]:
        s = np.concatenate([[0.0], np.cumsum(grown)])
        y -= np.outer(s / s[-1], y[-1] - (x[-1] + dx[-1]))
    elif free[0]:
        y += (dx - (y - x)).mean(axis=0)
    return y


class _Newton:
    """Damped Newton (Levenberg-Marquardt) on the free nodes' forces under a share of the load."""

    def __init__(self, model: CableModel, x_start: np.ndarray | None, f_ext: np.ndarray | None, tol: float):
        n = model.n
        self.fe = np.zeros((n, 3)) if f_ext is None else np.asarray(f_ext, dtype=float)
        self.twist = model.twist_state()
        a = self.a = model.kernel_arrays(model.control(self.fe), self.twist)
        x = (model.x0 if x_start is None else np.asarray(x_start, dtype=float)).copy()
        x[0] = model.first.position if a.held[0] else x[0]
        x[-1] = model.last.position if a.held[-1] else x[-1]
        self.x = x
        self.zeros_v = np.zeros((n, 3))  # static: no damping forces
        self.free = ~a.held
        self.dirs = model.holder_plan().start_dir
        scale = model.spec.mass * float(np.linalg.norm(a.gravity)) + float(np.abs(self.fe).sum()) + 1e-30
        self.target = tol * scale
        self.step_floor = 1e3 * np.finfo(float).eps * (float(np.abs(x).max()) + model.spec.length)  # [m]
        self.frame = (_CondensedTwist(a, x, self.dirs, self.free, model.spec.length)
                      if a.tw_k_twist.shape[0] > 0 else None)
        self.f = np.zeros((n, 3))
        # [J]: the work of the load, or of the start's elastic forces, over the cable's length: the potential's
        # round-off scale (pot_floor). The elastic part keeps it where no load is (gravity off): with the load's
        # alone a nearly straight cable held in two grippers (ends 1.7e-7 m closer than its length) had its
        # round-off steps refused, their potential rising by 5e-23 J against a floor of 1.6e-23 J, and the
        # solve ended unconverged at a residual of 2e-12 N
        self.set_load(0.0)
        elastic = self.residual(x)[1]  # [N] the largest elastic force on a free node at the start
        self.work_scale = (scale + elastic) * model.spec.length
        self.jac = np.zeros((n, 5, 3, 3))
        self.band = np.zeros((3 * n, 2 * HALF + 1))
        # Regularisation in units of M^-1 K: start tiny, grow when a step fails.
        self.mu0 = 1e-8 * float(np.max(a.k_stretch) / np.min(a.mass))

    def pot_floor(self, pot: float) -> float:
        """Round-off of the potential [J] near ``pot``: a step that lowers the residual may raise the potential
        this much (at convergence its changes are below it)."""
        return 1e3 * np.finfo(float).eps * (abs(pot) + self.work_scale)

    def set_load(self, share: float) -> None:
        """Apply ``share`` of gravity and f_ext: the external forces become share f_ext + (share - 1) m g."""
        a = self.a
        a.f_ext[:] = share * self.fe + (share - 1.0) * a.mass[:, None] * a.gravity[None, :]

    def mark(self) -> tuple | None:
        """The twist state as it is (None without a material frame)."""
        return None if self.frame is None else self.frame.arrays_copy()

    def back_to(self, mark: tuple | None) -> None:
        """Put the twist state of :meth:`mark` back."""
        if self.frame is not None:
            self.frame.saved = mark
            self.frame.restore()

    def residual(self, x: np.ndarray) -> tuple[np.ndarray, float]:
        """The forces [N] on the free nodes (0 on held ones), (n, 3), and their largest component."""
        total_forces(self.a, x, self.zeros_v, self.dirs, self.f)
        r = self.f.copy()
        r[~self.free] = 0.0
        return r, float(np.abs(r).max())

    def step(self, x: np.ndarray, r: np.ndarray, mu: float) -> np.ndarray:
        """The regularised Newton step [m], (3n,)."""
        if self.frame is not None:
            return self.frame.newton_step(x, r, mu).reshape(-1)
        force_jacobian(self.a, x, self.dirs, False, self.jac)
        assemble_system(self.a, self.jac, mu, 1.0, 0.0, self.band)
        rhs = r.reshape(-1).copy()
        band_solve(self.band, rhs)
        return rhs

    def solve(self, x: np.ndarray, share: float, max_iter: int) -> tuple[np.ndarray, float, int, bool]:
        """Equilibrium under ``share`` of the load from x [m]: positions, residual [N], iterations, converged."""
        self.set_load(share)
        a, n, frame, mu0 = self.a, x.shape[0], self.frame, self.mu0
        mu = mu0
        r, res = self.residual(x)
        pot = _potential(a, x, self.dirs)
        it = 0
        at_roundoff = False
        while it < max_iter and res > self.target:
            it += 1
            rhs = self.step(x, r, mu)
            if mu <= mu0 and float(np.abs(rhs).max()) <= self.step_floor:
                at_roundoff = True  # the Newton step is below position round-off: nothing left to gain
                break
            x_try = _advance(x, rhs.reshape(n, 3), self.free)
            if frame is not None:
                frame.settle(x_try)
            r_try, res_try = self.residual(x_try)
            pot_try = _potential(a, x_try, self.dirs)
            if np.isfinite(res_try) and (pot_try <= pot or (res_try < res and pot_try <= pot + self.pot_floor(pot))):
                x, r, res, pot = x_try, r_try, res_try, pot_try
                mu *= 0.1
                if frame is not None:
                    frame.keep()
            else:
                mu = max(mu, 1e-12) * 10.0
                if frame is not None:
                    frame.restore()
        return x, res, it, bool(res <= self.target or at_roundoff)
