"""Franka Panda kinematics and dynamics of the flange (``panda_link8``) from pybullet_data's URDF.

A private ``pybullet.DIRECT`` client holds the arm; nothing else lives in it. Frames and signs:

* world = the arm's base frame (the URDF's root), z up;
* flange = ``panda_link8``'s URDF frame (0.107 m beyond joint 7 along its axis; the frame an
  end effector is mounted on);
* Jacobian J (6, 7): [linear velocity [m/s]; angular velocity [rad/s]] of the flange origin in
  world axes per joint rate [rad/s] (the geometric Jacobian);
* wrench w (6,): [force [N]; moment about the flange origin [N m]] in world axes, **exerted by
  the load on the flange** (e.g. by a carried cable). Its torque about the joints is J^T w;
  Franka's external-torque estimate reports tau = -J^T w (:func:`external_torques`).
"""
from __future__ import annotations

import os
from typing import Sequence

import numpy as np

N_JOINTS = 7
FLANGE_LINK = 7  # panda_link8 (joint index of the fixed joint 8 in pybullet_data's panda.urdf)
PATHS_KEPT = 8  # joint paths whose flange poses and Jacobians a Panda keeps (Panda._along)


def external_torques(jacobian: np.ndarray, wrench: np.ndarray) -> np.ndarray:
    """Joint torques [N m], (..., 7), that Franka's external-torque estimate reports for a wrench
    ``wrench`` [N, N m], (..., 6), exerted by the load on the flange, with ``jacobian`` (..., 6, 7).

    Franka's ``tau_ext_hat_filtered`` is the torque the motors add to hold the load, i.e. minus
    the torque of the load's wrench about the joints: tau_ext = -J^T w (checked on the beam
    recordings: a strip hanging from the flange gives the measured static torques' sign, and the
    predicted vibration has a positive correlation with the measured one).
    """
    return -np.einsum("...ij,...i->...j", jacobian, wrench)


def wrench_from_torques(jacobian: np.ndarray, torques: np.ndarray) -> np.ndarray:
    """The flange wrench [N, N m], (6,), whose :func:`external_torques` are closest to ``torques``
    [N m], (7,), in least squares (the minimum-norm solution of -J^T w = tau; the Panda's 7 joints
    determine all 6 components away from singular poses)."""
    return np.linalg.lstsq(-np.asarray(jacobian).T, np.asarray(torques), rcond=None)[0]


class Panda:
    """The Panda arm in a private PyBullet DIRECT client: flange pose, Jacobian, inverse dynamics.

    Use as a context manager or call :meth:`close`. Joint vectors q [rad], dq [rad/s],
    ddq [rad/s^2] are the 7 arm joints; the fingers are held at 0.
    """

    def __init__(self) -> None:
        import pybullet
        import pybullet_data

        self._p = pybullet
        self._cid = pybullet.connect(pybullet.DIRECT)
        path = os.path.join(pybullet_data.getDataPath(), "franka_panda", "panda.urdf")
        self._arm = pybullet.loadURDF(path, useFixedBase=True, physicsClientId=self._cid)
        pybullet.setGravity(0.0, 0.0, -9.81, physicsClientId=self._cid)  # inverse dynamics includes the arm's weight
        self._dofs = sum(pybullet.getJointInfo(self._arm, j, physicsClientId=self._cid)[2] != pybullet.JOINT_FIXED
                         for j in range(pybullet.getNumJoints(self._arm, physicsClientId=self._cid)))

    def __enter__(self) -> "Panda":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Disconnect the private client (idempotent)."""
        if self._cid is not None:
            self._p.disconnect(physicsClientId=self._cid)
            self._cid = None

    def _set(self, q: Sequence[float]) -> None:
        self._p.resetJointStatesMultiDof(self._arm, range(N_JOINTS), [[float(q[j])] for j in range(N_JOINTS)],
                                         physicsClientId=self._cid)  # one call, not seven

    def _full(self, values: Sequence[float]) -> list[float]:
        """7 arm values padded with zeros for the fingers (PyBullet wants every movable joint)."""
        return [float(v) for v in values[:N_JOINTS]] + [0.0] * (self._dofs - N_JOINTS)

    def flange_pose(self, q: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
        """Flange position [m], (3,), and rotation matrix (columns: flange axes in world), (3, 3), at q [rad]."""
        self._set(q)
        state = self._p.getLinkState(self._arm, FLANGE_LINK, computeForwardKinematics=True,
                                     physicsClientId=self._cid)
        rot = np.array(self._p.getMatrixFromQuaternion(state[5])).reshape(3, 3)
        return np.array(state[4]), rot

    def jacobian(self, q: Sequence[float]) -> np.ndarray:
        """Geometric Jacobian of the flange origin at q [rad], (6, 7): [linear; angular] in world axes."""
        self._set(q)
        state = self._p.getLinkState(self._arm, FLANGE_LINK, computeForwardKinematics=True,
                                     physicsClientId=self._cid)
        # PyBullet takes the point in the link's inertial frame: the flange origin expressed there
        com_rot = np.array(self._p.getMatrixFromQuaternion(state[1])).reshape(3, 3)
        local = com_rot.T @ (np.array(state[4]) - np.array(state[0]))
        zeros = [0.0] * self._dofs
        lin, ang = self._p.calculateJacobian(self._arm, FLANGE_LINK, local.tolist(), self._full(q), zeros, zeros,
                                             physicsClientId=self._cid)
        return np.vstack([np.array(lin)[:, :N_JOINTS], np.array(ang)[:, :N_JOINTS]])

    def inverse_dynamics(self, q: Sequence[float], dq: Sequence[float], ddq: Sequence[float]) -> np.ndarray:
        """Joint torques [N m], (7,), of the bare arm (URDF inertias, hand included) for q, dq, ddq."""
        tau = self._p.calculateInverseDynamics(self._arm, self._full(q), self._full(dq), self._full(ddq),
                                               physicsClientId=self._cid)
        return np.array(tau[:N_JOINTS])

    def mass_matrix(self, q: Sequence[float]) -> np.ndarray:
        """Joint-space inertia matrix of the arm [kg m^2], (7, 7), at q [rad] (URDF inertias, hand included)."""
        m = self._p.calculateMassMatrix(self._arm, self._full(q), physicsClientId=self._cid)
        return np.array(m)[:N_JOINTS, :N_JOINTS]

    def flange_path(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Flange positions [m], (k, 3), and rotations, (k, 3, 3), for joint rows q [rad], (k, 7) (remembered:
        :meth:`_along`)."""
        def compute(rows):
            poses = [self.flange_pose(row) for row in rows]
            return np.array([p for p, _ in poses]), np.array([r for _, r in poses])
        pos, rot = self._along("flange_path", q, compute)
        return pos.copy(), rot.copy()

    def jacobians(self, q: np.ndarray) -> np.ndarray:
        """:meth:`jacobian` for joint rows q [rad], (k, 7): (k, 6, 7) (remembered: :meth:`_along`)."""
        return self._along("jacobians", q, lambda rows: np.array([self.jacobian(row) for row in rows])).copy()

    def _along(self, what: str, q: np.ndarray, compute):
        """``compute(q)`` for joint rows q, kept for the last :data:`PATHS_KEPT` joint paths: a fit predicts the
        same recordings with other strip parameters many times, and the arm's kinematics along a recording cost
        more than the strip's run (one PyBullet pose reset and query per row)."""
        rows = np.ascontiguousarray(q, dtype=float)
        key = (what, rows.shape, rows.tobytes())
        memo = self.__dict__.setdefault("_paths", {})
        if key not in memo:
            if len(memo) >= PATHS_KEPT:
                del memo[next(iter(memo))]
            memo[key] = compute(rows)
        return memo[key]
