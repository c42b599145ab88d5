"""Time series of a dual-arm run on disk (NPZ, HDF5, CSV), and reading them back for ``bullet-dlo fit``.

``bullet-dlo grasp --series FILE`` records every Bullet step with :class:`SeriesRecorder` and
writes :func:`write_series`. The columns have the names and units of dataset episodes
(:mod:`bullet_dlo.data.episode`); left arm = the cable's first end, right arm = its last end;
k rows, n masses, j arm joints:

=============== ================================================================ ============
column          meaning                                                          shape
=============== ================================================================ ============
t               time [s]                                                         (k,)
cable_x         mass positions [m]                                               (k, n, 3)
wrench_world    tared wrist load on the tool, world frame [fx fy fz mx my mz]    (k, 2, 6)
                [N, N m] (the force the cable exerts on the gripper, as read)
wrench_sensor   the same in the sensor frame                                     (k, 2, 6)
end_forces      force of the cable model on each holder [N]                      (k, 2, 3)
end_moments     clamp torque of the cable model on each holder [N m]             (k, 2, 3)
joint_q/qd      arm joint angles [rad], velocities [rad/s]                       (k, 2, j)
ee_pos/quat     grasp-frame position [m] and quaternion (x, y, z, w)             (k, 2, 3/4)
=============== ================================================================ ============

Formats, by the file's suffix: ``.npz`` (numpy, the columns above plus ``attrs``, a JSON
string), ``.h5``/``.hdf5`` (one dataset per column, attributes as in episodes; a dataset
episode file is read as is), ``.csv`` (only what a fit needs, one row per sample, a header
naming the columns ``t, left_x, left_y, left_z, left_qx, left_qy, left_qz, left_qw, left_fx,
left_fy, left_fz`` and the same with ``right_``, in any order, each optionally with its unit in
brackets: ``t [s], left_x [m], ..., left_fx [N]``; lines before the header that start with ``#`` are
comments, and one holding a JSON object gives the file's attributes, as ``write_series`` writes a simulation's
``integrator``, ``dt``, ``n_masses`` and its cable's ``length`` and ``diameter``, which the fit then takes). A
recording from a real robot in any of these formats needs only ``t``, ``ee_pos``, ``ee_quat`` and ``wrench_world``
(forces; moments optional).

Optional columns a fit also uses (NPZ/HDF5): ``grasp_moment`` (k, 2, 3), the measured moments
about the grasp points [N m] (``wrench_world`` moments are about the sensor origin and are not
used as such); ``linear_map`` (k, q, 12) with ``linear_obs`` (k, q), a measurement linear in the
end wrenches (e.g. joint torques, see :mod:`bullet_dlo.analysis.fit_recording`). With
``forces="end_forces"`` the model's ``end_moments`` come along as the moments. The attributes
``integrator`` and ``dt`` [s] of a simulated file become the recording's ``source``; its wrist sensors
(``wrench_world``) read each Bullet step's joint reaction to the cable's load of the step before, so such a
file's forces get ``force_delay`` = ``dt`` (the model's ``end_forces`` none).

Units: SI unless the file says otherwise: a CSV header's brackets, an HDF5 dataset's ``units``
attribute, an NPZ ``attrs`` entry ``"units": {"ee_pos": "mm", ...}``; time s, ms or us; length m,
cm or mm; force N or mN (a wrench column's unit names its force part, e.g. ``"N, N m"``); moment
N m, N mm or mN m. ``units=`` (CLI ``--units length=mm,force=mN``) gives the units of columns the
file does not label. Whatever the units, a recording is refused (one ParameterError line, the
CLI's exit code 2) before anything runs if it cannot be what a fit needs:

* unreadable: empty, truncated or damaged files, text, complex numbers or pickled objects in a
  column (NPZ is read with ``allow_pickle=False``), HDF5 columns that are links (soft or to
  another file) or keep their data in another file (links are never followed), a FIFO or folder;
* CSV without a header naming the needed columns (they are taken by name, never by position);
* times that repeat or go back, start below 0, fewer than 3 samples;
* implausible for SI units: a median time step outside 1e-5..1 s (ms?), a grasp position
  farther than 100 m from the origin (mm?), a cable end force above 1 kN (mN?), an end moment
  above 100 N m, a grasp quaternion not of unit norm (0.01 tolerance);
* too long for a fit on a small machine: more than :data:`MAX_SAMPLES` samples or a last time
  above :data:`MAX_DURATION` [s] (``window=(t0, t1)``, CLI ``--time-window T0 T1``, cuts one out;
  its times then start at 0);
* with ``cable=`` (the CLI's --length, --diameter, --mass): grasp points farther apart than 1.5
  cable lengths, or forces whose weight is more than 30 times the cable's (or, without a mass,
  a density above 30000 kg/m^3).
"""
from __future__ import annotations

import csv
import io
import json
import math
import os
import re
import stat
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from bullet_dlo.analysis.fit import Recording
from bullet_dlo.robots.dual_arm.series import SERIES_COLUMNS, SERIES_UNITS, SeriesRecorder, save_npz  # noqa: F401  (re-exported)
from bullet_dlo.core.validate import ParameterError

CSV_FIELDS = ("x", "y", "z", "qx", "qy", "qz", "qw", "fx", "fy", "fz")
FORMATS = (".npz", ".h5", ".hdf5", ".csv")
FORCE_SOURCES = ("wrench_world", "end_forces")


def series_format(path: str | Path) -> str:
    """The file's suffix if it names a series format (ParameterError otherwise)."""
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise ParameterError(f"series file must end in {', '.join(FORMATS)}, got {str(path)!r}")
    return suffix


def write_series(path: str | Path, arrays: dict[str, np.ndarray], attrs: dict[str, Any] | None = None) -> Path:
    """Write the columns ``arrays`` (and JSON-able ``attrs``) to ``path`` in the format its suffix names."""
    path = Path(path)
    suffix = series_format(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    attrs = attrs or {}
    units = {k: SERIES_UNITS[k] for k in arrays if k in SERIES_UNITS}
    if suffix == ".npz":
        save_npz(path, arrays, attrs)
    elif suffix == ".csv":
        write_csv(path, Recording(arrays["t"], arrays["ee_pos"], arrays["ee_quat"], arrays["wrench_world"][:, :, :3]),
                  _source(attrs))
    else:
        import h5py

        with h5py.File(path, "w") as f:
            for key, arr in arrays.items():
                f.create_dataset(key, data=arr)
                if key in units:
                    f[key].attrs["units"] = units[key]
            for k, v in attrs.items():
                f.attrs[k] = v if isinstance(v, (int, float, str, bool)) else json.dumps(v, default=float)
    return path


def write_csv(path: str | Path, rec: Recording, source: dict[str, Any] | None = None) -> None:
    """The CSV form of a recording (header in the module doc, each column's unit in brackets); ``source``: the
    simulation's {"integrator", "dt"} (and "n_masses" where known: :func:`_source`), written as a first line ``# {...}`` (JSON) that :func:`read_recording` takes
    as the NPZ and HDF5 attributes (without it a simulated file's one-step wrench lag went unmodelled)."""
    header = ["t [s]"] + [f"{arm}_{c}{CSV_UNIT_SUFFIX[c]}" for arm in ("left", "right") for c in CSV_FIELDS]
    cols = [rec.t[:, None]]
    for arm in (0, 1):
        cols += [rec.grasp_pos[:, arm], rec.grasp_quat[:, arm], rec.force[:, arm]]
    first = f"# {json.dumps(source)}\n" if source else ""
    np.savetxt(path, np.hstack(cols), delimiter=",", header=first + ",".join(header), comments="", fmt="%.10g")


# ----- reading: every check of a recording file happens here -----------------------------------
MAX_SAMPLES = 250_000
"""Most samples of one recording (after ``window``): more is refused before anything is read or run."""
MAX_DURATION = 120.0
"""[s] Longest recording (its last time; the model runs from t = 0 to it, many times per fit)."""
MAX_FORCE = 1e3  # [N] a cable end force above this is taken for a unit mistake (mN)
MAX_MOMENT = 1e2  # [N m]
MAX_POSITION = 1e2  # [m] a grasp position farther than this from the origin: a unit mistake (mm)
DT_RANGE = (1e-5, 1.0)  # [s] plausible median time step (outside: ms or us taken for s)
QUAT_TOLERANCE = 1e-2  # allowed | |q| - 1 | of a grasp quaternion
UNITS = {  # quantity -> unit name (lower case, spaces removed) -> factor to SI
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6},
    "length": {"m": 1.0, "cm": 1e-2, "mm": 1e-3},
    "force": {"n": 1.0, "mn": 1e-3},
    "moment": {"nm": 1.0, "nmm": 1e-3, "mnm": 1e-3},
    "none": {"": 1.0, "1": 1.0, "-": 1.0},
}
SI = {"time": "s", "length": "m", "force": "N", "moment": "N m", "none": "1"}
COLUMN_QUANTITY = {"t": "time", "ee_pos": "length", "ee_quat": "none", "wrench_world": "force",
                   "end_forces": "force", "end_moments": "moment", "grasp_moment": "moment"}
CSV_QUANTITY = {"x": "length", "y": "length", "z": "length", "qx": "none", "qy": "none", "qz": "none", "qw": "none",
                "fx": "force", "fy": "force", "fz": "force"}
CSV_UNIT_SUFFIX = {c: (f" [{SI[q]}]" if q != "none" else "") for c, q in CSV_QUANTITY.items()}
CSV_COLUMNS = ("t",) + tuple(f"{arm}_{c}" for arm in ("left", "right") for c in CSV_FIELDS)
SI_DONE = "SI (converted while read)"  # a column a reader has already taken to SI
HEADER_UNIT = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(?:[\[(]\s*([^\])]*?)\s*[\])])?\s*$")


def parse_units(units: str | dict[str, str] | None) -> dict[str, str]:
    """``{"time": "ms", "length": "mm", ...}`` from a dict or ``"length=mm,force=mN"`` (CLI ``--units``):
    the units of the quantities a file does not state (ParameterError naming a bad entry)."""
    if not units:
        return {}
    if isinstance(units, str):
        pairs = [item.split("=", 1) for item in units.split(",") if item.strip()]
        if any(len(p) != 2 for p in pairs):
            raise ParameterError(f"units must be given as QUANTITY=UNIT,... (e.g. length=mm,force=mN), got {units!r}")
        units = {k.strip(): v.strip() for k, v in pairs}
    out = {}
    for quantity, unit in units.items():
        if quantity not in ("time", "length", "force", "moment"):
            raise ParameterError(f"units: unknown quantity {quantity!r} (time, length, force or moment)")
        unit_factor(quantity, unit, "units")
        out[quantity] = str(unit)
    return out


def unit_factor(quantity: str, unit: str, where: str) -> float:
    """The factor taking ``unit`` of ``quantity`` to SI (ParameterError naming ``where`` otherwise)."""
    key = re.sub(r"[\s*·.]", "", str(unit)).lower()
    if key not in UNITS[quantity]:
        known = {"time": "s, ms, us", "length": "m, cm, mm", "force": "N, mN", "moment": "N m, N mm, mN m",
                 "none": "none (a quaternion has no unit)"}[quantity]
        raise ParameterError(f"{where}: unit {unit!r} not understood for {quantity} (use {known})")
    return UNITS[quantity][key]


def read_recording(path: str | Path, forces: str = "wrench_world", units: str | dict[str, str] | None = None,
                   window: tuple[float, float] | None = None, cable: Any = None) -> Recording:
    """A recording for :func:`bullet_dlo.analysis.fit.fit_cable` from a CSV, NPZ or HDF5 file (a dataset
    episode works as is), checked before anything runs: every problem is one ParameterError line.

    forces: ``wrench_world`` (the wrist sensors, default) or ``end_forces`` (the model's ground truth,
    for simulated files). units: the units of quantities the file does not state, e.g.
    ``{"length": "mm", "force": "mN"}`` or ``"length=mm,force=mN"`` (else SI; module doc). window:
    (t0, t1) [s, the file's times]: only the samples with t0 <= t <= t1, their times then starting at 0
    (to cut a recording longer than :data:`MAX_DURATION`). cable: a CableSpec-like object (length,
    diameter, mass [SI], mass may be None) the recording is checked against (grasp distance and weight).
    """
    if forces not in FORCE_SOURCES:
        raise ParameterError(f"forces must be one of {', '.join(FORCE_SOURCES)}, got {forces!r}")
    flag_units = parse_units(units)
    if window is not None:
        t0, t1 = (float(v) for v in window)
        if not (math.isfinite(t0) and math.isfinite(t1) and t1 > t0):
            raise ParameterError(f"time window must be two finite times T0 < T1 [s], got {tuple(window)!r}")
        window = (t0, t1)
    path = Path(path)
    suffix = series_format(path)
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise ParameterError(f"recording {str(path)!r} not found") from None
    except OSError as err:
        raise ParameterError(f"recording {str(path)!r} cannot be read: {err.strerror}") from None
    if not stat.S_ISREG(mode):
        raise ParameterError(f"recording {str(path)!r} is not a regular file (a directory, FIFO or device)")
    if os.stat(path).st_size == 0:
        raise ParameterError(f"recording {path.name} is empty")
    reader = {".csv": _read_csv, ".npz": _read_npz}.get(suffix, _read_h5)
    try:
        raw, source = reader(path, forces, window, flag_units)
    except ParameterError:
        raise
    except Exception as err:  # noqa: BLE001 - a damaged file: whatever its parser says, as one line
        fmt = {".csv": "CSV", ".npz": "NPZ"}.get(suffix, "HDF5")
        text = " ".join(str(err).split()) or type(err).__name__
        raise ParameterError(f"recording {path.name} cannot be read as {fmt} (damaged or truncated?): "
                             f"{text[:200]}") from None
    rec = check_recording(raw, path.name, flag_units, window, source, cable)
    if rec.length is None and source and "length" in source:  # (a simulated file states its cable's length)
        rec = replace(rec, length=source["length"])
    delay = _wrench_delay(source) if forces == "wrench_world" else 0.0
    rec = replace(rec, force_delay=delay) if delay else rec
    fresh = fresh_samples(rec.force, rec.moment) if rec.force is not None else None
    if fresh is not None and rec.use is None:
        rec = replace(rec, use=fresh)
    return rec


HELD_SHARE = 0.2
"""Share of samples [-] that repeat the one before exactly, from which a recording's wrench is taken as a sensor
sampled slower than the file (held between its samples) and only its fresh samples are compared."""


def fresh_samples(force: np.ndarray, moment: np.ndarray | None) -> np.ndarray | None:
    """Which samples hold a new reading (bool (k,)) when at least :data:`HELD_SHARE` of them repeat the previous
    sample's forces (and moments) bit for bit at a steady rate (a sensor's clock: 80 % of the readings held for the
    same number of samples, +-1), else None. A wrist sensor read at a lower rate than the file's
    (``arms.sensor_rate``) holds each reading over several samples: compared as they are, the held samples are a
    lagged copy the model cannot follow, and the noise level from sample-to-sample differences comes out near zero
    (every fit then reported "model discrepancy dominates")."""
    k = force.shape[0]
    flat = force.reshape(k, -1) if moment is None else np.concatenate((force.reshape(k, -1), moment.reshape(k, -1)), 1)
    same = np.all(flat[1:] == flat[:-1], axis=1)
    if k < 4 or same.mean() < HELD_SHARE:
        return None
    fresh = np.concatenate(([True], ~same))
    runs = np.diff(np.flatnonzero(fresh))  # samples per reading
    if len(runs) < 2:
        return None
    period = np.bincount(runs).argmax()
    if period < 2 or np.mean(np.abs(runs - period) <= 1) < 0.8:  # not a sensor's clock: e.g. a noise-free
        return None  # recording at rest, whose repeats carry the static load and stay compared
    return fresh if fresh.sum() >= 3 else None


def check_recording(raw: dict[str, tuple[np.ndarray, str | None]], name: str, flag_units: dict[str, str],
                    window: tuple[float, float] | None, source: dict[str, Any] | None, cable: Any) -> Recording:
    """The one validation of a recording read from a file. ``raw``: column -> (array as read, unit stated in
    the file or None), columns t, ee_pos (k, 2, 3), ee_quat (k, 2, 4), force (k, 2, 3), optional moment
    (k, 2, 3), linear_map (k, q, 12), linear_obs (k, q)."""
    cols = {}
    for key, (arr, stated) in raw.items():
        arr = _numeric(name, key, arr)
        quantity = COLUMN_QUANTITY.get({"force": "wrench_world", "moment": "grasp_moment"}.get(key, key))
        if quantity is not None:
            arr = arr * _factor(name, key, quantity, stated, flag_units)
        cols[key] = arr
    t = cols["t"]
    if t.ndim != 1:
        raise ParameterError(f"recording {name}: t must be one column of times, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise ParameterError(f"recording {name}: t holds NaN or infinite times")
    d = np.diff(t)
    bad = np.flatnonzero(d <= 0)
    if len(bad):
        i = int(bad[0])
        what = "repeats" if d[i] == 0 else "goes back"
        raise ParameterError(f"recording {name}: time {what} at sample {i + 1} ({t[i]:.9g} -> {t[i + 1]:.9g} s); "
                             f"times must strictly increase (no duplicates)")
    if window is not None:
        keep = (t >= window[0]) & (t <= window[1])
        if keep.sum() < 3:
            raise ParameterError(f"recording {name}: fewer than 3 samples in the time window "
                                 f"{window[0]:g}..{window[1]:g} s (it spans {t[0]:g}..{t[-1]:g} s)")
        cols = {k: (v[keep] if v.ndim and len(v) == len(t) else v) for k, v in cols.items()}
        t = cols["t"] = cols["t"] - cols["t"][0]
    k = len(t)
    if k < 3:
        raise ParameterError(f"recording {name}: needs at least 3 samples, has {k}")
    if t[0] < 0:
        raise ParameterError(f"recording {name}: times start at {t[0]:g} s; they must be >= 0 (the model starts "
                             f"at t = 0; --time-window T0 T1 cuts a recording and starts it at 0)")
    step = float(np.median(d))
    if not DT_RANGE[0] <= step <= DT_RANGE[1]:
        raise ParameterError(f"recording {name}: median time step {step:.3g} outside {DT_RANGE[0]:g}..{DT_RANGE[1]:g} "
                             f"s: times must be in seconds (state the unit, e.g. a CSV header 't [ms]', or "
                             f"--units time=ms)")
    _check_length(name, k, float(t[-1]))
    for key in ("ee_pos", "ee_quat", "force", "moment"):
        if key in cols:
            cols[key] = _shaped(name, key, cols[key], (k, 2, 4 if key == "ee_quat" else 3))
    pos_max = float(np.max(np.abs(cols["ee_pos"])))
    if pos_max > MAX_POSITION:
        raise ParameterError(f"recording {name}: grasp position {pos_max:.4g} m from the origin, above "
                             f"{MAX_POSITION:g} m: positions must be in metres (mm? state the unit, e.g. a CSV "
                             f"header 'left_x [mm]', or --units length=mm)")
    norms = np.linalg.norm(cols["ee_quat"], axis=2)
    off = np.abs(norms - 1.0) > QUAT_TOLERANCE
    if off.any():
        i, arm = (int(v) for v in np.argwhere(off)[0])
        raise ParameterError(f"recording {name}: grasp quaternion of the {('left', 'right')[arm]} arm at sample {i} "
                             f"has norm {norms[i, arm]:.3g}; quaternions (x, y, z, w) must be unit (columns swapped?)")
    if "force" in cols:
        fmax = float(np.max(np.linalg.norm(cols["force"], axis=2)))
        if fmax > MAX_FORCE:
            raise ParameterError(f"recording {name}: cable end force up to {fmax:.4g} N, above {MAX_FORCE:g} N: "
                                 f"forces must be in newtons (mN? state the unit, e.g. a CSV header "
                                 f"'left_fx [mN]', or --units force=mN)")
    if "moment" in cols:
        mmax = float(np.max(np.linalg.norm(cols["moment"], axis=2)))
        if mmax > MAX_MOMENT:
            raise ParameterError(f"recording {name}: end moment up to {mmax:.4g} N m, above {MAX_MOMENT:g} N m: "
                                 f"moments must be in N m (state the unit, or --units moment='N mm')")
    if ("linear_map" in cols) != ("linear_obs" in cols):
        raise ParameterError(f"recording {name}: linear_map and linear_obs must be given together")
    linear = (cols.get("linear_map"), cols.get("linear_obs"))
    rec = Recording(t, cols["ee_pos"], cols["ee_quat"], cols.get("force"), cols.get("moment"), *linear,
                    name=Path(name).stem, source=source)
    if cable is not None:
        check_cable(rec, cable)
    return rec


def check_cable(rec: Recording, cable: Any) -> None:
    """The recording against the cable it should hold (``cable.length``, ``.diameter`` [m], ``.mass`` [kg] or
    None): grasp points farther apart than 1.5 lengths, or a weight from the forces far from the mass (or,
    without a mass, a density outside 100..30000 kg/m^3), mean a unit mistake (ParameterError). What the cable
    does not state (None) is not checked."""
    if getattr(cable, "length", None) is None:
        return
    length = float(cable.length)
    diameter = None if getattr(cable, "diameter", None) is None else float(cable.diameter)
    mass = getattr(cable, "mass", None)
    span = float(np.max(np.linalg.norm(rec.grasp_pos[:, 1] - rec.grasp_pos[:, 0], axis=1)))
    if span > 1.5 * length:
        raise ParameterError(f"recording {rec.name}: grasp points up to {span:.4g} m apart, more than 1.5 cable "
                             f"lengths ({length:g} m): positions must be in metres (mm? state the unit or "
                             f"--units length=mm)")
    if rec.force is None:
        return
    weight = -float(np.mean(rec.force[:, :, 2].sum(axis=1)))  # [N], the cable's load on both grippers
    if mass:
        if abs(weight) > 30.0 * mass * 9.81 + 0.05:
            raise ParameterError(f"recording {rec.name}: the forces carry a weight of {weight:.4g} N, more than 30 "
                                 f"times the cable's ({mass * 9.81:.3g} N): forces must be in newtons (mN? state "
                                 f"the unit or --units force=mN)")
        return
    if diameter is None:
        return
    density = max(weight, 0.0) / 9.81 / (length * math.pi * diameter ** 2 / 4)  # [kg/m^3]
    if density > 3e4:
        raise ParameterError(f"recording {rec.name}: the forces carry a weight of {weight:.4g} N, a cable density of "
                             f"{density:.3g} kg/m^3 (above 30000): forces must be in newtons (mN? state the unit "
                             f"or --units force=mN)")


def _factor(name: str, key: str, quantity: str, stated: str | None, flag_units: dict[str, str]) -> float:
    """SI factor of column ``key``: its unit as stated in the file, else as given by ``units``, else 1."""
    if stated is SI_DONE:
        return 1.0
    flag = flag_units.get(quantity)
    if stated is not None and quantity == "force":
        stated = stated.split(",")[0]  # a wrench's unit "N, N m": the force part (moments come from elsewhere)
    if stated is not None:
        factor = unit_factor(quantity, stated, f"recording {name}, column {key}")
        if flag is not None and unit_factor(quantity, flag, "units") != factor:
            raise ParameterError(f"recording {name}: column {key} says it is in {stated!r}, the units given say "
                                 f"{flag!r}")
        return factor
    return unit_factor(quantity, flag, "units") if flag is not None else 1.0


def _numeric(name: str, key: str, arr: Any) -> np.ndarray:
    """``arr`` as float if it holds real numbers (complex, text, objects: ParameterError naming ``key``)."""
    arr = np.asarray(arr)
    kind = arr.dtype.kind
    if kind == "c":
        raise ParameterError(f"recording {name}: column {key} holds complex numbers; it must hold real numbers")
    if kind not in "fiu":
        what = {"U": "text", "S": "text", "O": "Python objects", "b": "booleans", "V": "records"}.get(kind, kind)
        raise ParameterError(f"recording {name}: column {key} holds {what}; it must hold real numbers")
    return arr.astype(float)


def _shaped(name: str, key: str, arr: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """``arr`` if it has ``shape`` and finite entries (ParameterError naming ``key`` otherwise)."""
    if arr.shape != shape:
        raise ParameterError(f"recording {name}: column {key} has shape {arr.shape}, expected "
                             f"({', '.join(map(str, shape))}) for {shape[0]} times")
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"recording {name}: column {key} holds NaN or infinite values")
    return arr


def _check_length(name: str, samples: int, duration: float | None = None) -> None:
    """The caps on one recording's size, checked before anything runs."""
    if samples > MAX_SAMPLES:
        raise ParameterError(f"recording {name} has {samples} samples, more than the {MAX_SAMPLES} a fit takes: "
                             f"cut it (--time-window T0 T1, or read_recording(..., window=(t0, t1))) or downsample it")
    if duration is not None and duration > MAX_DURATION:
        raise ParameterError(f"recording {name} lasts {duration:.4g} s (the model runs from t = 0 to its last time), "
                             f"more than the {MAX_DURATION:g} s a fit takes: cut it (--time-window T0 T1 of at most "
                             f"{MAX_DURATION:g} s, or read_recording(..., window=(t0, t1)))")


def _read_csv(path: Path, forces: str, window: Any, flag_units: dict[str, str]) -> tuple[dict, None]:
    """Columns of a CSV recording, taken by the names in its header (units in brackets)."""
    data = path.read_bytes()
    rows = data.count(b"\n") + (not data.endswith(b"\n"))
    text = data.decode("utf-8-sig")
    lines = text.splitlines()
    source, skip = None, 0
    while skip < len(lines) and lines[skip].startswith("#"):  # comment lines; "# {...}": a simulation's source
        source = source or _csv_source(lines[skip][1:])
        skip += 1
    if window is None:
        _check_length(path.name, rows - 1 - skip)
    lines = lines[skip:]
    header = next(csv.reader([lines[0]])) if lines else []
    parsed = [HEADER_UNIT.match(h) for h in header]
    if not header or any(m is None for m in parsed) or not any(m and m.group(1) == "t" for m in parsed):
        raise ParameterError(f"recording {path.name} must have 21 columns named in a header line: "
                             f"{', '.join(CSV_COLUMNS[:11])}, ... right_fz (units in brackets, e.g. 't [s]'; SI "
                             f"if none); its first line is not such a header")
    names = [m.group(1) for m in parsed]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise ParameterError(f"recording {path.name}: column(s) {', '.join(dupes)} named more than once")
    missing = [c for c in CSV_COLUMNS if c not in names]
    if missing:
        raise ParameterError(f"recording {path.name} must have 21 columns named t, left_x ... right_fz (SI units, "
                             f"module bullet_dlo.data.recording); it lacks {', '.join(missing[:6])}"
                             + (f" and {len(missing) - 6} more" if len(missing) > 6 else ""))
    if len([line for line in lines[1:] if line.strip()]) < 3:
        raise ParameterError(f"recording {path.name}: needs at least 3 samples (rows below the header)")
    index = {n: i for i, n in enumerate(names)}
    unit = {n: parsed[i].group(2) for n, i in index.items()}
    try:
        values = np.loadtxt(io.StringIO(text), delimiter=",", skiprows=1 + skip, ndmin=2, dtype=float, comments=None)
    except ValueError as err:
        raise ParameterError(f"recording {path.name}: not a numeric CSV ({' '.join(str(err).split())[:160]}); "
                             f"every cell must be a real number") from None
    if values.shape[1] != len(names):
        raise ParameterError(f"recording {path.name}: rows have {values.shape[1]} cells, the header {len(names)}")

    def column(n: str) -> np.ndarray:
        quantity = "time" if n == "t" else CSV_QUANTITY[n.split("_", 1)[1]]
        return values[:, index[n]] * _factor(path.name, n, quantity, unit[n], flag_units)

    def arm_block(fields: tuple[str, ...]) -> tuple[np.ndarray, str | None]:
        return np.stack([np.stack([column(f"{arm}_{c}") for c in fields], axis=1) for arm in ("left", "right")],
                        axis=1), SI_DONE

    raw = {"t": (column("t"), SI_DONE), "ee_pos": arm_block(CSV_FIELDS[:3]), "ee_quat": arm_block(CSV_FIELDS[3:7]),
           "force": arm_block(CSV_FIELDS[7:])}
    return raw, source


def _csv_source(comment: str) -> dict[str, Any] | None:
    """The source (:func:`_source`) from a CSV comment line holding a JSON object (:func:`write_csv`), else None."""
    try:
        attrs = json.loads(comment)
    except ValueError:
        return None
    return _source(attrs) if isinstance(attrs, dict) else None


def _refuse_pickle(path: Path, err: Exception) -> None:
    """A pickle (a whole file or an object column) as one line; any other error is left to the caller."""
    with open(path, "rb") as fh:
        start = fh.read(2)
    if "object arrays" in str(err).lower() or ("pickle" in str(err).lower() and start[:1] == b"\x80"):
        raise ParameterError(f"recording {path.name} holds pickled Python objects; recordings are loaded with "
                             f"allow_pickle=False (store plain numeric arrays)") from None


def _read_npz(path: Path, forces: str, window: Any, flag_units: dict[str, str]) -> tuple[dict, dict | None]:
    """Needed columns of an NPZ recording (headers read first: no pickles, no oversized arrays)."""
    try:
        z = np.load(path, allow_pickle=False)
    except ValueError as err:
        _refuse_pickle(path, err)
        raise
    if not isinstance(z, np.lib.npyio.NpzFile):
        z_close = getattr(z, "close", None)
        if z_close:
            z_close()
        raise ParameterError(f"recording {path.name} is a single .npy array, not an NPZ archive of named columns")
    with z:
        headers = {}
        for key in z.files:
            member = key + ".npy" if key + ".npy" in z.zip.namelist() else key
            with z.zip.open(member) as fh:
                version = np.lib.format.read_magic(fh)
                read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
                shape, _, dtype = read(fh)
            if dtype.hasobject:
                raise ParameterError(f"recording {path.name}: column {key} holds pickled Python objects; recordings "
                                     f"are loaded with allow_pickle=False (store plain numeric arrays)")
            headers[key] = shape
        attrs: dict[str, Any] = {}
        if "attrs" in z.files:
            try:
                attrs = json.loads(str(z["attrs"]))
            except ValueError:
                attrs = {}
            attrs = attrs if isinstance(attrs, dict) else {}
        units = attrs.get("units") if isinstance(attrs.get("units"), dict) else {}
        needed, optional = _wanted(forces)
        _require(path, needed, optional, headers, window)
        raw = {}
        for key in needed + [c for c in optional if c in headers]:
            try:
                arr = z[key]
            except ValueError as err:
                _refuse_pickle(path, err)
                raise
            raw[_role(key, forces)] = (arr, _unit_text(units.get(key)))
    return _post(raw), _source(attrs)


def _read_h5(path: Path, forces: str, window: Any, flag_units: dict[str, str]) -> tuple[dict, dict | None]:
    """Needed columns of an HDF5 recording: datasets in the file itself, never through a link."""
    import h5py

    with h5py.File(path, "r") as f:
        needed, optional = _wanted(forces)
        present = {}
        for key in needed + optional:
            link = f.get(key, getlink=True)
            if link is None:
                continue
            if isinstance(link, (h5py.ExternalLink, h5py.SoftLink)):
                kind = "an external link to another file" if isinstance(link, h5py.ExternalLink) else "a soft link"
                raise ParameterError(f"recording {path.name}: column {key} is {kind}; links are not followed "
                                     f"(store the data in the file)")
            obj = f[key]
            if not isinstance(obj, h5py.Dataset):
                raise ParameterError(f"recording {path.name}: {key} is a group, not a dataset")
            if obj.is_virtual or obj.external:
                raise ParameterError(f"recording {path.name}: column {key} keeps its data in another file (virtual "
                                     f"or external dataset); links are not followed (store the data in the file)")
            present[key] = obj
        _require(path, needed, optional, {k: v.shape for k, v in present.items()}, window)
        raw = {}
        for key, obj in present.items():
            unit = obj.attrs.get("units", obj.attrs.get("unit"))
            raw[_role(key, forces)] = (obj[()], _unit_text(unit))
        attrs = {k: f.attrs[k] for k in ("integrator", "dt", "cable", "n_masses") if k in f.attrs}
        attrs = attrs if "integrator" in attrs else _episode_params(f.attrs)
    return _post(raw), _source(attrs)


def _episode_params(attrs: Any) -> dict[str, Any]:
    """``integrator``, ``dt``, ``n_masses`` and the cable's ``length`` and ``diameter`` from a dataset episode's
    ``params`` (a JSON object), or {}."""
    text = attrs.get("params")
    if isinstance(text, bytes):
        text = text.decode("utf-8", "replace")
    try:
        params = json.loads(text) if isinstance(text, str) else {}
    except ValueError:
        return {}
    return {k: params[k] for k in ("integrator", "dt", "n_masses", "length", "diameter")
            if isinstance(params, dict) and k in params}


def _wanted(forces: str) -> tuple[list[str], list[str]]:
    """(needed, optional) column names of an NPZ/HDF5 recording."""
    moment = "end_moments" if forces == "end_forces" else "grasp_moment"
    return ["t", "ee_pos", "ee_quat", forces], [moment, "linear_map", "linear_obs"]


def _role(key: str, forces: str) -> str:
    """Column name -> its role in :func:`check_recording` (force, moment or the name itself)."""
    return {forces: "force", "end_moments": "moment", "grasp_moment": "moment"}.get(key, key)


def _require(path: Path, needed: list[str], optional: list[str], shapes: dict[str, tuple], window: Any) -> None:
    """Needed columns present, one row per time in each, and the sample cap: from the shapes, before any data
    is read."""
    missing = [k for k in needed if k not in shapes]
    if missing:
        raise ParameterError(f"recording {path.name} lacks column(s) {', '.join(missing)}")
    t = shapes["t"]
    if len(t) != 1:
        raise ParameterError(f"recording {path.name}: t must be one column of times, got shape {tuple(t)}")
    if window is None:
        _check_length(path.name, int(t[0]))
    for key in needed[1:] + [k for k in optional if k in shapes]:
        if not shapes[key] or shapes[key][0] != t[0]:
            raise ParameterError(f"recording {path.name}: column {key} has shape {tuple(shapes[key])}, not one row "
                                 f"per time ({t[0]} times)")


def _post(raw: dict) -> dict:
    """A wrench column (k, 2, 6) gives its forces; linear_obs (k,) becomes (k, 1)."""
    if "force" in raw:
        arr, unit = raw["force"]
        if arr.ndim == 3 and arr.shape[2] == 6:
            raw["force"] = (arr[:, :, :3], unit)
    if "moment" in raw:
        arr, unit = raw["moment"]
        if arr.ndim == 3 and arr.shape[2] == 6:
            raw["moment"] = (arr[:, :, :3], unit)
    if "linear_obs" in raw and np.ndim(raw["linear_obs"][0]) == 1:
        raw["linear_obs"] = (raw["linear_obs"][0][:, None], None)
    return raw


def _unit_text(unit: Any) -> str | None:
    if unit is None:
        return None
    if isinstance(unit, bytes):
        unit = unit.decode("utf-8", "replace")
    return str(unit)


def _wrench_delay(source: dict[str, Any] | None) -> float:
    """How long [s] a simulated file's wrist wrench lags its poses: one Bullet step (``source["dt"]``); 0 for a
    file that does not say it was simulated."""
    return float(source["dt"]) if source else 0.0


def _source(attrs: dict[str, Any]) -> dict[str, Any] | None:
    """{"integrator", "dt"} from a simulated series file's attributes (None when it does not say), with
    "n_masses", "length" [m] and "diameter" [m] where they give the simulated cable's (each as an attribute of its
    own, or in ``cable``: a dict or JSON)."""
    integrator, dt = attrs.get("integrator"), attrs.get("dt")
    n = _cable_n(attrs)
    sizes = {k: v for k in ("length", "diameter") if (v := _cable_size(attrs, k)) is not None}
    if isinstance(integrator, bytes):
        integrator = integrator.decode("utf-8", "replace")
    try:
        dt = float(dt) if dt else None
    except (TypeError, ValueError):
        dt = None
    if not integrator or not dt or not math.isfinite(dt) or dt <= 0:
        return None
    return {"integrator": str(integrator), "dt": dt} | ({"n_masses": n} if n else {}) | sizes


def _cable_entry(attrs: dict[str, Any], key: str) -> Any:
    """Series attribute ``key``, else the entry ``key`` of its ``cable`` attribute (a dict or JSON), or None."""
    value = attrs.get(key)
    cable = attrs.get("cable")
    if value is None and cable is not None:
        if isinstance(cable, bytes):
            cable = cable.decode("utf-8", "replace")
        if isinstance(cable, str):
            try:
                cable = json.loads(cable)
            except ValueError:
                cable = None
        value = cable.get(key) if isinstance(cable, dict) else None
    return value


def _cable_size(attrs: dict[str, Any], key: str) -> float | None:
    """The simulated cable's ``length`` or ``diameter`` [m] from series attributes (:func:`_cable_entry`), or None
    where absent or not a plausible size (0 < value <= 100 m)."""
    try:
        value = float(_cable_entry(attrs, key))
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) and 0.0 < value <= 100.0 else None


def _cable_n(attrs: dict[str, Any]) -> int | None:
    """The simulated cable's number of masses from series attributes (``n_masses`` or ``cable``), or None."""
    n = _cable_entry(attrs, "n_masses")
    try:
        n = int(n) if n is not None and float(n) == int(n) else None
    except (TypeError, ValueError, OverflowError):
        return None
    return n if n is not None and 2 <= n <= 100_000 else None
