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

Bullet spheres as proxies (``bullet_spheres="auto"``, the default): a cable whose contacts the model owns
(``contact="model"``, ``sync="contacts"``, no GUI) and whose spheres nothing in Bullet may collide with (every
other cable in the world handles cable contact through the model as well: :attr:`BulletCable.handles_cable_contact`
of both) does not need Bullet to move its spheres: untouched spheres are never read back (step 4), so the model's
trajectory does not depend on them. Its spheres are then parked asleep in Bullet (no sphere forces, no
integration, and Bullet's broad phase no longer walks their padded boxes against each other every step: that walk
grew as n^1.5 and was 60 % of the step at n = 1000), and their poses are written into Bullet only when something
reads them: :meth:`BulletCable.bullet_positions`, :meth:`BulletCable.sync_bullet_spheres`,
:meth:`~bullet_dlo.bullet.world.BulletWorld.sync_bullet_spheres`, a rendered frame
(:func:`bullet_dlo.render.camera.render_frame`) and the spawn check of a new cable. A direct PyBullet read of a
proxy sphere (``getBasePositionAndOrientation``, ``getClosestPoints`` with it) returns its pose as of the last such
sync and a velocity of zero; the model's ``x`` and ``v`` are the cable's state. The rule is re-taken whenever a
cable joins the world (a ``contact="bullet"`` cable wakes the others' spheres with their current state: Bullet then
moves them as before, exactly where the model is). ``bullet_spheres="live"`` keeps the spheres moving in Bullet
every step.

Steps 5, 6 and 1 are one Numba call (:func:`~bullet_dlo.bullet.kernels.sync_and_advance`), made by the
cable's :class:`~bullet_dlo.bullet.solver.CableSolver`.

Parts: :class:`BulletCable` is the facade; it holds the cable's model (read only), its control
(:class:`~bullet_dlo.core.model.CableControl`: end holds, clamp springs, holder poses, grips, external forces)
and its state (``x``, ``v``, ``t``, ``twist``), the Bullet spheres, the solver
(:class:`~bullet_dlo.bullet.solver.CableSolver`: stepper, scratch, held ends' plan, detector, the coupled
step's buffers), the contact set (:class:`~bullet_dlo.bullet.cable_contacts.CableContacts`) and the record
(:class:`~bullet_dlo.bullet.recorder.CableRecord`).
Without contacts the Bullet trajectory therefore equals the core trajectory of every
integrator (x' is reproduced exactly; v' is kept on our side when the method's x' is not
x + h v'). Bullet clamps body speeds at 100 m/s: only an unstable run gets there.
"""
from __future__ import annotations

import math
import warnings
import numpy as np
import pybullet as pb

from bullet_dlo.bullet import body_energy, held_bodies
from bullet_dlo.bullet.cable_contacts import CABLE_GROUPS, CableContacts  # noqa: F401 (CABLE_GROUPS: its old home)
from bullet_dlo.bullet.contact import ContactSet
from bullet_dlo.bullet.native import apply_forces, kernel_api
from bullet_dlo.bullet.kernels import StepInput, bind, end_loads
from bullet_dlo.bullet.recorder import CableRecord  # noqa: F401 (its home before the split)
from bullet_dlo.bullet.solver import CableSolver
from bullet_dlo.core.engine import DetectorOptions
from bullet_dlo.core.enums import Contact, EndMode, SelfCollision, Sync, name_of
from bullet_dlo.core.integrators import NewtonOptions, get_integrator
from bullet_dlo.core.kernels.contact import DEFAULT_ALPHA, SLIDE
from bullet_dlo.core.kernels.forces import mechanical_energy
from bullet_dlo.core.kernels.monitor import BODY_ENERGY, REASONS, STABLE
from bullet_dlo.core.kernels.twist import grip_section, transport
from bullet_dlo.core.model import CableControl, CableModel, CableState, end_twist_constants, kernel_arrays, with_arrays
from bullet_dlo.core.validate import (
    ParameterError,
    check_friction_order,
    check_int,
    check_nonnegative,
    check_positive,
)

SELF_COLLISION = SelfCollision.names()
BULLET_SPHERES = ("auto", "live")
ROLL_WITHOUT_OMEGA = 0.1  # [rad] roll of a held section given with omega zero before set_external_pose warns
# a parked proxy sphere: may sleep, is not woken by Bullet (its contacts or its velocity), asleep now
_PARK = pb.ACTIVATION_STATE_ENABLE_SLEEPING | pb.ACTIVATION_STATE_DISABLE_WAKEUP
_LIVE = pb.ACTIVATION_STATE_ENABLE_WAKEUP | pb.ACTIVATION_STATE_DISABLE_SLEEPING  # then WAKE_UP (a call of its own)
CONTACT = Contact.names()


class BulletCable:
    """A cable's spheres in a Bullet world and the state the MSD model keeps for them.

    Create with :meth:`bullet_dlo.bullet.world.BulletWorld.add_cable`. ``x`` [m], ``v`` [m/s]
    (n, 3) are the model's state, ``t`` [s] its time, ``twist`` its material frame's state
    (:class:`~bullet_dlo.core.kernels.twist.TwistState`); ``model`` the cable's model (read only);
    ``control`` (:class:`~bullet_dlo.core.model.CableControl`) what holds it: grasp, release, grips and
    holder poses write it, and so may the user (``control.f_ext`` [N], or :meth:`set_external_force`);
    ``arrays`` the kernels' view of the three (:class:`~bullet_dlo.core.model.KernelArrays`).
    """

    def __init__(self, world, name: str, model: CableModel, integrator: str, *, state: CableState | None,
                 substeps: int, self_collision: str, sync: str, newton: NewtonOptions,
                 detector: DetectorOptions, record_every: int, color=(0.9, 0.35, 0.1, 1.0),
                 contact: str = "auto", contact_stiffness: float = DEFAULT_ALPHA, contact_damping: float = 0.0,
                 bullet_spheres: str = "auto"):
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
        if bullet_spheres not in BULLET_SPHERES:
            raise ParameterError(f"bullet_spheres must be one of {', '.join(BULLET_SPHERES)}, got {bullet_spheres!r}")
        self.bullet_spheres = bullet_spheres
        self.proxy = False  # the spheres are parked proxies now (see the module doc; BulletWorld re-takes the rule)
        self._mirrored = -1  # the step whose positions the parked spheres hold in Bullet
        self._fresh: set[int] = set()  # spheres parked since the last step (see _hold_fresh)
        self._waking = False  # woken from proxies before the last step (see _finish_waking)
        self._plain_args = None  # plain_steps' packed arguments and loop (plain_steps._packed)
        self.contact_damping = check_nonnegative("contact_damping", contact_damping)
        self.record_every = check_int("record_every", record_every, 1)
        st = (state or model.initial_state()).copy()
        self.t = float(st.t)
        self.steps = 0
        self.control: CableControl = model.control()  # end holds, clamp springs, holder poses, grips, f_ext
        self.twist = st.twist if st.twist is not None else model.twist_state()
        self.arrays = kernel_arrays(model.arrays, self.control, self.twist)
        self.ext = self.control.holders  # measured holder poses (set_external_pose)
        self._unseen_roll = [0.0, 0.0]  # [rad] per end: roll given by set_external_pose with omega zero
        self._roll_warned: set[int] = set()
        # the stepper, its scratch, the held ends' plan, the detector and the Bullet step's buffers
        self.solver = CableSolver(model, self.arrays, self.control, st, method=self.method, newton=newton,
                                  detector=detector, dt=world.dt, substeps=self.substeps, gravity=world.gravity)
        self.x, self.v = self._cp.x, self._cp.v  # the state (views: the solver advances them in place)
        self._no_rows = np.zeros((0, 3))
        self._no_index = np.zeros(0, dtype=np.int64)
        self.radius = 0.5 * model.spec.diameter
        self.body_ids = self._spawn(color, self_collision)
        self._body_array = np.array(self.body_ids, dtype=np.int32)
        self._apply_native = None  # apply_forces's machine code, bound on first use
        self.grip = self.control.grip  # friction grips of the ends (grip_with_friction), shared by every contact set
        self.contact = CableContacts(self)  # the contact set, its exclusions, Bullet's filters
        self.contacts_last_step = 0
        self.record = CableRecord(self._cp.rows)  # (the step's kernel writes recorded rows into its block)
        self._end_loads = None  # end_loads's machine code, bound on first use
        # a twisting cable: its twist state at self.t (the plan advances self.twist to t + dt in place), kept for
        # state(); None until the first plan (_advance), end_loads() then reads the kernel's loads at self.t
        self._twist_now = None
        self._twist_planned = False  # self.twist is at t + dt (a plan advanced it since _twist_now was taken)
        self._record_row()
        self._advance(None)  # plan the first step

    # ----- the solver's parts, by their names of before the split ----------------------------
    @property
    def stepper(self):
        """The integrator's step (:class:`~bullet_dlo.core.kernels.steppers.Stepper`; h = dt / substeps [s])."""
        return self.solver.stepper

    @property
    def ws(self):
        """The step kernels' scratch (:class:`~bullet_dlo.core.kernels.steppers.Workspace`)."""
        return self.solver.workspace

    @property
    def plan(self):
        """The held ends' move tables (:class:`~bullet_dlo.core.kernels.holders.HolderPlan`)."""
        return self.solver.plan

    @property
    def _cp(self):
        return self.solver.coupling

    @property
    def detector(self):
        """The instability detector (:class:`~bullet_dlo.core.kernels.monitor.Detector`)."""
        return self.solver.detector

    @property
    def status(self) -> int:
        """STABLE, or the code of why the detector stopped the cable (:data:`~bullet_dlo.core.kernels.monitor.REASONS`)."""
        return self.solver.status

    @property
    def time_to_instability(self) -> float | None:
        """When the detector stopped the cable [s] (None: stable)."""
        return self.solver.time_to_instability

    @property
    def newton_iterations(self) -> int:
        """Newton iterations of all steps so far."""
        return self.solver.newton_iterations

    @property
    def newton_failures(self) -> int:
        """Steps whose Newton solve did not converge."""
        return self.solver.newton_failures

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

    # ----- the spheres in Bullet: live or parked proxies -----------------------------------------
    def proxy_allowed(self) -> bool:
        """This cable's own part of the proxy rule (module doc): ``bullet_spheres="auto"``, the model's
        contact, ``sync="contacts"`` (``always`` reads every sphere back) and no GUI (its viewer draws Bullet's
        poses every frame). :meth:`~bullet_dlo.bullet.world.BulletWorld.update_proxies` adds the other cables'."""
        return (self.bullet_spheres == "auto" and self.model_contact and self.sync == "contacts"
                and not getattr(self.world, "gui", False))

    def set_proxy(self, on: bool) -> None:
        """Park the spheres as proxies (``on``: their poses from the model's x, asleep) or make them live again
        (poses x, velocities the ones the coming step's forces were planned from, awake): the model's trajectory
        is the same either way. Called by the world when it re-takes the rule."""
        if on == self.proxy:
            return
        if on:
            self._park(range(self.model.n))
        else:
            self._fresh.clear()
            cid = self.world.client
            for b, pos, vel in zip(self.body_ids, self.x.tolist(), self._cp.v_bullet.tolist()):
                pb.resetBasePositionAndOrientation(b, pos, (0.0, 0.0, 0.0, 1.0), physicsClientId=cid)
                pb.resetBaseVelocity(b, vel, (0.0, 0.0, 0.0), physicsClientId=cid)
                pb.changeDynamics(b, -1, activationState=_LIVE, physicsClientId=cid)
                pb.changeDynamics(b, -1, activationState=pb.ACTIVATION_STATE_WAKE_UP, physicsClientId=cid)
                pb.resetBaseVelocity(b, vel, (0.0, 0.0, 0.0), physicsClientId=cid)  # (awake now: it keeps it)
            self._waking = True
        self.proxy = on

    def _finish_waking(self) -> None:
        """Bullet integrates a woken body only from its second step: put the spheres where the step they stood
        still would have sent them (x' and the step's velocity), as if Bullet had moved them."""
        cp, cid, h = self._cp, self.world.client, self.world.dt
        for b, x0, x1 in zip(self.body_ids, self.x.tolist(), cp.x_new.tolist()):
            pb.resetBasePositionAndOrientation(b, x1, (0.0, 0.0, 0.0, 1.0), physicsClientId=cid)
            pb.resetBaseVelocity(b, [(p1 - p0) / h for p0, p1 in zip(x0, x1)], (0.0, 0.0, 0.0), physicsClientId=cid)
        self._waking = False

    def _park(self, nodes) -> None:
        """Write the model's positions of ``nodes`` into their spheres and put them to sleep (a pose reset wakes
        a body; sleeping zeroes its velocity). Two activation calls: sleep is refused while sleeping is off."""
        cid = self.world.client
        x = self.x
        for i in nodes:
            b = self.body_ids[i]
            pb.resetBasePositionAndOrientation(b, x[i].tolist(), (0.0, 0.0, 0.0, 1.0), physicsClientId=cid)
            pb.changeDynamics(b, -1, activationState=_PARK, physicsClientId=cid)
            pb.changeDynamics(b, -1, activationState=pb.ACTIVATION_STATE_SLEEP, physicsClientId=cid)
            self._fresh.add(i)
        self._mirrored = self.steps

    def _hold_fresh(self) -> None:
        """Bullet puts a body to sleep only after its next step, which still lets it fall g h^2 from rest (0.17 mm
        at 240 Hz): the spheres parked since the last step get their weight's opposite for that step."""
        cid = self.world.client
        mass, g = self.model.arrays.mass, self.world.gravity
        for i in self._fresh:
            pb.applyExternalForce(self.body_ids[i], -1, (-mass[i] * g).tolist(), (0.0, 0.0, 0.0), pb.LINK_FRAME,
                                  physicsClientId=cid)  # (a parked sphere's frame is the world's, unrotated)
        self._fresh.clear()

    def sync_bullet_spheres(self) -> None:
        """Proxy spheres: write the model's positions into Bullet now (n pose resets, ~10-25 us each; once per
        step at most), so that direct PyBullet reads of them (poses, closest points, images) see the cable where
        it is. Live spheres are there already: nothing to do."""
        if self.proxy and self._mirrored != self.steps:
            self._park(range(self.model.n))

    @property
    def handles_cable_contact(self) -> bool:
        """Contacts with other cables are the model's (both cables model contact, neither has
        ``self_collision="none"``); else they stay Bullet's sphere contacts."""
        return self.model_contact and self.self_collision != "none"

    def _partners(self) -> list:
        """The other cables whose contacts with this one the model handles (stable ones)."""
        return self.contact.partners()

    def _refresh_contact_set(self) -> None:
        """(Re)read the world's bodies for the contact model when they changed (:meth:`CableContacts.refresh`)."""
        self.contact.refresh()

    def exclude_contact(self, body: int, link: int | None = None, nodes=None, rebuild: bool = True) -> None:
        """Leave ``body`` (its link ``link``; None: every link) out of the cable's contact model: entirely
        (``nodes`` None) or only for the given node indices and the segments next to them (a gripper holding
        an end: its fingers do not push the held end, the rest of the cable still meets them). Bullet's own
        collisions of those spheres with it are switched off too: the cable passes through. Only for
        ``contact="model"``. ``rebuild`` False: the contact set is rebuilt at the cable's next step, or by the next
        call with ``rebuild`` True (several exclusions, one rebuild)."""
        self.contact.exclude(body, link, nodes, rebuild)

    def disable_bullet_collisions(self) -> None:
        """Leave the world's bodies, the cable's self-contact and its contacts with the other cables the
        model handles (:attr:`handles_cable_contact`) to the contact model: in Bullet the spheres collide
        only with the spheres of cables whose contacts stay Bullet's (``contact="bullet"`` or
        ``self_collision="none"``)."""
        self.contact.disable_bullet_collisions()

    @property
    def _contact_set(self) -> ContactSet | None:
        return self.contact.set

    @property
    def contacts(self):
        """The core Contacts of the coming step (empty arrays when Bullet handles contact)."""
        return self.contact.contacts

    # ----- stepping -----------------------------------------------------------------------
    def _advance(self, touched: list[int] | None) -> None:
        """Sync the step Bullet made (unless ``touched`` is None: spawn) and plan the next one."""
        do_sync = touched is not None
        idx = touched if do_sync else []
        if do_sync and self.sync == "always":
            idx = list(range(self.model.n))
        if idx:
            cid = self.world.client
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
        solver, contact = self.solver, self.contact
        if self.model_contact:
            contact.refresh()
            cp = solver.coupling
            x0, v0 = (cp.x_new, cp.v_new) if do_sync else (cp.x, cp.v)  # the state this step starts from
            cs = contact.set
            world = self.world
            free = cs.free_bodies
            if free:
                self.contacts_last_step = cs.update(x0, v0, self.arrays.mass, solver.stepper.h, world.dt, do_sync,
                                                    world.shared_bodies(self.name), world.supported_bodies,
                                                    world.support_points, world.other_shares(self.name),
                                                    world.applied_by_others(self.name))
            else:
                self.contacts_last_step = cs.update(x0, v0, self.arrays.mass, solver.stepper.h, world.dt, do_sync)
            if free and len(world.cables) > 1:  # (only another cable can share a body this way)
                world.touched_by_model(self.name, cs.touched_free_bodies())
            if free and do_sync and body_energy.book(cs, world.support_points,
                                                     solver.detector.energy_factor, self.t):
                solver.stop(BODY_ENERGY, self.t, cs.energy_check.report)
                self._record_row()
                return
        record = do_sync and self.steps % self.record_every == 0
        contacts = contact.contacts
        inp = solver.step_input(self.t, self.steps if do_sync else 0, do_sync, record, contacts, idx_arr, pos, vel)
        gripped = self.grip.active.tolist()
        if self.twist.theta.shape[0]:  # the twist state at self.t, before the plan advances it
            if not do_sync:  # planned again from self.t: from the twist of self.t, not the one planned before
                self._twist_at_t()
            now = self._twist_now
            if now is None:
                self._twist_now = self.twist.copy()
            else:
                for a, b in zip(now, self.twist):
                    a[...] = b
            self._twist_planned = True
        status = solver.step(self.arrays, self.control, contacts, contact.bodies, inp)
        self._after_plan(status, record, do_sync, gripped)

    def _after_plan(self, status: int, record: bool, do_sync: bool, gripped=(False, False)) -> None:
        """What follows the kernel's plan (``status``) in :meth:`_advance`: the free bodies' books, a grip the end slid
        out of (``gripped``: which ends a grip held before the plan), the record's row."""
        solver = self.solver
        cs = self.contact.set
        if solver.last_ratio > 0.0 and self.model_contact and cs is not None and cs.free_bodies:  # kept unconverged
            held_bodies.spare_thrown(cs, self.world.dt)
        if status == STABLE and self.model_contact and cs is not None and cs.free_bodies:
            body_energy.plan(cs, self.world.dt, solver.last_ratio == 0.0)
            world = self.world
            if len(world.cables) > 1 and solver.stepper.h == world.dt and held_bodies.COUPLE_SHARED:
                # (only another cable can share a body; a sub-stepped plan's load masses are of its last sub-step)
                world.record_shares(self.name, held_bodies.shares_of(cs, world.steps, solver.coupling.v_new))
        if gripped[0] or gripped[1]:
            active = self.grip.active
            for end in (0, 1):
                if gripped[end] and not active[end]:  # the end slid out of the gripper
                    self._let_go(end)
        if record:
            self._record_row(from_kernel=True)
        elif do_sync and status != STABLE:
            self._record_row()

    def _twist_at_t(self) -> None:
        """Undo the coming step's plan on the twist state (in place): back to its state at self.t."""
        if self._twist_planned:
            for a, b in zip(self.twist, self._twist_now):
                a[...] = b
            self._twist_planned = False

    def _step_input(self, do_sync: bool, record: bool, index: np.ndarray, pos: np.ndarray,
                    vel: np.ndarray) -> StepInput:
        """What the kernel needs from this step: time, flags, the touched spheres' read-back state."""
        # a re-plan (not do_sync) starts BDF2 afresh: the step's first plan already stored its history
        return self.solver.step_input(self.t, self.steps if do_sync else 0, do_sync, record, self.contacts, index, pos,
                                      vel)

    def _kernel_args(self, inp: StepInput) -> tuple:
        """Arguments of :func:`~bullet_dlo.bullet.kernels.sync_and_advance` (the same objects every step)."""
        return self.solver.kernel_args(self.arrays, self.control, self.contacts, self.contact.bodies, inp)

    def apply_forces(self, replan: bool = False) -> None:
        """Apply the forces planned for the coming Bullet step (nothing once unstable); ``replan``: plan the step
        again first (the world's bodies changed since it was planned)."""
        solver = self.solver
        if solver.status != STABLE:
            return
        if replan:
            self.plan_again()
        if self.proxy:  # parked spheres: Bullet does not move them (module doc); the touched bodies' reactions only
            if self._fresh:
                self._hold_fresh()
            cs = self.contact.set
            if cs is not None:  # (it returns at once when no row has a dynamic body)
                cs.apply_to_bodies()
            return
        native = self.world.native_handle()
        if native:  # one compiled call instead of n PyBullet calls
            args = (kernel_api(native), self._body_array, solver.coupling.force, self.x)
            if self._apply_native is None:
                self._apply_native = bind(apply_forces, *args)
            self._apply_native(*args)
        else:
            cid = self.world.client
            apply = pb.applyExternalForce
            frame = pb.WORLD_FRAME
            for b, f, pos in zip(self.body_ids, solver.coupling.force.tolist(), self.x.tolist()):
                apply(b, -1, f, pos, frame, cid)  # positional: keyword parsing costs 50 % more per call
        cs = self.contact.set
        if cs is not None:
            cs.apply_to_bodies()

    def plan_again(self) -> None:
        """Plan the coming step again because bodies were added since it was planned (a free body placed on the
        cable meets it in its first step)."""
        if self.solver.status == STABLE and self.model_contact:
            self._replan()

    def free_bodies_to_land(self) -> list[tuple[int, int]]:
        """The free bodies (slot, body id) this cable's plan of the coming Bullet step moved over its ``substeps``:
        Bullet's update of the mean reaction lands their velocity, not their place (:meth:`land_free_bodies`). Empty
        for a cable of one step a Bullet step. (Not after a contact solve taken again as sub-steps, where the same
        holds: landed there too, a duck thrown at the cable at 3 m/s ended 0.15 mm inside it and a 1 g box tipping
        off took 1.06 times its energy; those retries keep Bullet's place, 2026-12-05.)"""
        cs = self.contact.set
        if self.substeps == 1 or cs is None or not cs.free_bodies:
            return []
        active = cs.bodies.active
        return [(o, body) for o, body in enumerate(cs.free_bodies) if active[o]]

    def land_free_bodies(self, bodies: list[tuple[int, int]], before: dict) -> None:
        """After Bullet's step: put each free body of ``bodies`` (slot, body id; of :meth:`free_bodies_to_land`, those
        nothing else touched: :meth:`BulletWorld.step_physics <bullet_dlo.bullet.world.BulletWorld.step_physics>`)
        where the plan's sub-steps took it, its pose ``before`` the step {body: (centre of mass [m], quaternion)}
        moved by the plan's travel (``Bodies.travel``), its velocity left as Bullet's update made it (the plan's last
        sub-step's). Bullet's update puts a body at x + dt U_k where the plan put it at x + h (U_1 + ... + U_k): a 30 g
        box resting on a cable of two sub-steps at 60 Hz rose at 0.11 mm/s with the nodes under it, until the energy
        check stopped the run (2026-12-05)."""
        cid = self.world.client
        travel = self.contact.set.bodies.travel
        for o, body in bodies:
            pos, orn = before[body]
            turn = travel[o, 3:]  # (a rotation vector [rad], world frame)
            angle = float(np.linalg.norm(turn))
            q = pb.getQuaternionFromAxisAngle((turn / angle).tolist(), angle) if angle > 0.0 else (0.0, 0.0, 0.0, 1.0)
            _, orn_new = pb.multiplyTransforms((0.0, 0.0, 0.0), q, (0.0, 0.0, 0.0), orn)
            lin, ang = pb.getBaseVelocity(body, physicsClientId=cid)
            pb.resetBasePositionAndOrientation(body, (np.asarray(pos) + travel[o, :3]).tolist(), orn_new,
                                              physicsClientId=cid)
            pb.resetBaseVelocity(body, lin, ang, physicsClientId=cid)  # (a pose reset zeroes it)

    def sync_after_step(self, touched) -> None:
        """Take over Bullet's step: ``touched`` holds the spheres that had contacts (read back)."""
        if self._waking:  # (their contacts of this step were taken where they stood still: not the cable's)
            self._finish_waking()
            touched = ()
        if self.solver.status == STABLE:
            # parked proxies are never read back: nothing in Bullet may touch them (the rule), and their Bullet
            # state is not the cable's
            self._advance(sorted(touched) if touched and not self.proxy else [])

    def _record_row(self, from_kernel: bool = False) -> None:
        """Append a row; ``from_kernel``: the step's kernel wrote its end loads and energy (``inp.record``)."""
        # sample 0 of the held-end samples is the current time (they are planned for the coming step)
        cp, record = self._cp, self.record
        if from_kernel:  # the kernel wrote the row into cp.rows
            if record.rows is cp.rows:
                record.written()
            else:  # (a record that replaced the cable's own)
                record.take_from(cp.rows)
        else:
            self.record.append(self.t, self.x, self.v, self.end_forces(),
                               mechanical_energy(self.arrays, self.x, self.v, cp.samples.dir[0]))

    def add_point_mass(self, node: int, mass: float) -> None:
        """Hang a weight of ``mass`` [kg] (> 0) on node ``node`` (its sphere gets heavier too).

        Meant for set-up (before stepping): the instability detector restarts from the new state.
        """
        n = self.model.n
        if not -n <= node < n:
            raise ParameterError(f"node must be in [0, {n - 1}], got {node}")
        node = node % n
        masses = self.model.arrays.mass.copy()
        masses[node] += check_positive("point mass", mass)
        self.set_parameters(mass=masses)
        pb.changeDynamics(self.body_ids[node], -1, mass=float(masses[node]), physicsClientId=self.world.client)
        if self.proxy:  # (changing a mass may wake the sphere)
            self._park([node])
        self.solver.restart_detector(self.model, self.arrays)
        self._replan()

    def set_parameters(self, **arrays: np.ndarray) -> None:
        """Replace model parameter arrays of this cable (``ModelArrays`` names, e.g. ``damp`` [N s/m] (n,)): it
        gets a new model (:func:`~bullet_dlo.core.model.with_arrays`), the one it was built from stays as it
        was. Meant for set-up; from the next planned step on (the coming Bullet step is planned already).
        Masses: use :meth:`add_point_mass` (the spheres and the detector follow)."""
        self.model = with_arrays(self.model, **arrays)
        self.arrays = kernel_arrays(self.model.arrays, self.control, self.twist)

    # ----- grasping -----------------------------------------------------------------------
    def hold_externally(self, end: int, mode: str = "clamped") -> None:
        """Make end ``end`` (0 first, 1 last) follow poses given by :meth:`set_external_pose`.

        mode: ``clamped`` (position and tangent held, like a gripper), ``fork`` (position and the roll about
        the holder's axis held) or ``pinned``.
        The clamp's bending stiffness is the spec's half-segment value (see CableSpec).
        """
        if mode not in (EndMode.CLAMPED, EndMode.FORK, EndMode.PINNED):
            raise ParameterError(f"grasp mode must be one of clamped, fork, pinned, got {mode!r}")
        mode = str(EndMode(mode))
        c, spec, n = self.control, self.model.spec, self.model.n
        node = 0 if end == 0 else n - 1
        c.held[node] = True
        c.k_bend[node] = spec.k_bend_clamp if mode == "clamped" else 0.0
        c.c_bend[node] = c.k_bend[node] * spec.internal_damping  # the clamp's Kelvin-Voigt damper
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
        check_friction_order(mu_d, mu_s, "grip_")
        c, n, g = self.control, self.model.n, self.grip
        node = 0 if end == 0 else n - 1
        c.held[node] = False
        c.k_bend[node] = self.model.spec.k_bend_clamp
        c.c_bend[node] = c.k_bend[node] * self.model.spec.internal_damping
        self._hold_twist(end, "clamped")  # the pinching fingers hold the roll as they hold the tangent
        self.ext.active[end] = True
        g.k_ax[end] = g.k_lat[end] = self.contact_stiffness * self.model.arrays.mass[node] / self.stepper.h ** 2
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
        c, n = self.control, self.model.n
        node = 0 if end == 0 else n - 1
        c.held[node] = False
        c.k_bend[node] = c.c_bend[node] = 0.0
        self._hold_twist(end, "free")
        self.ext.active[end] = False
        self.grip.active[end] = False

    def _hold_twist(self, end: int, mode: str) -> None:
        """A cable with a material frame: end ``end``'s twist spring for ``mode`` (a clamp or a fork holds the
        twist, a pin or a free end does not: :func:`~bullet_dlo.core.model.end_twist_constants`); a clamp or a
        fork takes the section as it is now (no twist added, :func:`~bullet_dlo.core.kernels.twist.grip_section`)
        and its axis becomes the holder's ``ext.normal``, which the holder then turns (the gripper's roll)."""
        c = self.control
        if not c.k_twist.shape[0]:
            return
        spec = self.model.spec
        node = 0 if end == 0 else self.model.n - 1
        c.k_twist[node], c.k_aniso[node] = end_twist_constants(spec, mode)
        c.c_twist[node] = c.k_twist[node] * spec.internal_damping
        if EndMode(mode).holds_roll:
            self._twist_at_t()  # the section as it is at t, with the positions (a re-plan follows)
            self.ext.normal[end] = grip_section(self.arrays, self.x, self.ext.dir, end)

    def release(self, end: int) -> None:
        """Let end ``end`` go: it becomes free and no longer follows any holder."""
        self._let_go(end)
        self._replan()

    def set_external_pose(self, end: int, position, velocity, acceleration, omega, direction, normal=None,
                          angular_acceleration=(0.0, 0.0, 0.0)) -> None:
        """Measured pose of the holder of ``end`` now, world frame: position [m], velocity [m/s],
        acceleration [m/s^2], angular velocity omega [rad/s], angular acceleration [rad/s^2], each (3), all at
        the same time as the pose (a Bullet body's velocity after a step is the step's mean, half a step
        earlier: see :func:`bullet_dlo.robots.kernels.grasp_frames`); direction: clamp tangent
        pointing along the cable from its first to its last mass (normalised here); normal: the holder's
        section axis d1 (3,), normal to direction, that a clamp of a cable with a material frame holds
        (its roll about the cable); None: it is carried from the last pose onto the new direction without
        roll (parallel transport). Only a cable with a material frame reads it. The step moves the held end
        between poses at constant ``acceleration`` and ``angular_acceleration``, and the energy check counts
        the holder's work with them: a section turned from pose to pose with ``omega`` left at zero is work the
        check does not see, and a large roll so stops the run as "energy growth" (pass the holder's angular
        velocity)."""
        e = self.ext
        if self.control.k_twist.shape[0]:
            d_old = e.dir[end].copy()
            d_new = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
            if normal is None:
                transport(e.normal[end].copy(), d_old, d_new, e.normal[end])
            else:
                if any(omega):
                    self._unseen_roll[end] = 0.0
                elif e.active[end]:
                    self._roll_without_omega(end, d_old, d_new, np.asarray(normal, dtype=float))
                e.normal[end] = normal
        e.pos[end], e.vel[end], e.acc[end], e.omega[end] = position, velocity, acceleration, omega
        e.alpha[end] = angular_acceleration
        dx, dy, dz = direction  # normalised in scalars: this runs twice per coupled step
        scale = 1.0 / math.sqrt(dx * dx + dy * dy + dz * dz)
        e.dir[end] = (dx * scale, dy * scale, dz * scale)

    def _roll_without_omega(self, end: int, d_old: np.ndarray, d_new: np.ndarray, normal: np.ndarray) -> None:
        """Warn once per end when a held section has turned about the cable by more than :data:`ROLL_WITHOUT_OMEGA`
        [rad] in poses given with ``omega`` zero since the last pose with omega (the net turn: a still holder's
        jitter does not add up): the energy check counts the holder's work from omega, so the twist's energy then
        looks like energy from nowhere and a large roll stops the run as "energy growth" (an independent check,
        2026-12-07: round cables rolled by 1.55-1.61 rad so)."""
        carried = np.empty(3)
        transport(self.ext.normal[end].copy(), d_old, d_new, carried)  # the last section axis on the new tangent
        self._unseen_roll[end] += math.atan2(float(np.cross(carried, normal) @ d_new), float(carried @ normal))
        if abs(self._unseen_roll[end]) > ROLL_WITHOUT_OMEGA and end not in self._roll_warned:
            self._roll_warned.add(end)
            warnings.warn(f"cable {self.name!r}: set_external_pose turned end {end}'s section by "
                          f"{abs(self._unseen_roll[end]):.3g} rad about the cable with omega = 0: the energy check "
                          "counts the holder's work from omega, so this roll's work looks like energy from nowhere "
                          "(a large one stops the run as energy growth); pass the holder's angular velocity [rad/s]",
                          RuntimeWarning, stacklevel=3)

    def set_external_force(self, node: int, force) -> None:
        """Apply the external force ``force`` [N] (3,), world frame, to node ``node`` from now on (it stays until
        set again; ``control.f_ext`` holds all of them, (n, 3)). It acts from the next planned step: the coming
        Bullet step was planned at the end of the last one."""
        n = self.model.n
        if not -n <= node < n:
            raise ParameterError(f"node must be in [{-n}, {n - 1}], got {node}")
        f = np.asarray(force, dtype=float)
        if f.shape != (3,) or not np.all(np.isfinite(f)):
            raise ParameterError(f"force must be a finite 3-vector [N], got {force!r}")
        self.control.f_ext[node] = f

    def holder_positions(self) -> np.ndarray:
        """Positions [m] of the external holders (e.g. grasp frames) as last measured, (2, 3)."""
        return self.ext.pos.copy()

    def _replan(self) -> None:
        """Re-plan the coming step after the end conditions changed (the forces must match)."""
        if self.status == STABLE:
            self.solver.forget_factors()
            self._advance(None)

    # ----- read-outs ----------------------------------------------------------------------
    @property
    def stable(self) -> bool:
        return self.status == STABLE

    @property
    def reason(self) -> str | None:
        return REASONS[self.status]

    def state(self) -> CableState:
        """The cable's current state as the model sees it (a copy, its twist state included), all of it at
        ``t`` (``self.twist`` is the twist state the coming step planned, at t + dt)."""
        twist = self._twist_now if self._twist_now is not None else self.twist
        return CableState(self.x.copy(), self.v.copy(), self.t, twist.copy())

    def end_forces(self) -> np.ndarray:
        """Force [N] the cable exerts on each held or gripped end now, (2, 3) (first, last)."""
        return self.end_loads()[0]

    def end_loads(self) -> tuple[np.ndarray, np.ndarray]:
        """Force [N] (the reaction of a friction grip's force where one holds the end) and clamp torque
        [N m] the cable exerts on each held end now, (2, 3) each (first, last): one kernel call. A twisting cable
        (once planned): the loads the step's kernel computed from the state at ``t``, before its plan advanced
        the twist state to t + dt (what the grippers get over the coming Bullet step)."""
        if self._twist_now is not None:
            cp = self._cp
            return cp.end_force.copy(), cp.end_torque.copy()
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
        """Sphere positions read from Bullet [m], (n, 3) (n PyBullet calls: for checks, not loops). Parked proxy
        spheres get the model's positions first (:meth:`sync_bullet_spheres`)."""
        self.sync_bullet_spheres()
        cid = self.world.client
        return np.array([pb.getBasePositionAndOrientation(b, physicsClientId=cid)[0] for b in self.body_ids])
