"""A cable inside PyBullet: one Bullet sphere per mass, moved by MSD forces from the core.

Contact (``contact`` option): with ``model`` (the default for the implicit integrators) the
cable's spheres do not collide in Bullet; contacts with the world's bodies are detected from the
bodies' shapes before each step (nodes as spheres, segments as capsules of the cable radius, see
:mod:`bullet_dlo.bullet.contact`) and enter the implicit step as stiff penalties with anchored
Coulomb friction (:mod:`bullet_dlo.core.kernels.contact`); their reactions are applied to the
touched dynamic bodies (two-way), and they are reported per contact and per body
(:meth:`BulletCable.contact_forces`, :meth:`BulletCable.body_forces`). With ``bullet`` (the
default for the explicit integrators, whose steps cannot carry a stiff penalty) Bullet resolves
the spheres' contacts as below (steps 3-5).

Stepping order of one Bullet step (``BulletWorld.step`` drives it; the kernels are in
:mod:`bullet_dlo.bullet.kernels`):

1. plan (done at the end of the previous step): the core integrator advances the model's
   state (x, v) -> (x', v') over the Bullet step h in ``substeps`` steps, held ends following
   their move tables or the measured gripper poses;
2. forces: each sphere gets the external force that makes Bullet's semi-implicit update land
   on x': F = m ((x' - x)/h - v_b)/h - m g_bullet, v_b Bullet's current sphere velocity
   (:meth:`BulletCable.apply_forces`: one compiled call through :mod:`bullet_dlo.bullet.native`
   where a C compiler is available, else one PyBullet call per sphere);
3. Bullet steps, resolving contacts with everything else;
4. contacts: one ``getContactPoints`` call says which spheres something touched; only those
   are read back (untouched spheres are exactly where step 2 sent them);
5. take over: the model state becomes (x', v'), with the read-back position of each touched
   sphere and its contact velocity change (read - target) added to v';
6. check: the instability detector runs on the new state (cheap checks every
   ``check_every`` steps, the energy balance every ``energy_every``); an unstable cable
   stops here and receives no more forces;
7. record (every ``record_every`` steps) and plan the next step (1).

Steps 5, 6 and 1 are one Numba call (:func:`~bullet_dlo.bullet.kernels.sync_and_advance`).
Without contacts the Bullet trajectory therefore equals the core trajectory of every
integrator (x' is reproduced exactly; v' is kept on our side when the method's x' is not
x + h v'). Bullet clamps body speeds at 100 m/s: only an unstable run gets there.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pybullet as pb

from bullet_dlo.bullet.contact import ContactSet
from bullet_dlo.bullet.native import apply_forces
from bullet_dlo.bullet.kernels import (
    Coupling,
    ExternalHolders,
    StepInput,
    bind,
    end_loads,
    sync_and_advance,
)
from bullet_dlo.core.engine import DetectorOptions, start_detector
from bullet_dlo.core.enums import Contact, EndMode, SelfCollision, Sync, name_of
from bullet_dlo.core.integrators import NewtonOptions, get_integrator, make_stepper
from bullet_dlo.core.kernels.contact import (
    DEFAULT_ALPHA,
    SLIDE,
    make_contacts,
    make_grip,
)
from bullet_dlo.core.kernels.forces import mechanical_energy
from bullet_dlo.core.kernels.holders import empty_samples, sample_holders
from bullet_dlo.core.kernels.monitor import REASONS, STABLE
from bullet_dlo.core.kernels.steppers import make_workspace
from bullet_dlo.core.boundary import holder_plan
from bullet_dlo.core.kernels.twist import grip_section, transport
from bullet_dlo.core.model import CableModel, CableState, end_twist_constants
from bullet_dlo.core.validate import (
    ParameterError,
    check_int,
    check_nonnegative,
    check_positive,
)

SELF_COLLISION = SelfCollision.names()
CONTACT = Contact.names()
CABLE_GROUPS = 0x7FFE  # the collision-group bits of cables (bit 0 is the world's default group)


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

    Create with :meth:`bullet_dlo.bullet.world.BulletWorld.add_cable`. ``x`` [m], ``v`` [m/s]
    (n, 3) are the model's state, ``t`` [s] its time; ``arrays`` its own copy of the model
    arrays (grasp and release change the end conditions in place).
    """

    def __init__(self, world, name: str, model: CableModel, integrator: str, *, state: CableState | None,
                 substeps: int, self_collision: str, sync: str, newton: NewtonOptions,
                 detector: DetectorOptions, record_every: int, color=(0.9, 0.35, 0.1, 1.0),
                 contact: str = "auto", contact_stiffness: float = DEFAULT_ALPHA, contact_damping: float = 0.0):
        self.world = world
        self.name = name
        self.model = model
        self.method = get_integrator(integrator)
        self.substeps = check_int("substeps", substeps, 1)
        self_collision = name_of("self_collision", self_collision, SelfCollision)
        self.sync = name_of("sync", sync, Sync)
        self.self_collision = self_collision
        contact = name_of("contact", contact, Contact)
        implicit = not self.method.explicit
        if contact == "model" and not implicit:
            raise ParameterError(f"contact='model' needs an implicit integrator (implicit_euler, bdf2, "
                                 f"implicit_midpoint), got {integrator!r}")
        self.model_contact = contact == "model" or (contact == "auto" and implicit)
        self.contact_stiffness = check_positive("contact_stiffness", contact_stiffness)
        self.contact_damping = check_nonnegative("contact_damping", contact_damping)
        self.stepper = make_stepper(self.method, world.dt / self.substeps, newton)
        self.record_every = check_int("record_every", record_every, 1)
        st = (state or model.initial_state()).copy()
        n = model.n
        self.t = float(st.t)
        self.steps = 0
        self.arrays = type(model.arrays)(*[np.array(a, copy=True) for a in model.arrays])
        # the samplers write a twisting cable's clamp axes into this cable's own arrays (not the model's)
        tw_normal = self.arrays.tw_normal
        self.plan = holder_plan(model.first, model.last, tw_normal if tw_normal.shape[0] else None)
        zeros = np.zeros((2, 3))
        self.ext = ExternalHolders(active=np.zeros(2, dtype=np.bool_), pos=zeros.copy(), vel=zeros.copy(),
                                   acc=zeros.copy(), omega=zeros.copy(),
                                   dir=self.plan.start_dir.copy(),  # clamp directions until a gripper takes over
                                   normal=self.plan.start_normal.copy())
        self._cp = Coupling(dt=float(world.dt), substeps=self.substeps,
                            gravity=np.asarray(world.gravity, dtype=float), x=st.x.copy(), v=st.v.copy(),
                            v_bullet=st.v.copy(), x_new=np.zeros((n, 3)), v_new=np.zeros((n, 3)),
                            force=np.zeros((n, 3)), samples=empty_samples(), end_force=np.zeros((2, 3)),
                            end_torque=np.zeros((2, 3)), energy=np.zeros(1))
        self.x, self.v = self._cp.x, self._cp.v
        self.ws = make_workspace(n)
        self._no_rows = np.zeros((0, 3))
        self._no_index = np.zeros(0, dtype=np.int64)
        self.radius = 0.5 * model.spec.diameter
        self.body_ids = self._spawn(color, self_collision)
        self._body_array = np.array(self.body_ids, dtype=np.int32)
        self._apply_native = None  # apply_forces's machine code, bound on first use
        self._contact_set: ContactSet | None = None
        self._bullet_collisions_off = False  # disable_bullet_collisions was called
        self._excluded: set[tuple[int, int]] = set()  # dynamic (body, link)s whose Bullet contacts with the spheres are off
        self._bodies_seen = -1  # bodies in the world when the contact set was built
        self._contact_exclusions: dict = {}  # (body, link or None) -> None (all) or node indices: exclude_contact
        self._partners_seen: tuple = ()  # names of the other cables in the contact set
        self.grip = make_grip()  # friction grips of the ends (grip_with_friction), shared by every contact set
        self._no_contacts = make_contacts(n, 1, self.radius, self.grip)
        self._refresh_contact_set()
        samples = self._cp.samples
        sample_holders(self.plan, self.t, world.dt, samples)
        self._detector_options = detector
        self.detector = start_detector(detector, model, self.arrays, self.x, self.v, samples)
        self.status = STABLE
        self.time_to_instability: float | None = None
        self.newton_iterations = 0
        self.newton_failures = 0
        self.contacts_last_step = 0
        self.record = CableRecord()
        self._end_loads = None  # end_loads's machine code, bound on first use
        self._record_row()
        spawn = self._step_input(False, False, self._no_index, self._no_rows, self._no_rows)
        self._sync_and_advance = bind(sync_and_advance, *self._kernel_args(spawn))
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
            pb.changeDynamics(b, -1, linearDamping=0.0, angularDamping=0.0, lateralFriction=spec.dynamic_friction,
                              activationState=pb.ACTIVATION_STATE_DISABLE_SLEEPING, physicsClientId=cid)
        self._group = None
        if self_collision == "none":
            group = self._group = self.world.next_cable_group()
            for b in body:
                pb.setCollisionFilterGroupMask(b, -1, group, 0xFFFF & ~group, physicsClientId=cid)
        elif self_collision == "neighbours" and not self.model_contact:
            # spheres closer than a diameter at rest always touch: never let them collide. (With model
            # contact the cable's own group leaves its mask (disable_bullet_collisions): pair filters
            # would only add work, as PyBullet then asks its filter plugin about every broad-phase pair:
            # 25-40 % of Bullet's step at n = 100-1000.)
            reach = max(1, math.ceil(1.05 * spec.diameter / spec.rest_length))
            for i in range(n):
                for j in range(i + 1, min(n, i + reach + 1)):
                    pb.setCollisionFilterPair(body[i], body[j], -1, -1, 0, physicsClientId=cid)
        return body

    @property
    def handles_cable_contact(self) -> bool:
        """Contacts with other cables are the model's (both cables model contact, neither has
        ``self_collision="none"``); else they stay Bullet's sphere contacts."""
        return self.model_contact and self.self_collision != "none"

    def _partners(self) -> list:
        """The other cables whose contacts with this one the model handles (stable ones)."""
        if not self.handles_cable_contact:
            return []
        return [c for c in self.world.cables.values() if c is not self and c.handles_cable_contact and c.stable]

    def _refresh_contact_set(self) -> None:
        """(Re)read the world's bodies for the contact model when they changed (new obstacles), and the
        other cables it handles contact with."""
        if not self.model_contact:
            return
        alone = len(self.world.cables) <= 1  # (this cable is in it once added): no partners can appear
        if alone and not self._partners_seen and self._bodies_seen == len(self.world.bodies):
            return  # the common case, checked without building the partner list every step
        partners = self._partners()
        names = tuple(c.name for c in partners)
        cid = self.world.client
        count = pb.getNumBodies(physicsClientId=cid)
        if self._bodies_seen == count and names == self._partners_seen:
            return
        spec = self.model.spec
        self._bodies_seen = count
        self._partners_seen = names
        # every body of the world but the cables' spheres (the robot arms too, whoever loaded them)
        spheres = set(self.world._owners) | set(self.body_ids)
        bodies = [b for b in (pb.getBodyUniqueId(i, physicsClientId=cid) for i in range(count)) if b not in spheres]
        self._contact_set = ContactSet(cid, bodies, self.model.n, self.radius,
                                       spec.static_friction, spec.dynamic_friction, self.contact_stiffness,
                                       self.contact_damping, self_contact=self.self_collision != "none",
                                       grip=self.grip, native=self.world.native_handle(), others=partners,
                                       exclude={**{(b, None): None for b in self.world.no_cable_contact},
                                                **self._contact_exclusions},
                                       rest_length=float(spec.rest_length),
                                       segments=(self.arrays.k_stretch, self.arrays.rest_length, self.arrays.k_bend))
        if self._bullet_collisions_off:
            self._exclude_model_bodies()

    def exclude_contact(self, body: int, link: int | None = None, nodes=None) -> None:
        """Leave ``body`` (its link ``link``; None: every link) out of the cable's contact model: entirely
        (``nodes`` None) or only for the given node indices and the segments next to them (a gripper holding
        an end: its fingers do not push the held end, the rest of the cable still meets them). Bullet's own
        collisions of those spheres with it are switched off too: the cable passes through. Only for
        ``contact="model"``."""
        cid = self.world.client
        n = self.model.n
        try:
            pb.getBodyInfo(int(body), physicsClientId=cid)
        except pb.error:
            raise ParameterError(f"exclude_contact: no body {body} in this world") from None
        if link is not None and not -1 <= link < pb.getNumJoints(body, physicsClientId=cid):
            raise ParameterError(f"exclude_contact: link must be in [-1, {pb.getNumJoints(body, physicsClientId=cid) - 1}]"
                                 f" or None, got {link}")
        if nodes is not None:
            idx = [int(i) for i in nodes]
            if any(not -n <= i < n for i in idx):
                raise ParameterError(f"exclude_contact: nodes must be in [{-n}, {n - 1}], got {idx}")
            nodes = {i % n for i in idx}
        self._contact_exclusions[(int(body), link)] = nodes
        spheres = [self.body_ids[i] for i in sorted(nodes)] if nodes is not None else self.body_ids
        for lk in ([link] if link is not None else range(-1, pb.getNumJoints(body, physicsClientId=cid))):
            for b in spheres:
                pb.setCollisionFilterPair(b, int(body), -1, lk, 0, physicsClientId=cid)
        self._bodies_seen = -1  # rebuild the contact set
        self._refresh_contact_set()

    def _exclude_model_bodies(self) -> None:
        """Keep Bullet from also colliding the spheres with the dynamic bodies the contact model handles.

        The collision-group masks of :meth:`disable_bullet_collisions` keep static bodies away from the
        spheres, but not dynamic ones (measured: a dynamic box, created before or after the cable, had
        Bullet contacts with the spheres under it): such a body was then pushed by the model's reaction
        and by Bullet's sphere contacts at once, and the spheres it pressed were read back pushed into
        the ground. One pair filter per sphere and body, once per body.
        """
        cs, cid = self._contact_set, self.world.client
        # a URDF's child links too, static ones included: Bullet collided the spheres with them (measured)
        bullet_sees = cs.dynamic | (cs.links >= 0)
        for body, link in sorted(set(zip(cs.body_ids[bullet_sees].tolist(), cs.links[bullet_sees].tolist()))
                                 - self._excluded):
            for b in self.body_ids:
                pb.setCollisionFilterPair(b, body, -1, link, 0, physicsClientId=cid)
            self._excluded.add((body, link))

    def disable_bullet_collisions(self) -> None:
        """Leave the world's bodies, the cable's self-contact and its contacts with the other cables the
        model handles (:attr:`handles_cable_contact`) to the contact model: in Bullet the spheres collide
        only with the spheres of cables whose contacts stay Bullet's (``contact="bullet"`` or
        ``self_collision="none"``)."""
        own = self._group or self.world.next_cable_group()
        mask = CABLE_GROUPS & ~own
        if self.handles_cable_contact:
            mask &= ~self.world._model_cable_groups  # (a pair collides only if each one's mask has the other)
            self.world._model_cable_groups |= own
        for b in self.body_ids:
            pb.setCollisionFilterGroupMask(b, -1, own, mask, physicsClientId=self.world.client)
        self._bullet_collisions_off = True
        if self._contact_set is not None:
            self._exclude_model_bodies()

    @property
    def contacts(self):
        """The core Contacts of the coming step (empty arrays when Bullet handles contact)."""
        return self._contact_set.contacts if self._contact_set is not None else self._no_contacts

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
        if self.model_contact:
            self._refresh_contact_set()
            cp = self._cp
            x0, v0 = (cp.x_new, cp.v_new) if do_sync else (cp.x, cp.v)  # the state this step starts from
            self.contacts_last_step = self._contact_set.update(x0, v0, self.arrays.mass, self.stepper.h,
                                                               self.world.dt, do_sync)
        record = do_sync and self.steps % self.record_every == 0
        inp = self._step_input(do_sync, record, idx_arr, pos, vel)
        active = self.grip.active
        gripped = (bool(active[0]), bool(active[1]))
        status, its, ok = self._sync_and_advance(*self._kernel_args(inp))
        for end in (0, 1):
            if gripped[end] and not active[end]:  # the end slid out of the gripper
                self._let_go(end)
        self.newton_iterations += its
        self.newton_failures += 0 if ok else 1
        if status != STABLE:
            self.status = status
            self.time_to_instability = self.t
        if record:
            self._record_row(from_kernel=True)
        elif do_sync and status != STABLE:
            self._record_row()

    def _step_input(self, do_sync: bool, record: bool, index: np.ndarray, pos: np.ndarray,
                    vel: np.ndarray) -> StepInput:
        """What the kernel needs from this step: time, flags, the touched spheres' read-back state."""
        det = self.detector
        has_prev = self.steps > 0 and self.contacts.impact[0] == 0  # BDF2 restarts after an impact
        return StepInput(self.t, has_prev, do_sync, do_sync and self.steps % det.check_every == 0,
                         do_sync and self.steps % det.energy_every == 0, record, index, pos, vel)

    def _kernel_args(self, inp: StepInput) -> tuple:
        """Arguments of :func:`~bullet_dlo.bullet.kernels.sync_and_advance` (the same objects every step)."""
        return self.stepper, self.arrays, self.plan, self.ext, self._cp, self.ws, self.detector, inp, self.contacts

    def apply_forces(self) -> None:
        """Apply the forces planned for the coming Bullet step (nothing once unstable)."""
        if self.status != STABLE:
            return
        native = self.world.native_handle()
        if native:  # one compiled call instead of n PyBullet calls
            args = (native, self._body_array, self._cp.force, self.x)
            if self._apply_native is None:
                self._apply_native = bind(apply_forces, *args)
            self._apply_native(*args)
        else:
            cid = self.world.client
            apply = pb.applyExternalForce
            frame = pb.WORLD_FRAME
            for b, f, pos in zip(self.body_ids, self._cp.force.tolist(), self.x.tolist()):
                apply(b, -1, f, pos, frame, cid)  # positional: keyword parsing costs 50 % more per call
        if self._contact_set is not None:
            self._contact_set.apply_to_bodies()

    def sync_after_step(self, touched) -> None:
        """Take over Bullet's step: ``touched`` holds the spheres that had contacts (read back)."""
        if self.status == STABLE:
            self._advance(sorted(touched) if touched else [])

    def _record_row(self, from_kernel: bool = False) -> None:
        """Append a row; ``from_kernel``: the step's kernel wrote its end loads and energy (``inp.record``)."""
        # sample 0 of the held-end samples is the current time (they are planned for the coming step)
        rec, cp = self.record, self._cp
        rec.t.append(self.t)
        rec.x.append(self.x.copy())
        rec.v.append(self.v.copy())
        if from_kernel:
            rec.end_forces.append(cp.end_force.copy())
            rec.energy.append(float(cp.energy[0]))
        else:
            rec.end_forces.append(self.end_forces())
            rec.energy.append(mechanical_energy(self.arrays, self.x, self.v, cp.samples.dir[0]))

    def add_point_mass(self, node: int, mass: float) -> None:
        """Hang a weight of ``mass`` [kg] (> 0) on node ``node`` (its sphere gets heavier too).

        Meant for set-up (before stepping): the instability detector restarts from the new state.
        """
        n = self.model.n
        if not -n <= node < n:
            raise ParameterError(f"node must be in [0, {n - 1}], got {node}")
        node = node % n
        self.arrays.mass[node] += check_positive("point mass", mass)
        pb.changeDynamics(self.body_ids[node], -1, mass=float(self.arrays.mass[node]),
                          physicsClientId=self.world.client)
        self.detector = start_detector(self._detector_options, self.model, self.arrays, self.x, self.v,
                                       self._cp.samples)
        self._replan()

    # ----- grasping -----------------------------------------------------------------------
    def hold_externally(self, end: int, mode: str = "clamped") -> None:
        """Make end ``end`` (0 first, 1 last) follow poses given by :meth:`set_external_pose`.

        mode: ``clamped`` (position and tangent held, like a gripper) or ``pinned``.
        The clamp's bending stiffness is the spec's half-segment value (see CableSpec).
        """
        if mode not in (EndMode.CLAMPED, EndMode.PINNED):
            raise ParameterError(f"grasp mode must be one of clamped, pinned, got {mode!r}")
        mode = str(EndMode(mode))
        a, spec, n = self.arrays, self.model.spec, self.model.n
        node = 0 if end == 0 else n - 1
        a.held[node] = True
        a.k_bend[node] = spec.k_bend_clamp if mode == "clamped" else 0.0
        a.c_bend[node] = a.k_bend[node] * spec.internal_damping  # the clamp's Kelvin-Voigt damper
        self._hold_twist(end, mode)
        self.ext.active[end] = True
        self.grip.active[end] = False
        self._replan()

    def grip_with_friction(self, end: int, normal_force: float, static_friction: float, dynamic_friction: float,
                           reach: float = 0.02) -> None:
        """Hold end ``end`` (0 first, 1 last) by a friction grip on the pose given by :meth:`set_external_pose`.

        Two fingers pinch the end node with ``normal_force`` F_n [N] (> 0) each: along the
        gripper's axis (the clamp direction) the grip holds up to 2 static_friction F_n, then the end
        slips along the gripper against 2 dynamic_friction F_n (0 <= dynamic_friction <= static_friction); across
        it a stiff spring keeps the end on the axis, and the clamp's bending spring holds the
        tangent. The end leaves the gripper (the grip is lost) after slipping ``reach`` [m] (> 0).
        Needs an implicit integrator (the grip is part of its step). Call it with the gripper's
        pose set; the end starts at rest on the gripper's axis where it is now.
        """
        if self.method.explicit:
            raise ParameterError("a friction grip needs an implicit integrator (implicit_euler, bdf2, "
                                 "implicit_midpoint)")
        if end not in (0, 1):
            raise ParameterError(f"end must be 0 or 1, got {end!r}")
        f_n = check_positive("grip normal force", normal_force)
        mu_s = check_nonnegative("grip_static_friction", static_friction)
        mu_d = check_nonnegative("grip_dynamic_friction", dynamic_friction)
        if mu_d > mu_s:
            raise ParameterError(f"grip_dynamic_friction must be in [0, grip_static_friction {mu_s}], got {mu_d}")
        a, n, g = self.arrays, self.model.n, self.grip
        node = 0 if end == 0 else n - 1
        a.held[node] = False
        a.k_bend[node] = self.model.spec.k_bend_clamp
        a.c_bend[node] = a.k_bend[node] * self.model.spec.internal_damping
        self._hold_twist(end, "clamped")  # the pinching fingers hold the roll as they hold the tangent
        self.ext.active[end] = True
        g.k_ax[end] = g.k_lat[end] = self.contact_stiffness * a.mass[node] / self.stepper.h ** 2
        g.cap_s[end], g.cap_d[end] = 2.0 * mu_s * f_n, 2.0 * mu_d * f_n
        g.reach[end] = check_positive("grip reach", reach)
        g.offset[end] = float(np.dot(self.x[node] - self.ext.pos[end], self.ext.dir[end]))
        g.state[end] = 0
        g.active[end] = True
        self._replan()

    def grip_state(self) -> dict[str, np.ndarray]:
        """The friction grips now: active (2,) bool, sliding (2,) bool, slip [m] (2,) (the anchor's
        offset along the gripper axis), force [N] (2, 3) the grip exerts on the cable."""
        g = self.grip
        return {"active": g.active.copy(), "sliding": (g.state == SLIDE) & g.active, "slip": g.offset.copy(),
                "force": g.force.copy()}

    def _let_go(self, end: int) -> None:
        a, n = self.arrays, self.model.n
        node = 0 if end == 0 else n - 1
        a.held[node] = False
        a.k_bend[node] = a.c_bend[node] = 0.0
        self._hold_twist(end, "free")
        self.ext.active[end] = False
        self.grip.active[end] = False

    def _hold_twist(self, end: int, mode: str) -> None:
        """A cable with a material frame: end ``end``'s twist spring for ``mode`` (a clamp holds the twist,
        a pin or a free end does not: :func:`~bullet_dlo.core.model.end_twist_constants`); a clamp takes the
        section as it is now (no twist added, :func:`~bullet_dlo.core.kernels.twist.grip_section`) and its
        axis becomes the holder's ``ext.normal``, which the holder then turns (the gripper's roll)."""
        a = self.arrays
        if not a.tw_k_twist.shape[0]:
            return
        spec = self.model.spec
        node = 0 if end == 0 else self.model.n - 1
        a.tw_k_twist[node], a.tw_k_aniso[node] = end_twist_constants(spec, mode)
        a.tw_c_twist[node] = a.tw_k_twist[node] * spec.internal_damping
        if mode == "clamped":
            self.ext.normal[end] = grip_section(a, self.x, self.ext.dir, end)

    def release(self, end: int) -> None:
        """Let end ``end`` go: it becomes free and no longer follows any holder."""
        self._let_go(end)
        self._replan()

    def set_external_pose(self, end: int, position, velocity, acceleration, omega, direction, normal=None) -> None:
        """Measured pose of the holder of ``end`` now, world frame: position [m], velocity [m/s],
        acceleration [m/s^2], angular velocity omega [rad/s], each (3,); direction: clamp tangent
        pointing along the cable from its first to its last mass (normalised here); normal: the holder's
        section axis d1 (3,), normal to direction, that a clamp of a cable with a material frame holds
        (its roll about the cable); None: it is carried from the last pose onto the new direction without
        roll (parallel transport). Only a cable with a material frame reads it."""
        e = self.ext
        if self.arrays.tw_k_twist.shape[0]:
            if normal is None:
                d_old = e.dir[end].copy()
                d_new = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
                transport(e.normal[end].copy(), d_old, d_new, e.normal[end])
            else:
                e.normal[end] = normal
        e.pos[end], e.vel[end], e.acc[end], e.omega[end] = position, velocity, acceleration, omega
        dx, dy, dz = direction  # normalised in scalars: this runs twice per coupled step
        scale = 1.0 / math.sqrt(dx * dx + dy * dy + dz * dz)
        e.dir[end] = (dx * scale, dy * scale, dz * scale)

    def holder_positions(self) -> np.ndarray:
        """Positions [m] of the external holders (e.g. grasp frames) as last measured, (2, 3)."""
        return self.ext.pos.copy()

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
        """Force [N] the cable exerts on each held or gripped end now, (2, 3) (first, last)."""
        return self.end_loads()[0]

    def end_loads(self) -> tuple[np.ndarray, np.ndarray]:
        """Force [N] (the reaction of a friction grip's force where one holds the end) and clamp torque
        [N m] the cable exerts on each held end now, (2, 3) each (first, last): one kernel call."""
        force, torque = np.empty((2, 3)), np.empty((2, 3))
        args = (self.arrays, self.x, self.v, self._cp.samples, self.grip, force, torque)
        if self._end_loads is None:
            self._end_loads = bind(end_loads, *args)
        self._end_loads(*args)
        return force, torque

    def planned_end_loads(self) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`end_loads` as the last step's kernel left them for the coming step, without a call:
        views (2, 3) each, valid until the next step while an end is held externally (the grasp
        coupling's per-step read; the kernel skips them for cables no gripper holds)."""
        return self._cp.end_force, self._cp.end_torque

    def contact_forces(self) -> dict[str, np.ndarray]:
        """The model's contacts of the step just planned, with the forces on the cable [N]: keys body,
        node (k, 2), weight (k, 2), point [m], normal, gap [m] (k,), normal_force (k,), friction (k, 3),
        force (k, 3), sliding (k,) (see :meth:`bullet_dlo.bullet.contact.ContactSet.per_contact`); empty when Bullet
        handles contact."""
        if self._contact_set is None:
            z = np.zeros((0, 3))
            return {"body": np.zeros(0, np.int64), "node": np.zeros((0, 2), np.int64), "gap": np.zeros(0),
                    "weight": np.zeros((0, 2)),
                    "point": z, "normal": z, "normal_force": np.zeros(0), "friction": z, "force": z,
                    "sliding": np.zeros(0, bool)}
        return self._contact_set.per_contact(self.x)

    def body_forces(self) -> dict[int, np.ndarray]:
        """Total force [N] the cable exerts on each body it touches, {body id: (3,)}."""
        return self._contact_set.per_body(self.x) if self._contact_set is not None else {}

    def end_moments(self) -> np.ndarray:
        """Torque [N m] the cable exerts on each clamp now, (2, 3) (zero rows for unclamped ends)."""
        return self.end_loads()[1]

    def bullet_positions(self) -> np.ndarray:
        """Sphere positions read from Bullet [m], (n, 3) (n PyBullet calls: for checks, not loops)."""
        cid = self.world.client
        return np.array([pb.getBasePositionAndOrientation(b, physicsClientId=cid)[0] for b in self.body_ids])
