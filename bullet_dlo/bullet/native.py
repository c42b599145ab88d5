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

The kernels here take that handle, with the addresses of the C functions they call, as one array
(:func:`kernel_api`) and plain arrays. They call through those addresses (:func:`c_function`), not
through ctypes objects: Numba compiles a ctypes object's address into the code, which it therefore
cannot cache, and every process compiled the six kernels again (about 2.4 s of CPU each). The
addresses differ between processes (the library loads anywhere), so they travel as an argument and
the kernels are cached like every other. Without a C
compiler, when the plugin does not load, with ``BULLET_DLO_NATIVE=0`` or ``NUMBA_DISABLE_JIT=1``, :func:`connect`
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
from llvmlite import ir
from numba import types

from numba.core import cgutils
from numba.extending import intrinsic

from bullet_dlo.bullet.kernels import bind
from bullet_dlo.core.kernels.jit import njit

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


_sync_init = _c("b3InitSyncBodyInfoCommand", _U, _U)  # (Python side: connect)
_submit = _c("b3SubmitClientCommandAndWaitStatus", _U, _U, _U)
_status_type = _c("b3GetStatusType", _I, _U)

# ----- the C functions the kernels call, by address ------------------------------------------------
_C_TYPES = {"u": types.uint64, "i": types.int32, "v": types.void}
_KERNEL_API: list[str] = []  # their names; their addresses follow the handle in kernel_api()


def c_function(name: str, signature: str):
    """A Numba intrinsic ``f(api, *args)`` that calls C function ``name`` at the address ``api`` holds for it
    (``api``: :func:`kernel_api`'s array). ``signature`` "r:ab..": the return type r, then each argument's,
    u a 64-bit integer or pointer, i a C int, v void (return only); arguments are converted to them."""
    ret, params = signature.split(":")
    _KERNEL_API.append(name)
    slot = len(_KERNEL_API)  # api[0] is the handle

    @intrinsic
    def call(typingctx, api, *args):
        if len(args) != len(params) or not isinstance(api, types.Array):
            return None

        def codegen(context, builder, sig, llargs):
            table = context.make_array(api)(context, builder, llargs[0])
            where = cgutils.get_item_pointer(context, builder, api, table, [context.get_constant(types.intp, slot)])
            fnty = ir.FunctionType(ir.VoidType() if ret == "v" else context.get_value_type(_C_TYPES[ret]),
                                   [context.get_value_type(_C_TYPES[p]) for p in params])
            fn = builder.inttoptr(builder.load(where), fnty.as_pointer())
            values = [context.cast(builder, builder.extract_value(llargs[1], k), args[k], _C_TYPES[p])
                      for k, p in enumerate(params)]
            out = builder.call(fn, values)
            return context.get_dummy_value() if ret == "v" else out
        return _C_TYPES[ret](api, types.StarArgTuple.from_types(args)), codegen
    return call


force_init = c_function("b3ApplyExternalForceCommandInit", "u:u")
add_force = c_function("b3ApplyExternalForce", "v:uiiuui")
add_torque = c_function("b3ApplyExternalTorque", "v:uiiui")
submit = c_function("b3SubmitClientCommandAndWaitStatus", "u:uu")
state_init = c_function("b3RequestActualStateCommandInit", "u:ui")
state_velocity = c_function("b3RequestActualStateCommandComputeLinkVelocity", "i:ui")
state_kinematics = c_function("b3RequestActualStateCommandComputeForwardKinematics", "i:ui")
link_state = c_function("b3GetLinkState", "i:uuiu")
joint_state = c_function("b3GetJointState", "i:uuiu")
actual_state = c_function("b3GetStatusActualState", "i:uuuuuuuu")
overlap_init = c_function("b3InitAABBOverlapQuery", "u:uuu")
overlap_results = c_function("b3GetAABBOverlapResults", "v:uu")
collision_info_init = c_function("b3RequestCollisionInfoCommandInit", "u:ui")
status_aabb = c_function("b3GetStatusAABB", "i:uiuu")
step_init = c_function("b3InitStepSimulationCommand", "u:u")
memcpy = c_function("memcpy", "u:uuu")  # reads the doubles behind the pointers the C API hands out
_ADDRESSES = np.array([ctypes.cast(getattr(ctypes.CDLL(None) if n == "memcpy" else _lib, n), ctypes.c_void_p).value
                       for n in _KERNEL_API], dtype=np.uint64)
HANDLE = 0  # api[HANDLE]: the C client handle
_APIS: dict[int, np.ndarray] = {}


def kernel_api(handle: int) -> np.ndarray:
    """The kernels' first argument for connection ``handle`` (from :func:`connect`): the handle, then the
    addresses of the C functions they call in this process, uint64 (1 + functions,)."""
    api = _APIS.get(handle)
    if api is None:
        api = _APIS[handle] = np.concatenate([np.array([handle], dtype=np.uint64), _ADDRESSES])
        api.flags.writeable = False
    return api

BASE_STATE = 13
"""Doubles per base state: CoM position (0:3), quaternion (3:7), linear (7:10) and angular (10:13) velocity."""


def enabled() -> bool:
    """Whether native calls may be used (``BULLET_DLO_NATIVE=0`` turns them off, and so does ``NUMBA_DISABLE_JIT=1``:
    the kernels' C calls are compiled intrinsics, which plain Python cannot run)."""
    from numba.core import config

    return os.environ.get("BULLET_DLO_NATIVE", "1") != "0" and not config.DISABLE_JIT


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


# ----- kernels (``api``: kernel_api(handle)) ----------------------------------------------------
@njit(cache=True)
def step_simulation(api):
    """Bullet's step of the world, as PyBullet's ``stepSimulation`` takes it (one command, waited for)."""
    handle = api[HANDLE]
    submit(api, handle, step_init(api, handle))


@njit(cache=True)
def apply_forces(api, bodies, force, point):
    """Force [N] (k, 3) at world point [m] (k, 3) on the base of each of ``bodies`` (k,) for the coming step."""
    handle = api[HANDLE]
    for i in range(bodies.shape[0]):
        cmd = force_init(api, handle)
        add_force(api, cmd, bodies[i], -1, force.ctypes.data + 24 * i, point.ctypes.data + 24 * i, WORLD_FRAME)
        submit(api, handle, cmd)


@njit(cache=True)
def apply_wrenches(api, bodies, links, active, force, point, torque):
    """On link ``links[i]`` of each body ``bodies[i]`` with ``active[i]`` (k,): force [N] (k, 3) at world
    point [m] ``point[i]`` (k, 3) and torque [N m] (k, 3), for the coming step."""
    handle = api[HANDLE]
    for i in range(bodies.shape[0]):
        if not active[i]:
            continue
        cmd = force_init(api, handle)
        add_force(api, cmd, bodies[i], links[i], force.ctypes.data + 24 * i, point.ctypes.data + 24 * i, WORLD_FRAME)
        submit(api, handle, cmd)
        cmd = force_init(api, handle)
        add_torque(api, cmd, bodies[i], links[i], torque.ctypes.data + 24 * i, WORLD_FRAME)
        submit(api, handle, cmd)


@njit(cache=True)
def read_states(api, bodies, links, joints, link_out, joint_out):
    """One actual-state request per body (velocities and forward kinematics on): the link states of
    ``links[b]`` into ``link_out[b]`` (rows of :data:`ROW` doubles) and the state of joint ``joints[b]``
    (its reaction wrench at 2:8) into ``joint_out[b]``. Returns how many reads failed (0: all good)."""
    handle = api[HANDLE]
    failed = 0
    for b in range(bodies.shape[0]):
        cmd = state_init(api, handle, bodies[b])
        state_velocity(api, cmd, 1)
        state_kinematics(api, cmd, 1)
        status = submit(api, handle, cmd)
        for k in range(links.shape[1]):
            row = link_out.ctypes.data + 8 * ROW * (b * links.shape[1] + k)
            failed += 1 - link_state(api, handle, status, links[b, k], row)
        failed += 1 - joint_state(api, handle, status, joints[b], joint_out.ctypes.data + 8 * JOINT_STATE * b)
    return failed


@njit(cache=True)
def read_base_states(api, bodies, out, prev, moved):
    """Base state of each of ``bodies`` (k,) into ``out`` (k, :data:`BASE_STATE`), as PyBullet's
    getBasePositionAndOrientation and getBaseVelocity give it; ``moved[b]``: the pose differs from
    ``prev[b]`` (k, 7), which becomes it. Returns how many moved (-1: a read failed)."""
    handle = api[HANDLE]
    pointers = np.zeros(2, dtype=np.uint64)  # where the status keeps q and q-dot
    count = 0
    for b in range(bodies.shape[0]):
        status = submit(api, handle, state_init(api, handle, bodies[b]))
        if actual_state(api, status, 0, 0, 0, 0, pointers.ctypes.data, pointers.ctypes.data + 8, 0) == 0:
            return -1
        memcpy(api, out.ctypes.data + 8 * BASE_STATE * b, pointers[0], 56)  # base position and quaternion
        memcpy(api, out.ctypes.data + 8 * (BASE_STATE * b + 7), pointers[1], 48)  # base velocities
        same = True
        for j in range(7):
            if out[b, j] != prev[b, j]:  # NaN (never read) counts as moved
                same = False
            prev[b, j] = out[b, j]
        moved[b] = not same
        count += 0 if same else 1
    return count


@njit(cache=True)
def overlapping(api, box, data, pairs):
    """PyBullet's ``getOverlappingObjects(box[0], box[1])``: the (body, link) pairs whose broad-phase boxes overlap
    ``box`` (2, 3) [m] into ``pairs`` (k, 2) int32; ``data`` (2,) int64 is scratch (Bullet's b3AABBOverlapData).
    Returns their count (-1: more than ``pairs`` holds)."""
    handle = api[HANDLE]
    data[0] = 0
    data[1] = 0
    submit(api, handle, overlap_init(api, handle, box.ctypes.data, box.ctypes.data + 24))
    overlap_results(api, handle, data.ctypes.data)
    count = data[0] & 0xFFFFFFFF  # int m_numOverlappingObjects, then the pointer to the (id, link) pairs
    if count > pairs.shape[0]:
        return -1
    if count > 0:
        memcpy(api, pairs.ctypes.data, data[1], 8 * count)
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
        api = kernel_api(self.handle) if self.handle else None
        self._args = (api, self.bodies, self.links, self.joints, self.link_rows, self.joint_rows)
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
        api = kernel_api(self.handle)
        if read_states(api, self.bodies, self.links, self.joints, self.link_rows, self.joint_rows) != 0:
            return False
        return (np.array_equal(links[..., :LINK_STATE_FIELDS], self.link_rows[..., :LINK_STATE_FIELDS])
                and np.array_equal(joints, self.joint_rows))
