"""A cable inside PyBullet: one Bullet sphere per mass, moved by MSD forces from the core.

Every fixed Bullet step:

1. the core integrator advances the cable's own state (x, v) -> (x', v') (Numba, one call);
2. each sphere gets the external force that makes Bullet's semi-implicit update land on x':
   F = m ((x' - x)/h - v_b)/h - m g_bullet, with v_b Bullet's current velocity of the sphere;
3. Bullet steps, resolving contacts with everything else;
4. one ``getContactPoints`` call says which spheres something touched. Only those are read
   back; for them the contact's velocity change (read - target) is added to v'. Untouched
   spheres are exactly where step 2 sent them, so there is nothing to read.

Without contacts the Bullet trajectory therefore equals the core trajectory of every
integrator (x' is reproduced exactly; v' is kept on our side when the method's x' is not
x + h v'). Bullet clamps body speeds at 100 m/s: only an unstable run gets there.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pybullet as pb
from numba import njit

from bullet_dlo.core.boundary import _rotate, sample_holders
from bullet_dlo.core.engine import (
    REASONS,
    STABLE,
    DetectorOptions,
    advance,
    end_forces_kernel,
    energy_kernel,
    energy_scale,
    history,
    monitor,
)
from bullet_dlo.core.integrators import NewtonOptions, get_integrator
from bullet_dlo.core.kernels.forces import clamp_torque
from bullet_dlo.core.model import CableModel, CableState
from bullet_dlo.core.validate import ParameterError, check_int

SELF_COLLISION = ("neighbours", "none", "all")


@njit(cache=True, error_model="numpy")
def external_samples(ext, e, tau0, hs, hp, hv, ha, hd):
    """Held-end samples of end ``e`` at tau0 + (0, hs/2, hs) after the time of ``ext``.

    ext: (5, 2, 3) = position [m], velocity [m/s], acceleration [m/s^2], angular velocity
    [rad/s] and clamp direction of each end, measured now (e.g. from a gripper link);
    extrapolated at constant velocity and angular velocity over the step.
    """
    for k in range(3):
        tau = tau0 + 0.5 * hs * k
        for j in range(3):
            hp[k, e, j] = ext[0, e, j] + tau * ext[1, e, j]
            hv[k, e, j] = ext[1, e, j]
            ha[k, e, j] = ext[2, e, j]
            hd[k, e, j] = ext[4, e, j]
        _rotate(hd[k, e], tau * ext[3, e, 0], tau * ext[3, e, 1], tau * ext[3, e, 2])


@njit(cache=True, error_model="numpy")
def coupled_targets(code, x, v, hist, has_prev, t, h, substeps, m, p0s, d0s, moves_first, moves_last, f_ext,
                    max_iter, tol, definite, v_bullet, g_bullet, ext_mask, ext, x_new, v_new, forces, hp, hv, ha, hd):
    """Advance the core state by one Bullet step h (``substeps`` integrator steps) and compute
    the sphere forces [N] that make Bullet reproduce it. x_new, v_new, forces: (n, 3) outputs.

    Ends with ``ext_mask`` follow the measured poses in ``ext`` (see :func:`external_samples`)
    instead of the move tables. hp/hv/ha/hd receive the held-end samples of the last substep.
    Returns (Newton iterations, all converged).
    """
    x_new[:, :] = x
    v_new[:, :] = v
    hs = h / substeps
    iters = 0
    ok_all = True
    for k in range(substeps):
        sample_holders(t + k * hs, hs, p0s, d0s, moves_first, moves_last, hp, hv, ha, hd)
        for e in range(2):
            if ext_mask[e]:
                external_samples(ext, e, k * hs, hs, hp, hv, ha, hd)
        its, ok = advance(code, x_new, v_new, hist, has_prev or k > 0, hs, m, hp, hv, hd, f_ext, max_iter, tol,
                          definite)
        iters += its
        ok_all = ok_all and ok
    for i in range(x.shape[0]):
        for j in range(3):
            v_target = (x_new[i, j] - x[i, j]) / h
            forces[i, j] = m.mass[i] * ((v_target - v_bullet[i, j]) / h - g_bullet[j])
    return iters, ok_all


@njit(cache=True, error_model="numpy")
def sync_and_advance(code, S, hist, has_prev, t, h, substeps, m, p0s, d0s, moves_first, moves_last, f_ext, max_iter,
                     tol, definite, g_bullet, ext_mask, ext, do_sync, touched_idx, touched_pos, touched_vel, H, mon, acc, e0,
                     max_strain_bound, energy_factor, do_check, energy_check):
    """One call per Bullet step (few, packed arguments: the step loop is overhead-bound).

    S: (6, n, 3) = x, v (model), v_bullet (Bullet's velocity), x_new, v_new (planned), forces.
    H: (4, 3, 2, 3) held-end samples (pos, vel, acc, dir) of the planned step.
    mon: (3, 2, 3) = end forces, last held positions, last end forces (for the holder work).

    1. (``do_sync``) take over the step Bullet just made: the planned x_new/v_new for untouched
       spheres; for touched ones the read-back position and velocity (``touched_*``), the
       contact's velocity change added to v_new;
    2. (``do_check``, ``energy_check``) monitor stability at the new time;
    3. if stable, plan the next step from time t (:func:`coupled_targets`).
    Returns (status, Newton iterations, converged).
    """
    x, v, v_bullet, x_new, v_new, forces = S[0], S[1], S[2], S[3], S[4], S[5]
    hp, hv, ha, hd = H[0], H[1], H[2], H[3]
    status = STABLE
    if do_sync:
        n = x.shape[0]
        for i in range(n):
            for j in range(3):
                vt = (x_new[i, j] - x[i, j]) / h
                x[i, j] = x_new[i, j]
                v[i, j] = v_new[i, j]
                v_bullet[i, j] = vt
        for k in range(touched_idx.shape[0]):
            i = touched_idx[k]
            for j in range(3):
                x[i, j] = touched_pos[k, j]
                v[i, j] += touched_vel[k, j] - v_bullet[i, j]
                v_bullet[i, j] = touched_vel[k, j]
        if do_check or energy_check:
            status = monitor(x, v, m, hp[2], ha[2], hd[2], f_ext, mon[0], mon[1], mon[2], acc, e0,
                             max_strain_bound, energy_factor, energy_check)
    if status != STABLE:
        return status, 0, True
    its, ok = coupled_targets(code, x, v, hist, has_prev, t, h, substeps, m, p0s, d0s, moves_first, moves_last,
                              f_ext, max_iter, tol, definite, v_bullet, g_bullet, ext_mask, ext, x_new, v_new,
                              forces, hp, hv, ha, hd)
    return status, its, ok


@dataclass
class CableRecord:
    """Rows recorded every ``record_every`` steps: t [s], x [m], v [m/s], end forces [N], energy [J]."""

    t: list = field(default_factory=list)
    x: list = field(default_factory=list)
    v: list = field(default_factory=list)
    end_forces: list = field(default_factory=list)
    energy: list = field(default_factory=list)

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.array(getattr(self, k)) for k in ("t", "x", "v", "end_forces", "energy")}


class BulletCable:
    """A cable's spheres in a Bullet world and the state the MSD model keeps for them.

    Create with :meth:`bullet_dlo.bullet_scene.BulletWorld.add_cable`.
    """

    def __init__(self, world, name: str, model: CableModel, integrator: str, *, state: CableState | None,
                 substeps: int, self_collision: str, sync: str, newton: NewtonOptions,
                 detector: DetectorOptions, record_every: int, color=(0.9, 0.35, 0.1, 1.0)):
        self.world = world
        self.name = name
        self.model = model
        self.method = get_integrator(integrator)
        self.substeps = check_int("substeps", substeps, 1)
        if self_collision not in SELF_COLLISION:
            raise ParameterError(f"self_collision must be one of {', '.join(SELF_COLLISION)}, got {self_collision!r}")
        if sync not in ("contacts", "always"):
            raise ParameterError(f"sync must be 'contacts' or 'always', got {sync!r}")
        self.sync = sync
        self.newton = newton
        self.tol = newton.tolerance(self.method.name)
        self.detector = detector
        self.record_every = check_int("record_every", record_every, 1)
        st = (state or model.initial_state()).copy()
        n = model.n
        # packed per-step arrays (views below): x, v, v_bullet, x_new, v_new, forces
        self._S = np.zeros((6, n, 3))
        self.x, self.v, self.v_bullet, self._x_new, self._v_new, self._forces = self._S
        self.x[:] = st.x
        self.v[:] = st.v
        self.v_bullet[:] = st.v
        self.t = float(st.t)
        self.hist = history(n)
        self.steps = 0
        self.f_ext = np.zeros((n, 3))
        self._H = np.zeros((4, 3, 2, 3))  # held-end samples: pos, vel, acc, dir
        self._samples = list(self._H)
        # own copy of the model arrays: grasp and release change the end conditions in place
        self.arrays = type(model.arrays)(*[np.array(a, copy=True) for a in model.arrays])
        self._ext = np.zeros((5, 2, 3))  # measured held-end poses: pos, vel, acc, omega, dir
        self._ext_mask = np.zeros(2, dtype=np.bool_)
        self._no_rows = np.zeros((0, 3))
        self._no_index = np.zeros(0, dtype=np.int64)
        self._tables = model.holder_tables()
        self._ext[4] = self._tables[1]  # clamp directions until a gripper takes over
        self.radius = 0.5 * model.spec.diameter
        self.body_ids = self._spawn(color, self_collision)
        # instability monitor
        hp, hv, ha, hd = self._samples
        p0s, d0s, mf, ml = self._tables
        sample_holders(self.t, world.dt, p0s, d0s, mf, ml, hp, hv, ha, hd)
        a = self.arrays
        self._e0 = energy_kernel(self.x, self.v, a, hd[0])
        self._mon = np.zeros((3, 2, 3))  # end forces, last held positions, last end forces
        self._ef = self._mon[0]
        end_forces_kernel(self.x, self.v, a, hd[0], ha[0], self.f_ext, self._ef)
        self._mon[1] = hp[0]
        self._mon[2] = self._ef
        self._acc = np.array([0.0, energy_scale(model, st)])
        self.status = STABLE
        self.time_to_instability: float | None = None
        self.newton_iterations = 0
        self.newton_failures = 0
        self.contacts_last_step = 0
        self.record = CableRecord()
        self._record_row()
        # argument groups of the per-step kernel, bound once (the step loop is overhead-bound)
        self._args_state = (self.method.code, self._S, self.hist)
        self._args_model = (self.substeps, a, *self._tables, self.f_ext, newton.max_iter, self.tol, newton.definite,
                            world.gravity, self._ext_mask, self._ext)
        self._args_monitor = (self._H, self._mon, self._acc, self._e0, detector.max_strain, detector.energy_factor)
        self._advance(None)  # plan the first step

    # ----- set-up -------------------------------------------------------------------------
    def _spawn(self, color, self_collision: str) -> list[int]:
        cid = self.world.client
        n = self.model.n
        spec = self.model.spec
        col = pb.createCollisionShape(pb.GEOM_SPHERE, radius=self.radius, physicsClientId=cid)
        vis = pb.createVisualShape(pb.GEOM_SPHERE, radius=self.radius, rgbaColor=list(color), physicsClientId=cid)
        # One createMultiBody per sphere: the batch form (batchPositions) leaves PyBullet's client
        # with one body where the server has n (getNumBodies, removeBody and later ids go wrong).
        body = [pb.createMultiBody(baseMass=float(mass), baseCollisionShapeIndex=col, baseVisualShapeIndex=vis,
                                   basePosition=pos, physicsClientId=cid)
                for mass, pos in zip(self.model.arrays.mass, self.x.tolist())]
        for i, b in enumerate(body):
            pb.resetBaseVelocity(b, self.v[i].tolist(), [0, 0, 0], physicsClientId=cid)
            pb.changeDynamics(b, -1, linearDamping=0.0, angularDamping=0.0, lateralFriction=spec.friction,
                              activationState=pb.ACTIVATION_STATE_DISABLE_SLEEPING, physicsClientId=cid)
        if self_collision == "none":
            group = self.world.next_cable_group()
            for b in body:
                pb.setCollisionFilterGroupMask(b, -1, group, 0xFFFF & ~group, physicsClientId=cid)
        elif self_collision == "neighbours":
            # spheres closer than a diameter at rest always touch: never let them collide
            reach = max(1, math.ceil(1.05 * spec.diameter / spec.rest_length))
            for i in range(n):
                for j in range(i + 1, min(n, i + reach + 1)):
                    pb.setCollisionFilterPair(body[i], body[j], -1, -1, 0, physicsClientId=cid)
        return body

    # ----- stepping -----------------------------------------------------------------------
    def _advance(self, touched: list[int] | None) -> None:
        """Sync the step Bullet made (unless ``touched`` is None: spawn) and plan the next one."""
        cid = self.world.client
        do_sync = touched is not None
        idx = touched if do_sync else []
        if do_sync and self.sync == "always":
            idx = list(range(self.model.n))
        if idx:
            pos = np.array([pb.getBasePositionAndOrientation(self.body_ids[i], physicsClientId=cid)[0] for i in idx])
            vel = np.array([pb.getBaseVelocity(self.body_ids[i], physicsClientId=cid)[0] for i in idx])
            idx_arr = np.asarray(idx, dtype=np.int64)
        else:  # the common case: nothing touched, nothing to read
            pos = vel = self._no_rows
            idx_arr = self._no_index
        if do_sync:
            self.t += self.world.dt
            self.steps += 1
            self.contacts_last_step = len(touched)
        status, its, ok = sync_and_advance(
            *self._args_state, self.steps > 0, self.t, self.world.dt, *self._args_model, do_sync, idx_arr, pos, vel,
            *self._args_monitor, do_sync and self.steps % self.detector.check_every == 0,
            do_sync and self.steps % self.detector.energy_every == 0)
        self.newton_iterations += its
        self.newton_failures += 0 if ok else 1
        if status != STABLE:
            self.status = status
            self.time_to_instability = self.t
        if do_sync and (self.steps % self.record_every == 0 or status != STABLE):
            self._record_row()

    def apply_forces(self) -> None:
        """Apply the forces planned for the coming Bullet step (nothing once unstable)."""
        if self.status != STABLE:
            return
        cid = self.world.client
        apply = pb.applyExternalForce
        frame = pb.WORLD_FRAME
        for b, f, pos in zip(self.body_ids, self._forces.tolist(), self.x.tolist()):
            apply(b, -1, f, pos, frame, cid)  # positional: keyword parsing costs 50 % more per call

    def sync_after_step(self, touched) -> None:
        """Take over Bullet's step: ``touched`` holds the spheres that had contacts (read back)."""
        if self.status == STABLE:
            self._advance(sorted(touched) if touched else [])

    def _record_row(self) -> None:
        hp, hv, ha, hd = self._samples
        a = self.arrays
        k = 0  # samples always start at the current time (they are planned for the coming step)
        out = np.zeros((2, 3))
        end_forces_kernel(self.x, self.v, a, hd[k], ha[k], self.f_ext, out)
        self.record.t.append(self.t)
        self.record.x.append(self.x.copy())
        self.record.v.append(self.v.copy())
        self.record.end_forces.append(out)
        self.record.energy.append(energy_kernel(self.x, self.v, a, hd[k]))

    # ----- grasping -----------------------------------------------------------------------
    def hold_externally(self, end: int, mode: str = "clamped") -> None:
        """Make end ``end`` (0 first, 1 last) follow poses given by :meth:`set_external_pose`.

        mode: ``clamped`` (position and tangent held, like a gripper) or ``pinned``.
        The clamp's bending stiffness is the spec's half-segment value (see CableSpec).
        """
        if mode not in ("clamped", "pinned"):
            raise ParameterError(f"grasp mode must be clamped or pinned, got {mode!r}")
        a, spec, n = self.arrays, self.model.spec, self.model.n
        node = 0 if end == 0 else n - 1
        a.held[node] = True
        a.end_mode[end] = 2 if mode == "clamped" else 1
        a.k_bend[node] = spec.k_bend_clamp if mode == "clamped" else 0.0
        self._ext_mask[end] = True
        self._replan()

    def release(self, end: int) -> None:
        """Let end ``end`` go: it becomes free and no longer follows any holder."""
        a, n = self.arrays, self.model.n
        node = 0 if end == 0 else n - 1
        a.held[node] = False
        a.end_mode[end] = 0
        a.k_bend[node] = 0.0
        self._ext_mask[end] = False
        self._replan()

    def set_external_pose(self, end: int, position, velocity, acceleration, omega, direction) -> None:
        """Measured pose of the holder of ``end`` now (world frame, SI); direction: clamp tangent
        pointing along the cable from its first to its last mass."""
        e = self._ext
        e[0, end], e[1, end], e[2, end], e[3, end] = position, velocity, acceleration, omega
        e[4, end] = np.asarray(direction, float) / np.linalg.norm(direction)

    def holder_positions(self) -> np.ndarray:
        """Positions [m] of the external holders (e.g. grasp frames) as last measured, (2, 3)."""
        return self._ext[0].copy()

    def _replan(self) -> None:
        """Re-plan the coming step after the end conditions changed (the forces must match)."""
        if self.status == STABLE:
            self._advance(None)

    # ----- read-outs ----------------------------------------------------------------------
    @property
    def stable(self) -> bool:
        return self.status == STABLE

    @property
    def reason(self) -> str | None:
        return REASONS[self.status]

    def state(self) -> CableState:
        """The cable's current state as the model sees it."""
        return CableState(self.x.copy(), self.v.copy(), self.t)

    def end_forces(self) -> np.ndarray:
        """Force [N] the cable exerts on each held end now, (2, 3) (first, last)."""
        hp, hv, ha, hd = self._samples
        out = np.zeros((2, 3))
        end_forces_kernel(self.x, self.v, self.arrays, hd[0], ha[0], self.f_ext, out)
        return out

    def end_moments(self) -> np.ndarray:
        """Torque [N m] the cable exerts on each clamp now, (2, 3) (zero rows for unclamped ends)."""
        hd = self._samples[3]
        a = self.arrays
        return np.stack([clamp_torque(self.x, a.k_bend, hd[0, 0], hd[0, 1], e) for e in (0, 1)])

    def bullet_positions(self) -> np.ndarray:
        """Sphere positions read from Bullet [m], (n, 3) (n PyBullet calls: for checks, not loops)."""
        cid = self.world.client
        return np.array([pb.getBasePositionAndOrientation(b, physicsClientId=cid)[0] for b in self.body_ids])
