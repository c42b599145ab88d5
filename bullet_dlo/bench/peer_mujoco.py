"""The benchmark's rod in MuJoCo (>= 4.0), truly clamped, in its two public forms: a 1-D flexcomp and a joint chain.

**Joint chain** (:class:`MujocoChainRod`, integrator labels ``"<integrator> chain"``; the cheaper of the two at
equal accuracy, found by an independent audit of this benchmark): n - 1 rigid capsule bodies in a kinematic tree,
each hinged to the one before by a ``ball`` joint with joint ``stiffness`` (what MuJoCo's ``composite
type="cable"`` built before 4.0, with the bending in the joints instead of the plugin):

* **clamp**: the first ball joint sits at x = 0 on the world with stiffness 2 E I / l (half the dual
  length, as our clamp spring), the inner ones E I / l (our bending springs): the same springs as our
  model; statically the chain is exact for its rigid segments, whose tip deflection is
  (1 + 1/(n - 1)^2) w L^4 / (8 E I) (second order, +0.83 % at n = 12, +0.28 % at n = 20);
* mass M / (n - 1) per segment at its centre, inertia of a solid cylinder of radius d / 2; a ball
  joint's stiffness also resists twist (with E I / l instead of G J / l: no twist in S1 or S2);
* damping: ``dof_damping = c M_jj`` (rate c [1/s], M_jj the joint-space mass matrix's diagonal at the
  straight pose): MuJoCo has no mass-proportional damping in joint coordinates, and this is the
  diagonal of c M; it only settles the rod (S1 and S2's settling), the free phase is undamped;
* ``discrete`` integrates the joint springs implicitly in position; MuJoCo's explicit
  integrators are unstable on this stiff chain above ~2e-5 s;
* the tip is a site at the last segment's end; MuJoCo computes positions at the start of a step, so
  :meth:`MujocoChainRod.advance` reads each step's tip height after the next step's kinematics (one
  ``mj_kinematics`` per chunk for the last), never a stale value.

**Flexcomp** (:class:`MujocoRod`, labels ``"discrete"``, ``"RK4"``, ``"Euler"``). MuJoCo 4.0 removed the
``elasticity.cable`` plugin (``<plugin plugin="mujoco.elasticity.cable">`` fails with "plugin not found"); its
replacement is ``<flexcomp dim="1">`` with ``<elasticity young=...>`` (bending and torsion, no stretching),
set up as a user would write it:

* **clamp**: a stub point at x = -s (s = :data:`STUB` x the segment length) before the n rod
  points at i L / (n - 1) along +x, and ``<pin id="0 1"/>``: the held edge is the stub behind
  x = 0, so the rod is clamped at x = 0 with its tangent along +x. The vertex at x = 0 gets
  MuJoCo's bending stiffness E I / (s + l), i.e. the half Voronoi length of a clamped end (as a
  mirror ghost node in finite differences); the tip deflection then converges at second order in
  n (+0.29 % at n = 20). Pinning the first *rod* edge instead (the old adapter) clamps the beam one
  element in: -2/n of the deflection, -10 % at n = 20;
* one capsule element per segment, radius d / 2 (so I = pi d^4 / 64, J = 2 I); young = E,
  poisson = 0.3 (G = E / 2.6);
* stretching is not part of MuJoCo's rod elasticity: edges are held at their length by
  ``<edge equality="true"/>`` soft constraints with solref = "2 dt 1", the stiffest time
  constant MuJoCo accepts (the default 0.02 s lets a hanging soft rod stretch by > 10 %);
* mass lumped as M / (n - 1) per free vertex and half of that at the tip, the same lumping as
  ours (flexcomp would give M / npoint to every point, pinned ones included);
* damping: ``dof_damping = c m`` on each vertex slide joint (rate c [1/s]), the same velocity
  damping as ours, integrated implicitly by ``discrete``; no twist damping;
* contacts off; gravity set at run time.

Integrators: ``discrete`` (implicit velocity stepping; MuJoCo's recommended integrator for flex
elasticity: MuJoCo 4.0 refuses ``implicit`` and ``implicitfast`` with "flex elasticity is no
longer integrated implicitly under integrator='implicit' and 'implicitfast': set
integrator='discrete', or 'Euler' with a small timestep"), and ``RK4`` / ``Euler`` (explicit in
the rod elasticity, small steps only).

Stepping: :meth:`MujocoRod.advance` calls ``mj_step(model, data, nstep=k)`` (no Python per
step) when nothing is recorded; the free mode reads one ``qpos`` entry (the tip's z slide) per step.

MuJoCo reports trouble (e.g. "Nan, Inf or huge value in QACC") through a global warning hook
that by default prints to the terminal and appends to ``MUJOCO_LOG.TXT`` in the working
directory. :class:`MujocoRod` is a context manager that routes those messages into its
``warnings`` list while it is open, and restores the previous hook after.
"""
from __future__ import annotations

import mujoco
import numpy as np

from bullet_dlo.bench.peers import POISSON
from bullet_dlo.core.spec import CableSpec

_BAD_STATE = ("mjWARN_BADQPOS", "mjWARN_BADQVEL", "mjWARN_BADQACC")

STUB = 1e-3
"""Length of the held stub behind x = 0, as a fraction of the segment length [-]."""

INTEGRATORS = ("discrete", "RK4", "Euler")
"""The integrators MuJoCo 4.0 accepts with flex elasticity."""

CHAIN = " chain"
"""Suffix of an integrator label that selects the joint chain (``"discrete chain"``)."""

CHAIN_INTEGRATORS = ("discrete", "implicitfast", "implicit", "RK4", "Euler")
"""MuJoCo's integrators, all of which take joint stiffness."""


def _xml(spec: CableSpec, dt: float, integrator: str) -> str:
    n, seg = spec.n_masses, spec.rest_length
    xs = [-STUB * seg] + [i * seg for i in range(n)]
    points = " ".join(f"{x:.17g} 0 0" for x in xs)
    elements = " ".join(f"{i} {i + 1}" for i in range(n))
    # flexcomp gives every one of its n + 1 points mass/npoint: ask for M/(n-1) per point
    return f"""
<mujoco model="cantilever">
  <option timestep="{dt:.17g}" integrator="{integrator}" gravity="0 0 0"/>
  <worldbody>
    <flexcomp name="rod" type="direct" dim="1" point="{points}" element="{elements}"
              radius="{spec.diameter / 2:.17g}" mass="{spec.mass * (n + 1) / (n - 1):.17g}">
      <edge equality="true" solref="{2.0 * dt:.17g} 1"/>
      <elasticity young="{spec.youngs_modulus:.17g}" poisson="{POISSON}"/>
      <contact contype="0" conaffinity="0"/>
      <pin id="0 1"/>
    </flexcomp>
  </worldbody>
</mujoco>"""


class _MujocoBase:
    """What both MuJoCo rods share: warnings captured while open (a context manager), gravity, velocities, the
    forward pass and MuJoCo's own divergence signal. Subclasses set ``model``, ``data`` and ``_bad``."""

    name = "mujoco"
    model: "mujoco.MjModel"
    data: "mujoco.MjData"

    def __enter__(self):
        self._previous_hook = mujoco.get_mju_user_warning()
        mujoco.set_mju_user_warning(self.warnings.append)
        return self

    def __exit__(self, *exc: object) -> None:
        mujoco.set_mju_user_warning(self._previous_hook)

    def set_gravity(self, g: float) -> None:
        self.model.opt.gravity[:] = (0.0, 0.0, -g)

    def refresh(self) -> None:
        mujoco.mj_forward(self.model, self.data)  # body positions of the current state

    def zero_velocities(self) -> None:
        self.data.qvel[:] = 0.0

    def diverged(self) -> bool:
        """MuJoCo's bad-state warnings (it then silently resets the state) or non-finite velocities."""
        return any(self.data.warning[w].number > 0 for w in self._bad) or not np.isfinite(self.data.qvel).all()


class MujocoRod(_MujocoBase):
    """:class:`bullet_dlo.bench.peers.PeerRod` for MuJoCo's flexcomp rod; use it as a context manager to capture
    warnings."""

    def __init__(self, spec: CableSpec, dt: float, integrator: str = "discrete") -> None:
        if integrator not in INTEGRATORS:
            raise ValueError(f"MuJoCo integrator for flex elasticity must be one of {INTEGRATORS}, got {integrator!r}")
        n = spec.n_masses
        self.integrator = integrator
        self.model = mujoco.MjModel.from_xml_string(_xml(spec, dt, integrator))
        self._tip = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, f"rod_{n}")  # point 0 is the stub
        self.model.body_mass[self._tip] = spec.mass / (2.0 * (n - 1))  # the tip node carries half a segment
        self.data = mujoco.MjData(self.model)
        mujoco.mj_setConst(self.model, self.data)
        slide = mujoco.mjtJoint.mjJNT_SLIDE
        joints = [j for j in range(self.model.njnt) if self.model.jnt_type[j] == slide]
        self._dofs = np.array([self.model.jnt_dofadr[j] for j in joints], dtype=int)
        self._dof_mass = np.array([self.model.body_mass[self.model.dof_bodyid[k]] for k in self._dofs])
        tip_z = [j for j in joints if self.model.jnt_bodyid[j] == self._tip and abs(self.model.jnt_axis[j, 2]) == 1.0]
        self._tip_qpos = int(self.model.jnt_qposadr[tip_z[0]])
        self._tip_z0 = float(self.model.body_pos[self._tip, 2])
        self._tip_sign = float(self.model.jnt_axis[tip_z[0], 2])
        self._bad = [int(getattr(mujoco.mjtWarning, w)) for w in _BAD_STATE]
        self.warnings: list[str] = []
        self._previous_hook = None
        solref = self.model.eq_solref[0]
        self.note = (f"integrator={integrator}; flexcomp dim=1 direct, stub point at x = -{STUB:g} l + {n} points, "
                     f"pin id='0 1' (the stub: clamp at x = 0), radius=d/2, young=E, poisson={POISSON}, edge equality "
                     f"(soft, solref {solref[0]:.3g} {solref[1]:.3g}), lumped mass M/(n-1) per free vertex and half at "
                     "the tip")

    def set_damping(self, rate: float) -> None:
        self.model.dof_damping[self._dofs] = rate * self._dof_mass

    def advance(self, k: int, trace: np.ndarray | None = None) -> None:
        """k steps; with ``trace`` (k,), the tip height [m] after each step (one qpos read per step)."""
        m, d = self.model, self.data
        if trace is None:
            mujoco.mj_step(m, d, nstep=k)
            return
        qpos, adr, z0, sign = d.qpos, self._tip_qpos, self._tip_z0, self._tip_sign
        for i in range(k):
            mujoco.mj_step(m, d)
            trace[i] = z0 + sign * qpos[adr]

    def positions(self) -> np.ndarray:
        """The n rod points (3, n) [m], the stub left out."""
        return self.data.flexvert_xpos.T[:, 1:]

    def tip_z(self) -> float:
        return self._tip_z0 + self._tip_sign * float(self.data.qpos[self._tip_qpos])


def _chain_xml(spec: CableSpec, dt: float, integrator: str) -> str:
    n, seg, r = spec.n_masses, spec.rest_length, spec.diameter / 2
    m = spec.mass / (n - 1)
    i_axial, i_cross = m * r * r / 2, m * (3 * r * r + seg * seg) / 12  # solid cylinder about its centre
    bodies = []
    for i in range(n - 1):
        k = (2.0 if i == 0 else 1.0) * spec.bending_rigidity / seg  # 2 EI / l at the clamp, EI / l inside [N m/rad]
        bodies.append(f'<body name="seg_{i}" pos="{0.0 if i == 0 else seg:.17g} 0 0">'
                      f'<joint name="node_{i}" type="ball" stiffness="{k:.17g}"/>'
                      f'<inertial pos="{seg / 2:.17g} 0 0" mass="{m:.17g}" '
                      f'diaginertia="{i_axial:.17g} {i_cross:.17g} {i_cross:.17g}"/>'
                      f'<geom type="capsule" fromto="0 0 0 {seg:.17g} 0 0" size="{r:.17g}" contype="0" '
                      f'conaffinity="0"/>' + (f'<site name="tip" pos="{seg:.17g} 0 0"/>' if i == n - 2 else ""))
    return f"""
<mujoco model="cantilever_chain">
  <option timestep="{dt:.17g}" integrator="{integrator}" gravity="0 0 0"/>
  <worldbody>{"".join(bodies)}{"</body>" * (n - 1)}</worldbody>
</mujoco>"""


class MujocoChainRod(_MujocoBase):
    """:class:`bullet_dlo.bench.peers.PeerRod` for MuJoCo's joint chain (see the module doc); a context manager
    like :class:`MujocoRod`."""

    def __init__(self, spec: CableSpec, dt: float, integrator: str = "discrete") -> None:
        if integrator not in CHAIN_INTEGRATORS:
            raise ValueError(f"MuJoCo integrator must be one of {CHAIN_INTEGRATORS}, got {integrator!r}")
        self.integrator = integrator + CHAIN
        self.model = mujoco.MjModel.from_xml_string(_chain_xml(spec, dt, integrator))
        self.data = mujoco.MjData(self.model)
        self._tip = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, "tip")
        mujoco.mj_forward(self.model, self.data)
        mass = np.zeros((self.model.nv, self.model.nv))
        mujoco.mj_fullM(self.model, self.data, mass)
        self._mass_diag = np.diag(mass).copy()
        self._bad = [int(getattr(mujoco.mjtWarning, w)) for w in _BAD_STATE]
        self.warnings: list[str] = []
        self._previous_hook = None
        self.note = (f"integrator={integrator}; chain of {spec.n_masses - 1} capsule bodies, ball joints with "
                     "stiffness 2 EI/l at the clamp (x = 0) and EI/l inside, M/(n-1) per segment at its centre, "
                     "solid-cylinder inertia, damping c diag(M) in joint space")

    def set_damping(self, rate: float) -> None:
        self.model.dof_damping[:] = rate * self._mass_diag

    def advance(self, k: int, trace: np.ndarray | None = None) -> None:
        """k steps; with ``trace`` (k,), the tip height [m] after each step: step i's height is the site
        position MuJoCo computes at the start of step i + 1, the last one from one ``mj_kinematics``."""
        m, d = self.model, self.data
        if trace is None:
            mujoco.mj_step(m, d, nstep=k)
            return
        site = d.site_xpos[self._tip]
        mujoco.mj_step(m, d)
        for i in range(1, k):
            mujoco.mj_step(m, d)
            trace[i - 1] = site[2]
        mujoco.mj_kinematics(m, d)
        trace[k - 1] = site[2]

    def positions(self) -> np.ndarray:
        """The n nodes (3, n) [m]: the segments' origins and the tip, as of MuJoCo's last kinematics."""
        d = self.data
        nodes = np.vstack([d.xpos[1:], d.site_xpos[self._tip][None, :]])
        return nodes.T

    def tip_z(self) -> float:
        return float(self.data.site_xpos[self._tip, 2])


def mujoco_rod(spec: CableSpec, dt: float, label: str) -> MujocoRod | MujocoChainRod:
    """The MuJoCo rod an integrator ``label`` names: ``"discrete"``, ``"RK4"``, ``"Euler"`` (flexcomp) or
    ``"<integrator> chain"`` (the joint chain, e.g. ``"discrete chain"``)."""
    if label.endswith(CHAIN):
        return MujocoChainRod(spec, dt, label[:-len(CHAIN)])
    return MujocoRod(spec, dt, label)
