"""A link's collision shapes, read without the call that kills the process.

PyBullet's ``getCollisionShapeData`` (``PhysicsServerCommandProcessor::extractCollisionShapes``, the handler
of CMD_REQUEST_COLLISION_SHAPE_INFO) describes a ``btMultiSphereShape`` (MULTI_SPHERE_SHAPE_PROXYTYPE) by
casting it to ``btCapsuleShapeZ`` and calling ``getHalfHeight()``, which indexes the capsule's dimensions with
its up axis: a member a multi-sphere shape does not have (its memory there holds the multi-sphere's own
fields), so the index is garbage and the read leaves the process's memory: SIGSEGV, the whole process dies
(measured with PyBullet 3.2.7 on pybullet_data's ``mjcf/capsule_fromtoX/Y/Z.xml`` and every limb of
``mjcf/humanoid_symmetric.xml``; bullet3's source of 2025-01 has the same cast). The only PyBullet loader that
makes that shape is ``loadMJCF``: a capsule geom given by ``fromto`` (the limbs of pybullet_data's ant and
humanoids) when the file is loaded without ``URDF_USE_IMPLICIT_CYLINDER``; with the flag the same geom is a
``btCapsuleShapeZ`` in a compound and reads fine. Cylinders given by ``fromto`` are convex hulls (they read
fine).

:func:`collision_shapes` answers what ``getCollisionShapeData`` would, or ``()`` for a link whose shapes
PyBullet cannot describe; for such a link the caller uses Bullet's narrow phase (``getClosestPoints``,
which handles a multi-sphere shape) instead, as for a heightfield, which PyBullet does not list either.
Which links are read directly (decided from ``getVisualShapeData``, ``getDynamicsInfo`` and ``getAABB``,
none of which touches the collision shape's description):

- a link without a visual capsule (the importer gives every MJCF geom a visual shape of its own type)
  cannot hold a multi-sphere shape;
- a link whose one visual shape is a capsule of radius r and half length h, whose collision margin is r (a
  ``btCapsuleShape``'s margin is its radius and cannot be changed) and whose bounding box has the half
  widths of a ``btCapsuleShapeZ`` in the link's centre-of-mass frame R (``btCapsuleShape::getAabb``:
  e_i = r sum_j |R_ij| + h |R_i2|) is that capsule. A multi-sphere shape along a (unit, that frame) has
  e_i = sum_j |R_ij| (r + m + h |a_j|), m its margin (0.04 m by default, also added to the box): the two
  agree only if m = r and r sum_j |R_ij| + h sum_j |R_ij| |a_j| = h |R_i2| for all three i at once;
- a link without any visual shape whose bounding box is a speck (a link without collision shapes: 2 mm
  wide, Bullet's margin round a point; a multi-sphere shape's box is at least two margins wide).

Any other link with a capsule (a URDF capsule in a compound, an MJCF capsule given by fromto, loaded
with or without the flag) is read in a forked copy of the process when the client is a DIRECT one (the
physics server then lives in this process, and the copy holds the same world): an answer is returned, a
copy killed by a signal means the link cannot be described (``()``). Other connections (GUI, shared
memory: the server is another thread or process, which a fork does not copy) return ``()`` for such a
link. One forked read takes 8-25 ms (measured with the package and Numba loaded, 160 MB resident, load
average 3-4: the MJCF humanoid's 11 capsule links cost 0.2 s each time the contact set is built).
"""
from __future__ import annotations

import faulthandler
import gc
import os
import pickle
import select
import signal
import warnings

import pybullet as pb

SPECK = 3e-3  # [m] widest bounding box of a link without collision shapes (contact.EMPTY_LINK_BOX)
FORK_TIMEOUT = 30.0  # [s] a forked reader that has not answered by then is ended and the link not described
_REL = 1e-5  # relative tolerance of the capsule checks (Bullet stores the sizes in float32)
_ABS = 1e-6  # [m] absolute tolerance of the capsule checks


def collision_shapes(client: int, body: int, link: int) -> tuple:
    """The collision shapes of ``body``'s ``link`` (-1: the base) as ``pb.getCollisionShapeData`` lists
    them, or ``()`` when PyBullet cannot describe them without crashing (a ``btMultiSphereShape``: an
    MJCF capsule given by ``fromto``). The link's contact is then for Bullet's narrow phase to measure
    (its bounding box is not a speck: ``contact._unlisted_shape``)."""
    if _readable(client, body, link):
        return pb.getCollisionShapeData(body, link, physicsClientId=client)
    info = pb.getConnectionInfo(physicsClientId=client)
    if info.get("connectionMethod") != pb.DIRECT or not hasattr(os, "fork"):
        return ()  # the server is not in this process: a forked copy could not ask it
    answer = _read_in_fork(client, body, link)
    return () if answer is None else answer


def round_shapes(data) -> list[tuple[int, float]]:
    """(geometry, radius [m]) of each cylinder and capsule among a link's collision shapes ``data`` (as
    :func:`collision_shapes` lists them: a cylinder's or capsule's dimensions are (length, radius, 0))."""
    return [(int(d[2]), float(d[3][1])) for d in data if d[2] in (pb.GEOM_CYLINDER, pb.GEOM_CAPSULE)]


def fixed_link(client: int, body: int, link: int) -> bool:
    """Can ``body``'s ``link`` (-1: the base) not move? Its body's base is fixed (Bullet gives a fixed base no
    mass) and every joint between the link and the base is a fixed one."""
    if pb.getDynamicsInfo(body, -1, physicsClientId=client)[0] != 0.0:
        return False
    while link >= 0:
        info = pb.getJointInfo(body, link, physicsClientId=client)
        if info[2] != pb.JOINT_FIXED:
            return False
        link = info[16]  # the parent link
    return True


def _readable(client: int, body: int, link: int) -> bool:
    """Can the link's shapes be read in this process (no btMultiSphereShape can be among them)? See the
    module's docstring for the three cases."""
    visuals = [v for v in pb.getVisualShapeData(body, physicsClientId=client) if v[1] == link]
    lo, hi = pb.getAABB(body, link, physicsClientId=client)
    widths = [h - l for l, h in zip(lo, hi)]
    if not visuals:
        return max(widths) <= SPECK
    capsules = [v for v in visuals if v[2] == pb.GEOM_CAPSULE]
    if not capsules:
        return True
    if len(visuals) > 1:
        return False
    length, radius = capsules[0][3][0], capsules[0][3][1]
    margin = pb.getDynamicsInfo(body, link, physicsClientId=client)[11]
    if abs(margin - radius) > _ABS + _REL * radius:
        return False  # a compound (URDF), or a multi-sphere shape (margin 0.04 m unless changed)
    if link < 0:
        orn = pb.getBasePositionAndOrientation(body, physicsClientId=client)[1]
    else:  # the link's centre-of-mass frame, where its collider sits
        orn = pb.getLinkState(body, link, physicsClientId=client)[1]
    rot = [abs(x) for x in pb.getMatrixFromQuaternion(orn)]  # row-major |R|
    for i in range(3):
        expect = radius * sum(rot[3 * i:3 * i + 3]) + 0.5 * length * rot[3 * i + 2]
        if abs(0.5 * widths[i] - expect) > _ABS + _REL * (length + radius):
            return False
    return True


def _read_in_fork(client: int, body: int, link: int):
    """``getCollisionShapeData`` asked in a forked copy of this process: its answer, or None when the copy
    died (a signal) or did not answer within FORK_TIMEOUT."""
    r, w = os.pipe()
    # The copy must run no finalizer of the parent's garbage: one that joins a thread the copy does not have
    # (PyAV's scaler joining its slice threads, seen in CI) blocks it until FORK_TIMEOUT, at every link read.
    collecting, pid = gc.isenabled(), -1
    gc.disable()
    try:
        with warnings.catch_warnings():  # Python >= 3.12 warns of fork in a threaded process; the copy only reads
            warnings.simplefilter("ignore", DeprecationWarning)
            pid = os.fork()
    finally:
        if collecting and pid != 0:  # the parent collects again; the copy never does
            gc.enable()
    if pid == 0:  # the copy: answer through the pipe and leave at once (no cleanup of the parent's state)
        status = 1
        try:
            os.close(r)
            faulthandler.disable()  # a crash here is expected: no traceback on the shared stderr
            try:
                import resource
                resource.setrlimit(resource.RLIMIT_CORE, (0, 0))  # nor a core file
            except (ImportError, ValueError, OSError):
                pass
            data = pickle.dumps(pb.getCollisionShapeData(body, link, physicsClientId=client))
            view = memoryview(data)
            while view:
                view = view[os.write(w, view):]
            status = 0
        finally:
            os._exit(status)
    os.close(w)
    chunks = []
    try:
        while True:
            ready, _, _ = select.select([r], [], [], FORK_TIMEOUT)
            if not ready:  # hung: end the copy (our own child, by its id)
                os.kill(pid, signal.SIGKILL)
                break
            chunk = os.read(r, 1 << 16)
            if not chunk:
                break
            chunks.append(chunk)
    finally:
        os.close(r)
        _, status = os.waitpid(pid, 0)
    if not os.WIFEXITED(status) or os.WEXITSTATUS(status) != 0 or not chunks:
        return None
    return pickle.loads(b"".join(chunks))
