"""Bullet's C API from Numba kernels: a coupled step's traffic with Bullet without Python in between.

PyBullet wraps every C API call in Python: parsing the arguments, building tuples of floats for
the answer. In the dual-arm step that wrapping (about 14 calls per step, and the Python around
them) cost more than Bullet's own step. PyBullet's shared library exports the C API
(``b3ApplyExternalForce``, ``b3RequestActualStateCommandInit``, ...); what Python cannot reach is
the C client handle of a connection. A ten-line Bullet plugin hands it over: plugins receive
the handle of their physics server (``b3PluginContext.m_physClient``), and
``executePluginCommand`` returns it in two 32-bit halves. The plugin is compiled with the
system's C compiler on first use and cached (``BULLET_DLO_CACHE``, default
``~/.cache/bullet_dlo``).

The kernels here take that handle and plain arrays. Numba cannot cache code that calls ctypes
functions, so they compile once per process (about 0.4 s each, on first use). Without a C
compiler, when the plugin does not load, or with ``BULLET_DLO_NATIVE=0``, :func:`connect`
returns 0 and callers use PyBullet's Python API; results are identical either way
(``tests/bullet/test_native.py``). Each reader checks a native read against PyBullet's once
before trusting the layout of Bullet's structs (:data:`LINK_STATE_FIELDS`).
"""
from __future__ import annotations

import ctypes
import os
import shutil
import subprocess
import sysconfig
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pybullet as pb
from numba import njit

from bullet_dlo.bullet.kernels import bind

ROW = 64
"""Doubles reserved per link state (Bullet's struct b3LinkState has 33; the rest is headroom)."""
LINK_STATE_FIELDS = 27
"""Leading doubles of b3LinkState that PyBullet's getLinkState returns (with velocities): CoM position (0:3),
CoM quaternion (3:7), local inertial position (7:10) and quaternion (10:14), link frame position
(14:17) and quaternion (17:21), linear velocity (21:24), angular velocity (24:27), world frame."""
JOINT_STATE = 9
"""Doubles of struct b3JointSensorState: position, velocity, reaction wrench (6), motor torque."""
WORLD_FRAME = 2  # EF_WORLD_FRAME of Bullet's external-force flags
SYNCED = 66  # CMD_SYNC_BODY_INFO_COMPLETED

PLUGIN_SOURCE = r"""
/* bullet_dlo: hands the C client handle of the physics server to the caller, in 32-bit halves. */
#include <stdint.h>
struct context { void *client; };            /* first member of b3PluginContext */
struct arguments { char text[1024]; };        /* first member of b3PluginArguments */
int initPlugin_bullet_dlo(struct context *c) { return API_VERSION; }
void exitPlugin_bullet_dlo(struct context *c) {}
int executePluginCommand_bullet_dlo(struct context *c, const struct arguments *a) {
    uintptr_t h = (uintptr_t)c->client;
    return a->text[0] == 'h' ? (int)(uint32_t)(h >> 32) : (int)(uint32_t)(h & 0xffffffffu);
}
"""

_lib = ctypes.CDLL(pb.__file__)  # the loaded PyBullet module: same C API, same physics servers
_U, _I = ctypes.c_uint64, ctypes.c_int  # handles and pointers pass as 64-bit integers (same ABI on x86-64)


def _c(name: str, restype, *argtypes):
    f = getattr(_lib, name)
    f.restype, f.argtypes = restype, list(argtypes)
    return f


_force_init = _c("b3ApplyExternalForceCommandInit", _U, _U)
_add_force = _c("b3ApplyExternalForce", None, _U, _I, _I, _U, _U, _I)
_add_torque = _c("b3ApplyExternalTorque", None, _U, _I, _I, _U, _I)
_submit = _c("b3SubmitClientCommandAndWaitStatus", _U, _U, _U)
_status_type = _c("b3GetStatusType", _I, _U)
_state_init = _c("b3RequestActualStateCommandInit", _U, _U, _I)
_state_velocity = _c("b3RequestActualStateCommandComputeLinkVelocity", _I, _U, _I)
_state_kinematics = _c("b3RequestActualStateCommandComputeForwardKinematics", _I, _U, _I)
_link_state = _c("b3GetLinkState", _I, _U, _U, _I, _U)
_joint_state = _c("b3GetJointState", _I, _U, _U, _I, _U)
_sync_init = _c("b3InitSyncBodyInfoCommand", _U, _U)
_actual_state = _c("b3GetStatusActualState", _I, _U, _U, _U, _U, _U, _U, _U, _U)
_overlap_init = _c("b3InitAABBOverlapQuery", _U, _U, _U, _U)
_overlap_results = _c("b3GetAABBOverlapResults", None, _U, _U)
_collision_info_init = _c("b3RequestCollisionInfoCommandInit", _U, _U, _I)
_status_aabb = _c("b3GetStatusAABB", _I, _U, _I, _U, _U)
_memcpy = ctypes.CDLL(None).memcpy  # reads the doubles behind the pointers the C API hands out
_memcpy.restype, _memcpy.argtypes = _U, [_U, _U, _U]
BASE_STATE = 13
"""Doubles per base state: CoM position (0:3), quaternion (3:7), linear (7:10) and angular (10:13) velocity."""


def enabled() -> bool:
    """Whether native calls may be used (``BULLET_DLO_NATIVE=0`` turns them off)."""
    return os.environ.get("BULLET_DLO_NATIVE", "1") != "0"


def _cache_dir() -> Path:
    base = os.environ.get("BULLET_DLO_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "bullet_dlo")
    return Path(base)


def plugin_library() -> Path | None:
    """The compiled handle plugin for this PyBullet's API version (compiled now if missing); None without a compiler."""
    version = pb.getAPIVersion()
    target = _cache_dir() / f"handle_plugin_{version}.so"
    if target.is_file():
        return target
    cc = shutil.which((sysconfig.get_config_var("CC") or "cc").split()[0]) or shutil.which("cc")
    if cc is None:
        return None
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=target.parent) as tmp:
            src, out = Path(tmp) / "handle_plugin.c", Path(tmp) / "handle_plugin.so"
            src.write_text(PLUGIN_SOURCE)
            subprocess.run([cc, "-O2", "-shared", "-fPIC", f"-DAPI_VERSION={version}", "-o", str(out), str(src)],
                           check=True, capture_output=True, timeout=60)
            os.replace(out, target)  # atomic: concurrent first uses never load a half-written library
    except (OSError, subprocess.SubprocessError):
        return None
    return target


def connect(client: int) -> int:
    """The C client handle of PyBullet connection ``client`` (0: native calls unavailable or off).

    Valid until the connection closes: its owner (a :class:`~bullet_dlo.bullet.world.BulletWorld`)
    keeps it and forgets it on close. Loading the plugin once per connection costs about 1 ms.
    """
    if not enabled():
        return 0
    path = plugin_library()
    if path is None:
        return 0
    plugin = pb.loadPlugin(str(path), "_bullet_dlo", physicsClientId=client)
    if plugin < 0:
        return 0
    low = pb.executePluginCommand(plugin, "l", physicsClientId=client) & 0xFFFFFFFF
    high = pb.executePluginCommand(plugin, "h", physicsClientId=client) & 0xFFFFFFFF
    handle = (high << 32) | low
    return handle if handle and sync_bodies(handle) else 0


def sync_bodies(handle: int) -> bool:
    """Let the handle's client learn the bodies loaded since (joint reads need their joint tables)."""
    return _status_type(_submit(handle, _sync_init(handle))) == SYNCED


def disabled_warning(what: str, why: str) -> None:
    warnings.warn(f"{what}: native Bullet calls disabled ({why}); using PyBullet's Python API", RuntimeWarning,
                  stacklevel=3)


# ----- kernels (compiled on first use, once per process) ------------------------------------------
@njit
def apply_forces(handle, bodies, force, point):
    """Force [N] (k, 3) at world point [m] (k, 3) on the base of each of ``bodies`` (k,) for the coming step."""
    for i in range(bodies.shape[0]):
        cmd = _force_init(handle)
        _add_force(cmd, bodies[i], -1, force.ctypes.data + 24 * i, point.ctypes.data + 24 * i, WORLD_FRAME)
        _submit(handle, cmd)


@njit
def apply_wrenches(handle, bodies, links, active, force, point, torque):
    """On link ``links[i]`` of each body ``bodies[i]`` with ``active[i]`` (k,): force [N] (k, 3) at world
    point [m] ``point[i]`` (k, 3) and torque [N m] (k, 3), for the coming step."""
    for i in range(bodies.shape[0]):
        if not active[i]:
            continue
        cmd = _force_init(handle)
        _add_force(cmd, bodies[i], links[i], force.ctypes.data + 24 * i, point.ctypes.data + 24 * i, WORLD_FRAME)
        _submit(handle, cmd)
        cmd = _force_init(handle)
        _add_torque(cmd, bodies[i], links[i], torque.ctypes.data + 24 * i, WORLD_FRAME)
        _submit(handle, cmd)


@njit
def read_states(handle, bodies, links, joints, link_out, joint_out):
    """One actual-state request per body (velocities and forward kinematics on): the link states of
    ``links[b]`` into ``link_out[b]`` (rows of :data:`ROW` doubles) and the state of joint ``joints[b]``
    (its reaction wrench at 2:8) into ``joint_out[b]``. Returns how many reads failed (0: all good)."""
    failed = 0
    for b in range(bodies.shape[0]):
        cmd = _state_init(handle, bodies[b])
        _state_velocity(cmd, 1)
        _state_kinematics(cmd, 1)
        status = _submit(handle, cmd)
        for k in range(links.shape[1]):
            failed += 1 - _link_state(handle, status, links[b, k], link_out.ctypes.data + 8 * ROW * (b * links.shape[1] + k))
        failed += 1 - _joint_state(handle, status, joints[b], joint_out.ctypes.data + 8 * JOINT_STATE * b)
    return failed


@njit
def read_base_states(handle, bodies, out, prev, moved):
    """Base state of each of ``bodies`` (k,) into ``out`` (k, :data:`BASE_STATE`), as PyBullet's
    getBasePositionAndOrientation and getBaseVelocity give it; ``moved[b]``: the pose differs from
    ``prev[b]`` (k, 7), which becomes it. Returns how many moved (-1: a read failed)."""
    pointers = np.zeros(2, dtype=np.uint64)  # where the status keeps q and q-dot
    count = 0
    for b in range(bodies.shape[0]):
        status = _submit(handle, _state_init(handle, bodies[b]))
        if _actual_state(status, 0, 0, 0, 0, pointers.ctypes.data, pointers.ctypes.data + 8, 0) == 0:
            return -1
        _memcpy(out.ctypes.data + 8 * BASE_STATE * b, pointers[0], 56)  # base position and quaternion
        _memcpy(out.ctypes.data + 8 * (BASE_STATE * b + 7), pointers[1], 48)  # base velocities
        same = True
        for j in range(7):
            if out[b, j] != prev[b, j]:  # NaN (never read) counts as moved
                same = False
            prev[b, j] = out[b, j]
        moved[b] = not same
        count += 0 if same else 1
    return count


@njit
def overlapping(handle, box, data, pairs):
    """PyBullet's ``getOverlappingObjects(box[0], box[1])``: the (body, link) pairs whose broad-phase boxes overlap
    ``box`` (2, 3) [m] into ``pairs`` (k, 2) int32; ``data`` (2,) int64 is scratch (Bullet's b3AABBOverlapData).
    Returns their count (-1: more than ``pairs`` holds)."""
    data[0] = 0
    data[1] = 0
    _submit(handle, _overlap_init(handle, box.ctypes.data, box.ctypes.data + 24))
    _overlap_results(handle, data.ctypes.data)
    count = data[0] & 0xFFFFFFFF  # int m_numOverlappingObjects, then the pointer to the (id, link) pairs
    if count > pairs.shape[0]:
        return -1
    if count > 0:
        _memcpy(pairs.ctypes.data, data[1], 8 * count)
    return count


class StateReader:
    """Per-step reads of a few links and one joint per body: through the native kernel when the world
    has a handle, else through PyBullet's ``getLinkStates`` and ``getJointState`` into the same arrays.

    ``links`` (b, k) [-]: link indices per body (velocities and forward kinematics computed);
    ``joints`` (b,): one joint per body (its reaction wrench). After :meth:`read`, ``link_rows``
    (b, k, ROW) holds the states (fields in :data:`LINK_STATE_FIELDS`) and ``joint_rows`` (b, 9)
    the joint states.
    """

    def __init__(self, client: int, handle: int, bodies, links, joints):
        self.client = client
        self.bodies = np.asarray(bodies, dtype=np.int32)
        self.links = np.asarray(links, dtype=np.int32).reshape(len(self.bodies), -1)
        self.joints = np.asarray(joints, dtype=np.int32)
        self.link_rows = np.zeros((len(self.bodies), self.links.shape[1], ROW))
        self.joint_rows = np.zeros((len(self.bodies), JOINT_STATE))
        self.handle = handle
        if handle:
            sync_bodies(handle)  # bodies loaded after the handle was made
            if not self._native_matches():
                disabled_warning("StateReader", "a native read differs from PyBullet's: unknown struct layout")
                self.handle = 0
        self._args = (self.handle, self.bodies, self.links, self.joints, self.link_rows, self.joint_rows)
        self._read_native = bind(read_states, *self._args) if self.handle else None  # no per-call dispatch

    def read(self) -> None:
        """Read the current states into ``link_rows`` and ``joint_rows``."""
        if self._read_native is not None:
            self._read_native(*self._args)
        else:
            self._read_python()

    def _read_python(self) -> None:
        cid = self.client
        for b, body in enumerate(self.bodies.tolist()):
            states = pb.getLinkStates(body, self.links[b].tolist(), computeLinkVelocity=1, computeForwardKinematics=1,
                                      physicsClientId=cid)
            for k, st in enumerate(states):
                self.link_rows[b, k, :LINK_STATE_FIELDS] = [v for part in st for v in part]
            js = pb.getJointState(body, int(self.joints[b]), physicsClientId=cid)
            self.joint_rows[b, :] = (js[0], js[1], *js[2], js[3])

    def _native_matches(self) -> bool:
        self._read_python()
        links, joints = self.link_rows.copy(), self.joint_rows.copy()
        if read_states(self.handle, self.bodies, self.links, self.joints, self.link_rows, self.joint_rows) != 0:
            return False
        return (np.array_equal(links[..., :LINK_STATE_FIELDS], self.link_rows[..., :LINK_STATE_FIELDS])
                and np.array_equal(joints, self.joint_rows))
