"""The benchmark's rod in MuJoCo (>= 4.0): a 1-D flexcomp, MuJoCo's discrete elastic rod.

MuJoCo 4.0 removed the ``elasticity.cable`` plugin; its replacement is ``<flexcomp dim="1">``
with ``<elasticity young=...>`` (bending and torsion, no stretching). Mapping:

* n points at i L / (n - 1) along +x (``type="direct"``), one capsule element per segment,
  radius d / 2 (so I = pi d^4 / 64, J = 2 I); young = E, poisson = 0.3 (G = E / 2.6);
  the vertex bending stiffness E I / (l0 + l1) is MuJoCo's own;
* stretching is not part of MuJoCo's rod elasticity: edges are held at their length by
  ``<edge equality="true"/>`` soft constraints with solref = "2 dt 1", the stiffest time
  constant MuJoCo accepts (the default 0.02 s lets a hanging soft rod stretch by > 10 %);
* mass lumped as M / (n - 1) per vertex body and half of that at the tip (flexcomp would
  give M / n to every point, pinned ones included);
* clamp: ``<pin id="0 1"/>`` (the first edge and its material frame);
* damping: ``dof_damping = c m`` on each vertex slide joint (rate c [1/s]); no twist damping;
* contacts off; gravity set at run time.

Integrators: ``discrete`` (implicit velocity stepping, MuJoCo's choice for rods), ``RK4`` or
``Euler`` (explicit in the rod elasticity); ``implicit``/``implicitfast`` do not support 1-D
rod elasticity in MuJoCo 4.0.

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


def _xml(spec: CableSpec, dt: float, integrator: str) -> str:
    n, seg = spec.n_masses, spec.rest_length
    points = " ".join(f"{i * seg:.17g} 0 0" for i in range(n))
    elements = " ".join(f"{i} {i + 1}" for i in range(n - 1))
    # flexcomp gives every point mass/npoint: ask for M/(n-1) per point (an interior node's share)
    return f"""
<mujoco model="cantilever">
  <option timestep="{dt:.17g}" integrator="{integrator}" gravity="0 0 0"/>
  <worldbody>
    <flexcomp name="rod" type="direct" dim="1" point="{points}" element="{elements}"
              radius="{spec.diameter / 2:.17g}" mass="{spec.mass * n / (n - 1):.17g}">
      <edge equality="true" solref="{2.0 * dt:.17g} 1"/>
      <elasticity young="{spec.youngs_modulus:.17g}" poisson="{POISSON}"/>
      <contact contype="0" conaffinity="0"/>
      <pin id="0 1"/>
    </flexcomp>
  </worldbody>
</mujoco>"""


class MujocoRod:
    """:class:`bullet_dlo.bench.peers.PeerRod` for MuJoCo; use it as a context manager to capture warnings."""

    name = "mujoco"

    def __init__(self, spec: CableSpec, dt: float, integrator: str = "discrete") -> None:
        n = spec.n_masses
        self.model = mujoco.MjModel.from_xml_string(_xml(spec, dt, integrator))
        self._tip = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, f"rod_{n - 1}")
        self.model.body_mass[self._tip] = spec.mass / (2.0 * (n - 1))  # the tip node carries half a segment
        self.data = mujoco.MjData(self.model)
        mujoco.mj_setConst(self.model, self.data)
        slide = mujoco.mjtJoint.mjJNT_SLIDE
        self._dofs = np.array([self.model.jnt_dofadr[j] for j in range(self.model.njnt)
                               if self.model.jnt_type[j] == slide], dtype=int)
        self._dof_mass = np.array([self.model.body_mass[self.model.dof_bodyid[k]] for k in self._dofs])
        self._bad = [int(getattr(mujoco.mjtWarning, w)) for w in _BAD_STATE]
        self.warnings: list[str] = []
        self._previous_hook = None
        solref = self.model.eq_solref[0]
        self.note = (f"integrator={integrator}; flexcomp dim=1 direct, {n} points, radius=d/2, young=E, "
                     f"poisson={POISSON}, edge equality (soft, solref {solref[0]:.3g} {solref[1]:.3g}), lumped mass "
                     "M/(n-1) per free vertex and half at the tip, pin id='0 1'")

    def __enter__(self) -> "MujocoRod":
        self._previous_hook = mujoco.get_mju_user_warning()
        mujoco.set_mju_user_warning(self.warnings.append)
        return self

    def __exit__(self, *exc: object) -> None:
        mujoco.set_mju_user_warning(self._previous_hook)

    def set_gravity(self, g: float) -> None:
        self.model.opt.gravity[:] = (0.0, 0.0, -g)

    def set_damping(self, rate: float) -> None:
        self.model.dof_damping[self._dofs] = rate * self._dof_mass

    def step(self) -> None:
        mujoco.mj_step(self.model, self.data)

    def refresh(self) -> None:
        mujoco.mj_forward(self.model, self.data)  # body positions of the current state

    def zero_velocities(self) -> None:
        self.data.qvel[:] = 0.0

    def positions(self) -> np.ndarray:
        return self.data.flexvert_xpos.T

    def tip_z(self) -> float:
        return float(self.data.xpos[self._tip, 2])

    def diverged(self) -> bool:
        """MuJoCo's bad-state warnings (it then silently resets the state) or non-finite velocities."""
        return any(self.data.warning[w].number > 0 for w in self._bad) or not np.isfinite(self.data.qvel).all()
