"""The PyBullet world: client, fixed step, gravity, ground, obstacles and cables.

``BulletWorld`` owns one PyBullet client (DIRECT by default: no display needed) and steps
everything at a fixed rate. Cables are added with :meth:`BulletWorld.add_cable`; their own
physics comes from the MSD core, contacts from Bullet (see :mod:`bullet_dlo.bullet_cable`).
"""
from __future__ import annotations

import os
import time
import weakref
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np
import pybullet as pb
import pybullet_data

from bullet_dlo.assets import URDF_DIR as PROJECT_URDF
from bullet_dlo.bullet import body_energy, held_bodies, plain_steps
from bullet_dlo.bullet.cable import BulletCable
from bullet_dlo.bullet.shape_data import collision_shapes, round_shapes
from bullet_dlo.core.boundary import Move
from bullet_dlo.core.integrators import NewtonOptions
from bullet_dlo.core.model import STANDARD_GRAVITY, CableModel, CableState
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError, check_int, check_nonnegative, check_positive, check_vector3

SPAWN_TOLERANCE = 1e-4  # [m] penetration allowed at spawn before it counts as an overlap
PROGRESS_EVERY = 100  # steps between the progress reports of run_while_stable
FREE_BODY_RESIDUAL = 1e-12
"""Bullet's solver residual threshold [N^2 s^2] once a cable's contact model meets a free body (:meth:`BulletWorld.
solve_free_bodies`). Bullet's constraint solver stops iterating when an iteration's squared impulse changes, summed
over the world's constraints, fall below its ``solverResidualThreshold``; its default, 1e-7, is (3.2e-4 N s)^2, more
than a light body's whole contact impulse a step (a 30 g box weighs 4.9e-3 N s a step at 60 Hz; a 1 g box 4.1e-5
N s at 240 Hz), so on such a body the solver stops after an iteration or two. A 30 g box leaning on the cable and
on one corner on the ground (n 25, 60 Hz) turned at 16 mrad/s for seconds with that corner sliding at 0.7 mm/s under
a sixth of its friction limit: one Bullet step from rest under the cable's reaction alone gave it that turn, and
with the threshold at 1e-12 or 0 none (2026-12-05, docs/concepts/contact.md, "Bullet's solver and light bodies").
At 1e-12 every off-centre drop of the resting-bodies grid comes to rest; the scaled (1e-3 m g dt)^2 left a 3 kg
box creeping at 240 Hz. The price is Bullet iterating to its iteration count where there are contacts: a resting
box's bare step 8 -> 18 us at n 20; a world without free bodies keeps its threshold."""
_WORLDS: "weakref.WeakValueDictionary[int, BulletWorld]" = weakref.WeakValueDictionary()  # client -> its world


class SupportPoints:
    """Bullet's contact points of a step on the bodies they hold, as ``get(body, default)`` of a dict {body: points}
    (:attr:`BulletWorld.support_points`), each body's list built when first asked: a contact set asks for the bodies
    near its cable, so the points of a body lying far away (every box on a table holds four) are never built."""

    __slots__ = ("_contacts", "_owners", "_points")

    def __init__(self, contacts: Sequence[tuple], owners: dict):
        self._contacts, self._owners = contacts, owners  # getContactPoints rows; sphere body ids of the cables
        self._points: dict[int, list[tuple]] = {}

    def get(self, body: int, default=()):
        """[(point on ``body`` [m], unit normal from the holder into it, normal force [N], holder body, holder link)],
        in Bullet's order, or ``default`` when Bullet reported none on it (a cable's spheres' contacts left out)."""
        points = self._points.get(body)
        if points is None:
            owners, points = self._owners, []
            for cp in self._contacts:
                if cp[1] in owners or cp[2] in owners:
                    continue
                if cp[1] == body:
                    points.append((cp[5], cp[7], cp[9], cp[2], cp[4]))  # normal on B, from B towards A
                if cp[2] == body:  # (also: a body's two links touching each other give it both sides)
                    normal = cp[7]
                    points.append((cp[6], (-normal[0], -normal[1], -normal[2]), cp[9], cp[1], cp[3]))
            self._points[body] = points
        return points if points else default


def sync_bullet_spheres(client: int) -> None:
    """Write the parked proxy spheres of the world on PyBullet client ``client`` (if it is a
    :class:`BulletWorld`'s) into Bullet (:meth:`BulletWorld.sync_bullet_spheres`): what reads Bullet's poses of
    every body at once (a camera image) calls it first."""
    world = _WORLDS.get(client)
    if world is not None:
        world.sync_bullet_spheres()


def resolve_asset(path: str | os.PathLike) -> Path:
    """Find a URDF/mesh: absolute, relative to the working directory, the project's ``urdf/``
    folder or ``pybullet_data``; ParameterError naming the searched places otherwise."""
    p = Path(path)
    candidates = [p] if p.is_absolute() else [Path.cwd() / p, PROJECT_URDF / p, Path(pybullet_data.getDataPath()) / p]
    for c in candidates:
        if c.is_file():
            return c
    raise ParameterError(f"file {str(path)!r} not found (looked in: {', '.join(str(c.parent) for c in candidates)})")


class BulletWorld:
    """A PyBullet world stepping at a fixed rate.

    Args:
        dt: Bullet time step [s], > 0.
        gravity: gravitational acceleration [m/s^2].
        gui: open the PyBullet GUI instead of DIRECT mode (needs a display).
        ground: add a ground plane at ``ground_height`` [m].
        ground_friction: lateral friction of the ground.
        solver_iterations: Bullet constraint-solver iterations (None: Bullet's default).
        solver_residual: Bullet's solver residual threshold [N^2 s^2] (``solverResidualThreshold``; None: Bullet's
            default, 1e-7), lowered to :data:`FREE_BODY_RESIDUAL` once a cable meets a free body
            (:meth:`solve_free_bodies`).
        renderer: set up an image renderer now (``auto``/``tiny``/``egl``, see
            :class:`bullet_dlo.bullet.renderer.Renderer`); None: no rendering. The EGL plugin only draws
            bodies created after it was loaded, so a world that will be filmed says so here.
    """

    def __init__(self, dt: float = 1.0 / 240.0, gravity: Sequence[float] = STANDARD_GRAVITY, *, gui: bool = False,
                 ground: bool = True, ground_height: float = 0.0, ground_friction: float = 0.5,
                 solver_iterations: int | None = None, solver_residual: float | None = None,
                 renderer: str | None = None):
        self.dt = check_positive("dt", dt)
        self.gravity = check_vector3("gravity", gravity)
        self.ground_height = float(ground_height)
        ground_friction = check_nonnegative("ground_friction", ground_friction)
        residual = None if solver_residual is None else check_positive("solver_residual", solver_residual)
        self.client = pb.connect(pb.GUI if gui else pb.DIRECT)
        if self.client < 0:
            raise ParameterError("could not connect to PyBullet (GUI mode needs a display; use gui=False)")
        self.gui = bool(gui)
        _WORLDS[self.client] = self
        pb.setTimeStep(self.dt, physicsClientId=self.client)
        pb.setGravity(*self.gravity.tolist(), physicsClientId=self.client)
        self.renderer = None
        if renderer is not None:
            from bullet_dlo.bullet.renderer import Renderer

            self.renderer = Renderer(self.client, renderer)
        if solver_iterations is not None:
            pb.setPhysicsEngineParameter(numSolverIterations=int(solver_iterations), physicsClientId=self.client)
        self.solver_residual = 1e-7  # [N^2 s^2] Bullet's default
        if residual is not None:
            self.solver_residual = residual
            pb.setPhysicsEngineParameter(solverResidualThreshold=residual, physicsClientId=self.client)
        self.cables: dict[str, BulletCable] = {}
        self._owners: dict[int, tuple[str, int]] = {}  # sphere body id -> (cable name, mass index)
        # free bodies that a cable's step may not move by itself (contact.Bodies): those in a Bullet contact
        # in the last step (the ground or another body supports them) and, per cable, the free bodies touched by
        # the model's contacts of each cable in the last step (a body on two cables is moved by neither alone)
        self._supported: set[int] = set()  # see supported_bodies
        self._support_points: SupportPoints | None = SupportPoints((), {})  # see support_points (None: not made yet)
        self._support_contacts: tuple = ()  # the contacts supported_bodies was taken from
        self._supported_due = False  # phase 7 left the contact query for supported_bodies to its first reader
        self.model_touches: dict[int, set[str]] = {}
        self._model_touches_now: dict[int, set[str]] = {}
        self.shares: dict[int, dict[str, held_bodies.Share]] = {}  # free bodies' parts in the cables' last plans
        self.bodies_added = False  # a dynamic body was added since the cables planned their coming step
        self.bodies: dict[int, str] = {}  # non-cable bodies and their names (for messages)
        # bodies left out of every cable's contact model (a scene obstacle's ``contact: false``); a cable's
        # own exclusions: BulletCable.exclude_contact. Read when a cable (re)builds its contact set.
        self.no_cable_contact: set[int] = set()
        # links that collide with nothing in Bullet (set_collision_filter with group and mask 0): out of every
        # cable's contact model as well (PyBullet has no getter of a link's filter for the model to read)
        self.no_collision_links: set[tuple[int, int]] = set()
        # bodies whose links motors hold (position- or velocity-controlled joints whose force limits dwarf the
        # cables' loads, fixed joints: the arms the robots load): the cables meet their links as kinematic
        # obstacles (docs/concepts/contact.md, "Driven links"). Set with drive_body; read when a cable (re)builds
        # its contact set.
        self.driven_bodies: dict[int, frozenset | None] = {}  # body -> its driven links (None: all)
        self._groups_used = 0
        self._model_cable_groups = 0  # collision groups of the cables whose mutual contacts the model handles
        self._pending: set[str] = set()  # cables still to take their step in phase 7 (see take_cable_steps)
        self.ground_id: int | None = None
        if ground:
            plane = str(Path(pybullet_data.getDataPath()) / "plane.urdf")
            self.ground_id = pb.loadURDF(plane, [0, 0, self.ground_height], useFixedBase=True,
                                         physicsClientId=self.client)
            pb.changeDynamics(self.ground_id, -1, lateralFriction=ground_friction, physicsClientId=self.client)
            self.bodies[self.ground_id] = "ground"
        self.time = 0.0
        self.steps = 0
        self._contacts: tuple = ()  # every contact point of the step ``_contacts_step``, queried once
        self._contacts_step = -1
        # couplings of cables to Bullet's bodies (objects with load() and read(), see step()), and
        # user hooks (callables without arguments) at three points of the step
        self.couplings: list = []
        self.before_step: list = []
        self.after_physics: list = []
        self.after_step: list = []
        self._native: int | None = None  # C client handle for bullet.native kernels, made on first use

    def native_handle(self) -> int:
        """The C client handle of this world for :mod:`bullet_dlo.bullet.native` kernels (0: they are
        unavailable or switched off, use PyBullet's Python API). Valid until :meth:`close`."""
        if self._native is None:
            from bullet_dlo.bullet import native

            self._native = native.connect(self.client) if pb.isConnected(self.client) else 0
        return self._native

    # ----- obstacles --------------------------------------------------------------------------
    def add_box(self, half_extents: Sequence[float], position: Sequence[float],
                orientation: Sequence[float] = (0, 0, 0, 1), *, mass: float = 0.0, friction: float = 0.5,
                name: str = "box", color: Sequence[float] = (0.6, 0.6, 0.65, 1.0)) -> int:
        """A box (static when ``mass`` = 0) with half extents [m] at ``position`` [m]."""
        he = check_vector3("half_extents", half_extents)
        if np.any(he <= 0):
            raise ParameterError(f"half_extents must be > 0, got {list(half_extents)}")
        col = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=he.tolist(), physicsClientId=self.client)
        vis = pb.createVisualShape(pb.GEOM_BOX, halfExtents=he.tolist(), rgbaColor=list(color),
                                   physicsClientId=self.client)
        return self._add_body(col, vis, position, orientation, mass, friction, name)

    def add_cylinder(self, radius: float, height: float, position: Sequence[float],
                     orientation: Sequence[float] = (0, 0, 0, 1), *, mass: float = 0.0, friction: float = 0.5,
                     name: str = "cylinder", color: Sequence[float] = (0.6, 0.6, 0.65, 1.0)) -> int:
        """A cylinder (axis along its local z) of ``radius`` and ``height`` [m]."""
        r = check_positive("radius", radius)
        hgt = check_positive("height", height)
        col = pb.createCollisionShape(pb.GEOM_CYLINDER, radius=r, height=hgt, physicsClientId=self.client)
        vis = pb.createVisualShape(pb.GEOM_CYLINDER, radius=r, length=hgt, rgbaColor=list(color),
                                   physicsClientId=self.client)
        return self._add_body(col, vis, position, orientation, mass, friction, name)

    def add_urdf(self, path: str | os.PathLike, position: Sequence[float] = (0, 0, 0),
                 orientation: Sequence[float] = (0, 0, 0, 1), *, fixed: bool = True, name: str | None = None) -> int:
        """Load a URDF (absolute, relative, from the project's ``urdf/`` or ``pybullet_data``). Its
        ``<cylinder>`` collisions load as cylinders (not meshes), so the cable's contact model meets its base
        link's primitives on their exact geometry; meshes and the shapes of child links it meets through
        Bullet's narrow phase (:mod:`bullet_dlo.bullet.contact`)."""
        file = resolve_asset(path)
        pos = check_vector3("position", position)
        try:
            body = pb.loadURDF(str(file), pos.tolist(), list(orientation), useFixedBase=fixed,
                               flags=pb.URDF_USE_IMPLICIT_CYLINDER, physicsClientId=self.client)
        except pb.error as err:
            raise ParameterError(f"could not load URDF {str(file)!r}: {err}") from None
        self.bodies[body] = name or file.stem
        self.bodies_added = self.bodies_added or not fixed
        return body

    def drive_body(self, body: int, links=None) -> None:
        """Declare ``body``'s links ``links`` (None: all) held by motors: every joint between such a link and the
        base position- or velocity-controlled with a force limit far above the cables' loads, or fixed (a robot
        arm). The cables' contact models then meet those links as kinematic obstacles that move with the link's
        own velocity, and still apply their reactions to the link (its joint sensors read them)."""
        try:
            pb.getBodyInfo(int(body), physicsClientId=self.client)
        except pb.error:
            raise ParameterError(f"drive_body: no body {body} in this world") from None
        self.driven_bodies[int(body)] = None if links is None else frozenset(int(k) for k in links)
        for cable in self.cables.values():
            cable.contact.bodies_seen = -1  # rebuild its contact set at the next refresh
            cable.contact.refresh()

    def set_collision_filter(self, body: int, link: int, group: int, mask: int) -> None:
        """Bullet's collision filter group and mask of ``body``'s link ``link`` (-1: its base), told to the cables'
        contact model too: the model cannot read Bullet's filters (PyBullet has setters only), so a filter set with
        ``pb.setCollisionFilterGroupMask`` directly leaves the link solid to the cables. A link that collides with
        nothing (``group`` and ``mask`` 0) is left out of every cable's contact model, now and for cables added
        later, as Bullet leaves it out of its own collisions; any other filter keeps it in the model (out of one
        cable's contact: :meth:`BulletCable.exclude_contact <bullet_dlo.bullet.cable.BulletCable.exclude_contact>`;
        a scene obstacle: ``contact: false``)."""
        cid = self.client
        try:
            pb.getBodyInfo(int(body), physicsClientId=cid)
            joints = pb.getNumJoints(int(body), physicsClientId=cid)
        except pb.error:
            raise ParameterError(f"set_collision_filter: no body {body} in this world") from None
        if not -1 <= int(link) < joints:
            raise ParameterError(f"set_collision_filter: link must be in [-1, {joints - 1}], got {link}")
        group, mask = check_int("group", group, 0, 2**31 - 1), check_int("mask", mask, 0, 2**31 - 1)
        pb.setCollisionFilterGroupMask(int(body), int(link), group, mask, physicsClientId=cid)
        key = (int(body), int(link))
        if group == 0 and mask == 0:
            self.no_collision_links.add(key)
        else:
            self.no_collision_links.discard(key)
        for cable in self.cables.values():
            cable.contact.bodies_seen = -1  # rebuild its contact set at the next refresh
            cable.contact.refresh()

    def _add_body(self, col: int, vis: int, position, orientation, mass, friction, name) -> int:
        pos = check_vector3("position", position)
        quat = np.asarray(orientation, dtype=float)
        if quat.shape != (4,) or not np.all(np.isfinite(quat)) or np.linalg.norm(quat) < 1e-9:
            raise ParameterError(f"orientation must be a quaternion [x, y, z, w], got {list(orientation)}")
        body = pb.createMultiBody(baseMass=check_nonnegative("mass", mass), baseCollisionShapeIndex=col,
                                  baseVisualShapeIndex=vis, basePosition=pos.tolist(),
                                  baseOrientation=(quat / np.linalg.norm(quat)).tolist(), physicsClientId=self.client)
        pb.changeDynamics(body, -1, lateralFriction=check_nonnegative("friction", friction),
                          physicsClientId=self.client)
        self.bodies[body] = name
        self.bodies_added = self.bodies_added or mass > 0
        return body

    def passages(self, narrowest: float, widest: float) -> list[tuple[float, str, str]]:
        """The gaps between the world's bodies (not the cables) that a cable could thread: (width [m], name,
        name) of each pair of bodies whose closest distance (Bullet's narrow phase, every link, any shape) lies
        in (``narrowest``, ``widest``], narrowest first. Bodies out of the cables' contact model are left out."""
        bodies = [b for b in self.bodies if b not in self.no_cable_contact]
        found = []
        for k, a in enumerate(bodies):
            for b in bodies[k + 1:]:
                points = pb.getClosestPoints(a, b, widest, physicsClientId=self.client)
                gap = min((p[8] for p in points), default=np.inf)
                if narrowest < gap <= widest:
                    found.append((float(gap), self.bodies[a], self.bodies[b]))
        return sorted(found)

    def round_radii(self) -> tuple[float, ...]:
        """Radii [m] of the cylinders and capsules among the collision shapes of every link of the world's bodies (not
        the cables, not the bodies out of the cables' contact model), smallest first: what resolve's contact floor
        on n reads (:func:`~bullet_dlo.analysis.resolve.cylinder_segment`)."""
        radii = []
        for b in self.bodies:
            if b in self.no_cable_contact:
                continue
            for link in range(-1, pb.getNumJoints(b, physicsClientId=self.client)):
                radii += [r for _, r in round_shapes(collision_shapes(self.client, b, link))]
        return tuple(sorted(radii))

    def solve_free_bodies(self) -> None:
        """Lower Bullet's solver residual threshold to :data:`FREE_BODY_RESIDUAL` (once; a lower one is kept): a
        cable's contact model met a free body, which Bullet's step must move to the cable's precision (its default
        threshold stops the solver after an iteration or two on a light body)."""
        if self.solver_residual > FREE_BODY_RESIDUAL:
            self.solver_residual = FREE_BODY_RESIDUAL
            pb.setPhysicsEngineParameter(solverResidualThreshold=FREE_BODY_RESIDUAL, physicsClientId=self.client)

    def next_cable_group(self) -> int:
        """A collision-group bit of its own for a cable whose spheres never collide with each other (bits 2-14;
        bit 1 is :data:`~bullet_dlo.bullet.cable_contacts.MODEL_CABLE_GROUP`)."""
        self._groups_used += 1
        if self._groups_used > 13:
            raise ParameterError("at most 13 cables can have self_collision='none' or Bullet's contact in one world")
        return 1 << (self._groups_used + 1)

    # ----- cables -----------------------------------------------------------------------------
    def add_cable(
        self,
        cable: CableSpec | CableModel,
        start: Sequence[float] = (0.0, 0.0, 0.5),
        direction: Sequence[float] = (1.0, 0.0, 0.0),
        ends: tuple[str, str] = ("free", "free"),
        motion: Sequence[Move] = (),
        integrator: str = "implicit_euler",
        *,
        name: str = "cable",
        state: CableState | None = None,
        substeps: int = 1,
        self_collision: str = "neighbours",
        sync: str = "contacts",
        newton: NewtonOptions = NewtonOptions(),
        detector=None,
        record_every: int = 1,
        overlap_ok: Sequence[int] = (),
        contact: str = "auto",
        contact_stiffness: float = 1.0e4,
        contact_damping: float = 0.0,
        bullet_spheres: str = "auto",
    ) -> BulletCable:
        """Spawn a cable as Bullet spheres driven by the MSD model.

        Args:
            cable: a CableSpec (laid out straight from ``start`` along ``direction``) or a
                ready CableModel (its own layout, ends and motion are used; gravity must match).
            ends, motion: end conditions and prescribed moves (see :class:`CableModel`).
            integrator: core integrator name; the Bullet step is ``dt``/``substeps`` for it.
            name: unique name of this cable in the world.
            state: start state (default: the layout at rest).
            substeps: integrator steps per Bullet step (for explicit methods at small steps).
            self_collision: ``neighbours`` (spheres closer than a diameter at rest never collide,
                the others do), ``none`` (no self-contact; other cables meet it only through Bullet's
                spheres: fastest), ``all``. With model contact (and not ``none``) contacts with the
                other such cables are the model's (segment capsules, see :mod:`bullet_dlo.bullet.contact`).
            sync: ``contacts`` (read back only spheres that touched something) or ``always``.
            detector: instability thresholds (DetectorOptions).
            record_every: Bullet steps between recorded rows.
            overlap_ok: bodies the cable may touch at spawn (e.g. the grippers that hold it).
            contact: ``model`` (contact and Coulomb friction inside the cable's implicit step, the
                spheres out of Bullet's collisions, reactions applied to the touched bodies),
                ``bullet`` (Bullet resolves the spheres' contacts) or ``auto`` (model for the
                implicit integrators, bullet for the explicit ones). See :mod:`bullet_dlo.bullet.contact`.
            contact_stiffness: alpha = k_n h^2 / m of the model's contact penalty, > 0 (1e4: the
                contact's natural period is 2 pi h / 100; penetration at rest about g h^2 / alpha). The rows
                a free body presses, and the table's under them, stiffen to their load: a body's
                weight presses them at most ``contact.LOAD_DEPTH`` of the radius deep.
            contact_damping: damping ratio of the model's normal contact, >= 0.
            bullet_spheres: ``auto`` (the spheres are parked proxies, asleep in Bullet and written there only when
                read, while the rule of :meth:`update_proxies` holds: model contact, and nothing in Bullet collides
                with them) or ``live`` (Bullet moves them every step). See :mod:`bullet_dlo.bullet.cable`.
        """
        from bullet_dlo.core.engine import DetectorOptions

        if name in self.cables:
            raise ParameterError(f"a cable named {name!r} already exists in this world; names must be unique")
        if isinstance(cable, CableModel):
            model = cable
            if not np.allclose(model.gravity, self.gravity):
                raise ParameterError(f"cable model gravity {model.gravity.tolist()} differs from the world's "
                                     f"{self.gravity.tolist()}")
        elif isinstance(cable, CableSpec):
            model = CableModel.straight(cable, start, direction, ends, motion, self.gravity)
        else:
            raise ParameterError(f"cable must be a CableSpec or CableModel, got {type(cable).__name__}")
        c = BulletCable(self, name, model, integrator, state=state, substeps=substeps,
                        self_collision=self_collision, sync=sync, newton=newton,
                        detector=detector or DetectorOptions(), record_every=record_every, contact=contact,
                        contact_stiffness=contact_stiffness, contact_damping=contact_damping,
                        bullet_spheres=bullet_spheres)
        self.sync_bullet_spheres()  # the spawn check collides the new spheres with the others where they are
        try:
            self._check_spawn_overlap(c, set(overlap_ok))
        except ParameterError:
            for b in c.body_ids:
                pb.removeBody(b, physicsClientId=self.client)
            raise
        if c.model_contact:
            c.disable_bullet_collisions()
        self.cables[name] = c
        self._owners.update({b: (name, i) for i, b in enumerate(c.body_ids)})
        self.update_proxies()
        return c

    def update_proxies(self) -> None:
        """Re-take the proxy rule for every cable (when cables join): a cable's spheres are parked proxies
        (:meth:`BulletCable.set_proxy`) when its own conditions hold (:meth:`BulletCable.proxy_allowed`) and no
        other cable's spheres may collide with them in Bullet, i.e. it and every other cable leave their mutual
        contacts to the model (:attr:`BulletCable.handles_cable_contact`); else they are live."""
        cables = list(self.cables.values())
        for c in cables:
            alone = all(c.handles_cable_contact and o.handles_cable_contact for o in cables if o is not c)
            c.set_proxy(c.proxy_allowed() and alone)

    def sync_bullet_spheres(self) -> None:
        """Write every parked proxy cable's positions into Bullet (:meth:`BulletCable.sync_bullet_spheres`), for
        direct PyBullet reads of the spheres; a rendered frame does it itself."""
        for c in self.cables.values():
            c.sync_bullet_spheres()

    def _check_spawn_overlap(self, cable: BulletCable, overlap_ok: set[int]) -> None:
        """Refuse a cable that starts inside the ground or another body."""
        low = float(np.min(cable.x[:, 2])) - cable.radius
        if self.ground_id is not None and low < self.ground_height - SPAWN_TOLERANCE:
            raise ParameterError(
                f"cable {cable.name!r} overlaps the ground at spawn: its lowest sphere reaches z = {low:.4f} m, "
                f"below the ground at {self.ground_height:.4f} m; raise the layout start")
        pb.performCollisionDetection(physicsClientId=self.client)
        index = {b: i for i, b in enumerate(cable.body_ids)}
        # one query for the world: a query per sphere scans every contact pair each time (n = 1000: 13 s)
        overlaps = []  # (sphere index, other body, distance [m])
        for cp in pb.getContactPoints(-1, -1, -2, -2, self.client):
            for mine, other in ((cp[1], cp[2]), (cp[2], cp[1])):
                if mine in index and other not in index and other not in overlap_ok and cp[8] <= -SPAWN_TOLERANCE:
                    overlaps.append((index[mine], other, cp[8]))
        if overlaps:
            sphere, other, dist = min(overlaps, key=lambda o: o[0])  # the first sphere, as the spheres are laid out
            what = self.bodies.get(other, f"body {other}")
            for cname, c in self.cables.items():
                if other in c.body_ids:
                    what = f"cable {cname!r}"
            raise ParameterError(f"cable {cable.name!r} overlaps {what} at spawn (sphere {sphere} "
                                 f"penetrates by {-dist * 1000:.2f} mm); move the layout")

    # ----- stepping ---------------------------------------------------------------------------
    def step(self, n: int = 1) -> None:
        """Advance the world by ``n`` fixed steps of ``dt``. One step, in this order:

        1. :meth:`push_cables`: each cable's sphere forces go to Bullet (they meet Bullet's bodies);
        2. each coupling's ``load()``: what couples a cable to Bullet's bodies loads them (the dual-arm
           grasp: the cable's end force and clamp torque on each gripper, then the task's arm targets);
        3. ``before_step`` hooks (user controllers);
        4. Bullet's step (arms, obstacles, the spheres);
        5. each coupling's ``read()``: it reads Bullet's bodies back (the dual-arm grasp: both arms,
           the held ends follow the measured grasp frames, the wrist sensors sample);
        6. ``after_physics`` hooks;
        7. :meth:`take_cable_steps`: contacts read back, each cable's own (implicit) step; the bodies several
           cables moved get their reactions together (:meth:`settle_shares`);
        8. ``after_step`` hooks (recorders, progress, user extensions).

        Plain steps (one cable on parked spheres among static bodies, no couplings, no hooks: see
        :mod:`~bullet_dlo.bullet.plain_steps`) run these phases in one compiled call, to the same results.

        After the steps, a cable lying across a static cylinder whose axis its segments can straddle is warned of
        (:meth:`CableContacts.warn_straddled <bullet_dlo.bullet.cable_contacts.CableContacts.warn_straddled>`).
        """
        self._steps(n)
        self._warn_straddled()

    def _warn_straddled(self) -> None:
        """After a run of steps: each cable lying across a static cylinder it can straddle is warned of, once per
        cylinder (:meth:`CableContacts.warn_straddled <bullet_dlo.bullet.cable_contacts.CableContacts.warn_straddled>`)."""
        for cable in self.cables.values():
            cable.contact.warn_straddled()

    def _steps(self, n: int, watch: BulletCable | None = None, horizon: int = 0) -> int:
        """:meth:`step` ``n`` times, stopping early (before a step) once ``watch`` is unstable; returns the steps
        taken. ``horizon``: the steps the run asks for in all, from here (plain_steps.PLAIN_FROM)."""
        done = 0
        while done < n:
            if watch is not None and not watch.stable:
                break
            plain = plain_steps.take(self, n - done, horizon - done)
            if plain:
                done += plain
                continue
            done += 1
            self.push_cables()
            for coupling in self.couplings:
                coupling.load()
            for hook in self.before_step:
                hook()
            self.step_physics()
            for coupling in self.couplings:
                coupling.read()
            for hook in self.after_physics:
                hook()
            self.take_cable_steps()
            for hook in self.after_step:
                hook()
        return done

    def push_cables(self) -> None:
        """Phase 1 of :meth:`step`: every cable's sphere forces to Bullet (a cable first plans its coming step again
        when a dynamic body was added since it was planned: a body placed on the cable meets it in its first step;
        a static one joins the next step's contacts)."""
        replan, self.bodies_added = self.bodies_added, False
        cables = self.cables.values()
        if replan:
            for c in cables:
                c.plan_again()
            self.settle_shares()
        for c in cables:
            c.apply_forces()

    def settle_shares(self) -> None:
        """The free bodies several cables moved in their plans of the coming step: each cable whose plan is off where
        all their reactions together take the body is planned again with the others' reactions of this step (block
        Gauss-Seidel, at most ``held_bodies.SHARED_PASSES`` rounds), then the reactions handed to each body are
        combined (:func:`~bullet_dlo.bullet.held_bodies.settle`), and one of them books the body's energy with the
        work of them all (:func:`~bullet_dlo.bullet.body_energy.plan_shared`)."""
        if not self.shares:
            return
        again, targets = held_bodies.unsettled(self.shares, self.steps, self.dt)
        for _ in range(held_bodies.SHARED_PASSES):
            if not again:
                break
            for c in self.cables.values():
                if c.name in again:
                    c.plan_again()
            again, targets = held_bodies.unsettled(self.shares, self.steps, self.dt)
        for cs, slot, work in held_bodies.settle(self.shares, self.steps, targets):
            body_energy.plan_shared(cs, slot, work)

    def shared_bodies(self, cable: str) -> dict[int, int]:
        """The free bodies another cable's contacts touched in the last step or in its plan of this one, each with the
        number of cables that share it (this one included): the cable named ``cable`` moves such a body in its own
        step with the other cables' reactions (each cable's step alone would carry the body's whole weight; a
        sub-stepped cable with its share of the mass, or the condensed contact where something else holds it too:
        :meth:`ContactSet.update <bullet_dlo.bullet.contact.ContactSet.update>`). (The bodies Bullet supports,
        :attr:`supported_bodies`, move in it under the load Bullet put on them.)"""
        if not self.model_touches and not self._model_touches_now:
            return {}
        touches = {b: set(names) for b, names in self.model_touches.items()}
        for b, names in self._model_touches_now.items():  # the plans of this step so far (the cables before this
            touches.setdefault(b, set()).update(names)  # one, or all of them when the step is planned again)
        return {b: len(names | {cable}) for b, names in touches.items() if names - {cable}}

    def other_shares(self, cable: str) -> dict[int, list[tuple]]:
        """The other cables' reactions on the free bodies they moved in their plans of this step (planned before this
        cable's) or of the last one, which the cable named ``cable`` takes with a body they share
        (:func:`~bullet_dlo.bullet.held_bodies.couple`): {body: [(impulse, load_mass, ref)]}, each linear in the
        body's velocity delta, impulse - load_mass (delta - ref) (:class:`~bullet_dlo.bullet.held_bodies.Share`).
        ref is the velocity of a plan of this step; of the last step's, the one that keeps its contacts as they are
        (``Share.rest``): their springs' load stays with the body's position, not its velocity (taking that plan's
        velocity instead had a 1 g box landing on three cables at 60 Hz pulled into them by 5000 times its weight in
        the next plan)."""
        out: dict[int, list] = {}
        for body, parts in self.shares.items():
            for name, p in parts.items():
                if name != cable and p.step >= self.steps - 1:
                    ref = p.vel if p.step == self.steps else p.rest
                    out.setdefault(body, []).append((p.impulse, p.load_mass, ref))
        return out

    def applied_by_others(self, cable: str) -> dict[int, np.ndarray]:
        """{body: force and torque [N, N m] (about its centre of mass)} the cables other than the one named ``cable``
        applied in Bullet's last step to the free bodies they share with it (a held body's measured load leaves
        them out: :func:`~bullet_dlo.bullet.held_bodies.measure`)."""
        out: dict[int, np.ndarray] = {}
        for body, parts in self.shares.items():
            for name, p in parts.items():
                if name != cable:
                    applied = p.cs._applied[p.slot]
                    out[body] = out[body] + applied if body in out else applied.copy()
        return out

    def record_shares(self, cable: str, shares: dict) -> None:
        """Keep the parts of the cable named ``cable`` in the free bodies of its plan just made ({body: Share}), and
        forget the parts older than the last step."""
        for body in list(self.shares):
            parts = self.shares[body]
            parts.pop(cable, None)
            for name in [k for k, p in parts.items() if p.step < self.steps - 1]:
                del parts[name]
            if not parts:
                del self.shares[body]
        for body, p in shares.items():
            self.shares.setdefault(body, {})[cable] = p

    def touched_by_model(self, cable: str, bodies) -> None:
        """Record the free bodies the model's contacts of ``cable`` touch in the step being planned."""
        for b in bodies:
            self._model_touches_now.setdefault(b, set()).add(cable)

    @property
    def supported_bodies(self) -> set[int]:
        """The free bodies in a Bullet contact (not with a cable's sphere) in the last step: the ground or another body
        supports them (a cable's step moves them under the load Bullet put on them,
        :mod:`bullet_dlo.bullet.held_bodies`). Taken in phase 7 of :meth:`step`; when every cable's spheres are parked proxies and no cable's contact set has a
        free body, phase 7 reads Bullet's contacts only if a cable asks for this set in it (a set rebuilt there with a
        new free body); otherwise it stays empty: only free bodies in it count, and there were none in the step."""
        if self._supported_due:
            self._supported_due = False
            self._supported = self._supported_in(self.contacts())
        return self._supported

    @supported_bodies.setter
    def supported_bodies(self, bodies: set[int]) -> None:
        self._supported_due = False
        self._supported = bodies

    @property
    def support_points(self) -> "SupportPoints":
        """Bullet's contact points of the last step on each body of :attr:`supported_bodies`, ``get(body, ())``: [(point
        on it [m], unit normal from the holder into it, normal force [N], holder body, holder link)]."""
        self.supported_bodies  # (taken with it)
        if self._support_points is None:  # made on first demand: only a free body in a contact set asks
            self._support_points = SupportPoints(self._support_contacts, self._owners)
        return self._support_points

    def _supported_in(self, contacts) -> set[int]:
        self._support_contacts, self._support_points = contacts, None
        return self._in_bullet_contact(contacts)

    def _in_bullet_contact(self, contacts) -> set[int]:
        """The bodies of Bullet's ``contacts`` (``getContactPoints`` rows) in a contact not with a cable's sphere."""
        if not contacts:
            return set()
        owners = self._owners
        return {b for cp in contacts if cp[1] not in owners and cp[2] not in owners for b in (cp[1], cp[2])}

    def step_physics(self) -> None:
        """Phase 4 of :meth:`step`: Bullet's own step; the clock advances by ``dt``. A free body that one cable's plan
        moved over several sub-steps and nothing else touched in Bullet's step is then put where the plan took it
        (:meth:`BulletCable.land_free_bodies`; a body several cables planned, :meth:`touched_by_model`, or one in a
        Bullet contact, keeps Bullet's place: their motion is not one plan's)."""
        landing = [(c, c.free_bodies_to_land()) for c in self.cables.values()] if self.cables else []
        landing = [(c, [(o, b) for o, b in bodies if len(self._model_touches_now.get(b, ())) <= 1])
                   for c, bodies in landing if bodies]
        before = {b: pb.getBasePositionAndOrientation(b, physicsClientId=self.client)
                  for _, bodies in landing for _, b in bodies}
        pb.stepSimulation(self.client)
        self.time += self.dt
        self.steps += 1
        if before:
            held = self._in_bullet_contact(self.contacts())  # (the step's one contact query, shared with phase 7)
            for c, bodies in landing:
                c.land_free_bodies([(o, b) for o, b in bodies if b not in held], before)

    def take_cable_steps(self) -> None:
        """Phase 7 of :meth:`step`: the spheres that touched something are read back (one contact query
        for the world) and every cable takes its own step."""
        cables = list(self.cables.values())
        # parked proxies are never read back (BulletCable.sync_after_step): with only those, Bullet's contacts serve
        # just the free bodies' support (supported_bodies), asked for on demand when no contact set has a free body
        lazy = True
        for c in cables:
            cs = c.contact.set
            if not c.proxy or (cs is not None and cs.free_bodies):
                lazy = False
                break
        contacts = self.contacts() if cables and not lazy else ()
        self._supported = self._supported_in(contacts)
        self._supported_due = lazy and bool(cables)
        if self.model_touches or self._model_touches_now:  # (empty both: nothing to hand over)
            self.model_touches, self._model_touches_now = self._model_touches_now, {}
        # cables touching each other through the model read the ones still pending as held where they
        # are, the ones done as moving over their planned step (see ContactSet._read_others; one cable: nobody)
        several = len(cables) > 1
        if several:
            self._pending = {c.name for c in cables}
        try:
            self._take_cable_steps(cables, contacts)
        finally:
            if several:
                self._pending = set()
            self._supported_due = False  # (not asked in phase 7: no free body in any set, the empty set holds)
        self.settle_shares()

    def _take_cable_steps(self, cables, contacts) -> None:
        if not contacts:
            pending = self._pending
            for c in cables:
                c.sync_after_step(())
                pending.discard(c.name)
            return
        touched: dict[str, set[int]] = {c.name: set() for c in cables}
        owners = self._owners
        for cp in contacts:
            for body in (cp[1], cp[2]):
                hit = owners.get(body)
                if hit is not None:
                    touched[hit[0]].add(hit[1])
        for c in cables:
            c.sync_after_step(touched[c.name])
            self._pending.discard(c.name)

    def contacts(self) -> tuple:
        """Every contact point of the step just taken, as ``pybullet.getContactPoints`` gives them: one
        query per step, shared by the cables' sync and the wrist sensors."""
        if self._contacts_step != self.steps:
            self._contacts = pb.getContactPoints(-1, -1, -2, -2, self.client)  # all, one call
            self._contacts_step = self.steps
        return self._contacts

    def steps_in(self, duration: float) -> int:
        """Whole steps of ``dt`` in ``duration`` [s] (> 0), at least one."""
        return max(1, int(round(check_positive("duration", duration) / self.dt)))

    def run(self, duration: float) -> int:
        """Step for ``duration`` seconds (rounded to whole steps); returns the number of steps."""
        n = self.steps_in(duration)
        self.step(n)
        return n

    def run_while_stable(self, steps: int, cable: BulletCable,
                         progress: Callable[[int], Any] | None = None) -> float:
        """Step up to ``steps`` times, stopping early when ``cable`` goes unstable; returns the wall time [s].
        ``progress(k)`` is told of every ``PROGRESS_EVERY`` steps taken (a progress bar without an ``after_step``
        hook, which would keep every step out of the plain steps' loop)."""
        tic = time.perf_counter()
        done = 0
        while done < steps and cable.stable:
            k = self._steps(min(PROGRESS_EVERY, steps - done) if progress is not None else steps - done, cable,
                            steps - done)
            done += k
            self._warn_straddled()
            if progress is not None:
                progress(k)
        return time.perf_counter() - tic

    def step_bare(self, n: int = 1) -> None:
        """Bullet's own step only, no cable forces (the baseline of the overhead benchmark)."""
        for _ in range(n):
            pb.stepSimulation(self.client)

    def close(self) -> None:
        """Disconnect the PyBullet client."""
        self._native = 0  # the handle dies with the connection
        if _WORLDS.get(self.client) is self:
            del _WORLDS[self.client]
        if pb.isConnected(self.client):
            pb.disconnect(self.client)

    def __enter__(self) -> "BulletWorld":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def add_obstacles(world: BulletWorld, obstacles) -> None:
    """Add a scene's ``bullet.obstacles`` (mappings with ``type: box | cylinder | urdf``) to ``world``;
    ``contact: false`` leaves one out of the cables' contact model (:attr:`BulletWorld.no_cable_contact`)."""
    for k, ob in enumerate(obstacles):
        spec = {key: val for key, val in ob.items() if key not in ("type", "contact")}
        contact = ob.get("contact", True)
        try:
            if not isinstance(contact, bool):
                raise ParameterError(f"contact must be true or false, got {contact!r}")
            if ob["type"] == "box":
                body = world.add_box(**spec)
            elif ob["type"] == "cylinder":
                body = world.add_cylinder(**spec)
            else:
                body = world.add_urdf(**spec)
        except (ParameterError, TypeError) as err:
            raise ParameterError(f"bullet.obstacles[{k}]: {err}") from None
        if not contact:
            world.no_cable_contact.add(body)
