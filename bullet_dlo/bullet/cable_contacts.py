"""The contact model's side of one Bullet cable: which bodies and cables it meets, and Bullet's filters.

:class:`CableContacts` keeps the cable's :class:`~bullet_dlo.bullet.contact.ContactSet` (rebuilt when the world's
bodies or the cables the model handles contact with change), the bodies and nodes left out of it
(:meth:`CableContacts.exclude`), and the collision filters that leave those contacts to the model instead of
Bullet (:meth:`CableContacts.disable_bullet_collisions`). The cable's :class:`~bullet_dlo.bullet.cable.BulletCable`
holds one and delegates to it; the contacts it detects enter the cable's step through
:meth:`~bullet_dlo.bullet.solver.CableSolver.step`.
"""
from __future__ import annotations

import warnings

import numpy as np
import pybullet as pb

from bullet_dlo.analysis.resolve import cylinder_masses
from bullet_dlo.bullet.contact import CAPSULE, CYLINDER, PROBE, ContactSet
from bullet_dlo.bullet.shape_data import collision_shapes, fixed_link, round_shapes
from bullet_dlo.core.kernels.contact import Bodies, Contacts, make_bodies, make_contacts
from bullet_dlo.core.validate import ParameterError

CABLE_GROUPS = 0x7FFE  # the collision-group bits of cables (bit 0 is the world's default group)
MODEL_CABLE_GROUP = 0x2
"""The group of every cable whose contacts with the world and with other cables are the model's. PyBullet
collides a pair when either body's group is in the other's mask, and a static body's mask holds every bit
but this one (Bullet's static filter): any other group met static bodies in Bullet on top of the model."""


def flat_section(spec) -> tuple[float, float]:
    """The (width, thickness) [m] whose support distance the cable's contacts take (docs/concepts/contact.md, "Flat
    sections"): a rectangle's, which always has the material frame; (0, 0) for a round or tube section (its
    ``diameter``)."""
    if spec.section == "rectangle":
        return float(spec.width), float(spec.thickness)
    return 0.0, 0.0


STRADDLE_SPAN = 1.9
"""A segment longer than STRADDLE_SPAN times the radius its centre line keeps from a static cylinder's axis, R + r,
can lie straight across the cylinder (its rounding's diameter is 2 (R + r)), and there the model holds a cable that
should slide: the cylinder pushes the chord at one point, square to it, and the turn over the cylinder sits at the
segment's nodes as bends, which a sliding cable would carry from node to node. Measured (``python
demos/cylinder_edge_slide.py``: a frictionless cylinder at a table's edge, the rope's pull 1.2 times what the table's
friction holds; docs/concepts/contact.md, "A cable over a cylinder"): every cable that held had segments of at least
1.95 (R + r), 19 of the 24 layouts at 60, 240 and 1000 Hz with friction 0.4 held; none of the 16 with shorter ones
held. Resolve's contact floor (:func:`~bullet_dlo.analysis.resolve.cylinder_segment`) is well within."""


def static_round_shapes(cs: ContactSet) -> tuple[np.ndarray, np.ndarray]:
    """The static cylinders and capsules among the shapes of contact set ``cs``: (kind, CYLINDER or CAPSULE, -1
    elsewhere; radius [m], 0 elsewhere), per shape. An exact shape on a fixed body, or a fixed link (of a fixed base,
    by fixed joints) whose one collision shape is a cylinder or capsule: Bullet's narrow phase (a PROBE row) meets a
    segment's chord there as the exact cylinder does."""
    kind, radius = np.full(len(cs.rows), -1, dtype=np.int64), np.zeros(len(cs.rows))
    round_kinds = {pb.GEOM_CYLINDER: CYLINDER, pb.GEOM_CAPSULE: CAPSULE}
    for s, row in enumerate(cs.rows):  # (body, link, kind, local position, local rotation, size, dynamic, ...)
        body, link, shape_kind, size, dynamic = row[0], row[1], row[2], row[5], row[6]
        if shape_kind in (CYLINDER, CAPSULE) and not dynamic:
            kind[s], radius[s] = shape_kind, size[0]
        elif shape_kind == PROBE and fixed_link(cs.client, body, link):  # (cheap: asked first, the shapes then; a
            # link PyBullet cannot describe directly costs a forked read, 8-25 ms, shape_data)
            data = collision_shapes(cs.client, body, link)
            found = round_shapes(data) if len(data) == 1 else []
            if found:
                geom, radius[s] = found[0]
                kind[s] = round_kinds[geom]
    return kind, radius


def straddled_cylinders(kind: np.ndarray, radius: np.ndarray, cable_radius: float, longest: float) -> np.ndarray:
    """The shape indices among the static cylinders and capsules (the same rows along their axis) ``kind`` and
    ``radius`` [m] (:func:`static_round_shapes`) whose axis a segment ``longest`` [m] long, of a cable of
    ``cable_radius`` [m], can straddle (:data:`STRADDLE_SPAN`)."""
    return np.flatnonzero((kind >= 0) & (STRADDLE_SPAN * (radius + cable_radius) < longest))


class CableContacts:
    """The contact set of one cable and what it leaves out (see the module doc).

    cable: the :class:`~bullet_dlo.bullet.cable.BulletCable`; set: its contact set (None until built; always None
    when Bullet handles contact); bullet_off: :meth:`disable_bullet_collisions` was called; excluded: the
    (body, link)s whose Bullet contacts with the spheres are off; bodies_seen: bodies in the world when the set
    was built; exclusions: (body, link or None) -> None (all nodes) or node indices (:meth:`exclude`);
    partners_seen: names of the other cables in the set; none, no_bodies: the empty contacts and free bodies of a
    cable without them.
    """

    def __init__(self, cable):
        self.cable = cable
        self.set: ContactSet | None = None
        self.bullet_off = False
        self.excluded: set[tuple[int, int]] = set()
        self.bodies_seen = -1
        self.exclusions: dict = {}
        self.partners_seen: tuple = ()
        self.none = make_contacts(cable.model.n, 1, cable.radius, cable.grip)
        self.no_bodies = make_bodies(cable.model.n, 1, 0)
        self.round = (np.zeros(0, np.int64), np.zeros(0))  # the set's static cylinders (static_round_shapes)
        self.any_round = False  # whether the set has any (warn_straddled looks further only then)
        self.straddle_warned: set[int] = set()  # their bodies warned of (warn_straddled)
        self.refresh()

    @property
    def contacts(self) -> Contacts:
        """The core Contacts of the coming step (empty arrays when Bullet handles contact)."""
        return self.set.contacts if self.set is not None else self.none

    @property
    def bodies(self) -> Bodies:
        """The free bodies solved with the coming step's contacts (none when Bullet handles contact)."""
        return self.set.bodies if self.set is not None else self.no_bodies

    def partners(self) -> list:
        """The other cables whose contacts with this one the model handles (stable ones)."""
        cable = self.cable
        if not cable.handles_cable_contact:
            return []
        return [c for c in cable.world.cables.values() if c is not cable and c.handles_cable_contact and c.stable]

    def refresh(self) -> None:
        """(Re)read the world's bodies for the contact model when they changed (new obstacles), and the
        other cables it handles contact with."""
        cable = self.cable
        if not cable.model_contact:
            return
        cid = cable.world.client
        count = pb.getNumBodies(physicsClientId=cid)
        cables = cable.world.cables
        if not self.partners_seen and len(cables) == 1 and cables.get(cable.name) is cable:
            # the common case: this cable alone in the world (so no partners), checked without building the
            # partner list every step
            if self.bodies_seen == count:
                return
            partners = []
        else:
            partners = self.partners()
        names = tuple(c.name for c in partners)
        if self.bodies_seen == count and names == self.partners_seen:
            return
        spec = cable.model.spec
        self.bodies_seen = count
        self.partners_seen = names
        # every body of the world but the cables' spheres (the robot arms too, whoever loaded them)
        spheres = set(cable.world._owners) | set(cable.body_ids)
        bodies = [b for b in (pb.getBodyUniqueId(i, physicsClientId=cid) for i in range(count)) if b not in spheres]
        self.set = ContactSet(cid, bodies, cable.model.n, cable.radius,
                              spec.static_friction, spec.dynamic_friction, cable.contact_stiffness,
                              cable.contact_damping, self_contact=cable.self_collision != "none",
                              grip=cable.grip, native=cable.world.native_handle(), others=partners,
                              exclude={**{(b, None): None for b in cable.world.no_cable_contact}, **self.exclusions,
                                       **{key: None for key in cable.world.no_collision_links}},
                              driven=dict(cable.world.driven_bodies),
                              rest_length=float(spec.rest_length),
                              # the segments' springs and the bending constants in force (the control's, changed
                              # in place by grasp and release): what a segment wrapping an edge needs
                              segments=(cable.model.arrays.k_stretch, cable.model.arrays.rest_length,
                                        cable.control.k_bend, cable.control.held),
                              section=flat_section(spec))
        self.round = static_round_shapes(self.set)
        self.any_round = bool((self.round[0] >= 0).any())
        if self.bullet_off:
            self.exclude_model_bodies()
        if self.set.free_bodies:
            cable.world.solve_free_bodies()

    def warn_straddled(self) -> None:
        """Warn, once per body, where a segment rests across a static cylinder or capsule it is long enough to straddle
        (:data:`STRADDLE_SPAN`): the cable may hold there where a real one slides. Cheap where no such cylinder is
        in the world (the usual case); called after the steps of :meth:`BulletWorld.step
        <bullet_dlo.bullet.world.BulletWorld.step>` and :meth:`~bullet_dlo.bullet.world.BulletWorld.run_while_stable`."""
        cs = self.set
        if cs is None or not self.any_round:
            return
        cable = self.cable
        r = cable.radius
        longest = float(np.max(cable.model.arrays.rest_length))  # (now: set_parameters may change the rest lengths)
        straddled = straddled_cylinders(*self.round, r, longest)
        if not straddled.size:
            return
        c = cs.contacts
        count = int(c.count[0])
        across = cs.store.body[:count][c.node[:count, 0] != c.node[:count, 1]]  # the shapes segments touch
        for s in np.intersect1d(across, straddled).tolist():
            body, link = int(cs.body_ids[s]), int(cs.links[s])
            if body in self.straddle_warned:
                continue
            self.straddle_warned.add(body)
            R = float(self.round[1][s])
            spec = cable.model.spec
            what = ("capsule" if self.round[0][s] == CAPSULE else "cylinder") + f" body {body}"
            what += f" link {link}" if link >= 0 else ""
            warnings.warn(f"cable {cable.name!r} lies across {what} (radius {R * 1e3:.3g} mm) with "
                          f"segments of {longest * 1e3:.3g} mm, longer than {STRADDLE_SPAN:g} (R + r) = "
                          f"{STRADDLE_SPAN * (R + r) * 1e3:.3g} mm: the turn over it sits at the nodes, and the model "
                          f"can hold the cable there where a real one slides (docs/concepts/contact.md, \"A cable over a "
                          f"cylinder\"); n_masses >= {cylinder_masses(spec.length, 2 * r, R)} (resolve's "
                          "contact floor) follows it", stacklevel=4)  # (the caller of the world's step)

    def exclude(self, body: int, link: int | None = None, nodes=None, rebuild: bool = True) -> None:
        """Leave ``body`` (its link ``link``; None: every link) out of the cable's contact model: entirely
        (``nodes`` None) or only for the given node indices and the segments next to them (a gripper holding
        an end: its fingers do not push the held end, the rest of the cable still meets them). Bullet's own
        collisions of those spheres with it are switched off too: the cable passes through. Only for
        ``contact="model"``. ``rebuild`` False: the set is rebuilt at the next :meth:`refresh` (the cable's next
        step, or the next exclusion that rebuilds): building it takes milliseconds with an arm's meshes."""
        cable = self.cable
        cid = cable.world.client
        n = cable.model.n
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
        self.exclusions[(int(body), link)] = nodes
        spheres = [cable.body_ids[i] for i in sorted(nodes)] if nodes is not None else cable.body_ids
        for lk in ([link] if link is not None else range(-1, pb.getNumJoints(body, physicsClientId=cid))):
            for b in spheres:
                pb.setCollisionFilterPair(b, int(body), -1, lk, 0, physicsClientId=cid)
        self.bodies_seen = -1  # rebuild the contact set
        if rebuild:
            self.refresh()

    def exclude_model_bodies(self) -> None:
        """Keep Bullet from also colliding the spheres with the dynamic bodies the contact model handles.

        The collision-group masks of :meth:`disable_bullet_collisions` keep static bodies away from the
        spheres, but not dynamic ones (measured: a dynamic box, created before or after the cable, had
        Bullet contacts with the spheres under it): such a body was then pushed by the model's reaction
        and by Bullet's sphere contacts at once, and the spheres it pressed were read back pushed into
        the ground. One pair filter per sphere and body, once per body.
        """
        cable = self.cable
        cs, cid = self.set, cable.world.client
        # a URDF's child links too, static ones included: Bullet collided the spheres with them (measured)
        bullet_sees = cs.dynamic | (cs.links >= 0)
        for body, link in sorted(set(zip(cs.body_ids[bullet_sees].tolist(), cs.links[bullet_sees].tolist()))
                                 - self.excluded):
            for b in cable.body_ids:
                pb.setCollisionFilterPair(b, body, -1, link, 0, physicsClientId=cid)
            self.excluded.add((body, link))

    def disable_bullet_collisions(self) -> None:
        """Leave the world's bodies, the cable's self-contact and its contacts with the other cables the
        model handles (:attr:`BulletCable.handles_cable_contact <bullet_dlo.bullet.cable.BulletCable.handles_cable_contact>`)
        to the contact model: in Bullet the spheres collide
        only with the spheres of cables whose contacts stay Bullet's (``contact="bullet"`` or
        ``self_collision="none"``)."""
        cable = self.cable
        own = cable._group or (MODEL_CABLE_GROUP if cable.handles_cable_contact else cable.world.next_cable_group())
        mask = CABLE_GROUPS & ~own
        if cable.handles_cable_contact:
            mask &= ~cable.world._model_cable_groups  # (a pair collides only if each one's mask has the other)
            cable.world._model_cable_groups |= own
        for b in cable.body_ids:
            pb.setCollisionFilterGroupMask(b, -1, own, mask, physicsClientId=cable.world.client)
        self.bullet_off = True
        if self.set is not None:
            self.exclude_model_bodies()

