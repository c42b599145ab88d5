"""What a fit compares: a recording's measured quantities and the model's prediction of each (residual kinds).

A :class:`Recording` holds both grippers' grasp poses over time and any of

* ``force``: the tared world-frame wrist forces [N], (k, 2, 3) (kind ``force``);
* ``moment``: the world-frame wrist moments about the grasp points [N m], (k, 2, 3) (kind ``moment``);
* ``linear_map`` (k, q, 12) with ``linear_obs`` (k, q): any quantity linear in the two end wrenches
  w = (f_left, m_left, f_right, m_right) [N, N m] (the load the cable exerts on each gripper,
  world frame), observed as y_t = A_t w_t (kind ``linear``). Joint torques of an arm holding the
  cable are tau = -J_t^T w with the per-sample grasp-point Jacobian J_t: pass A_t = -J_t^T and the
  measured torques (less what the arm's own dynamics explain), and the analysis layer needs no PyBullet;
* ``markers`` (k, m, 3) with ``marker_s`` (m,): positions of marks on the cable [m] at arc lengths
  from the first held end [m] (kind ``marker``: motion capture).

How the ends are held: ``held`` per end, ``clamped`` (the grasp pose is followed, orientation
included) or ``free`` (an end nobody holds, e.g. a strip's tip: its grasp pose is only where it
starts). ``length``: the cable's length between the held points when the recording knows it [m].
``initial``: the cable's shape and velocity at the first sample when the recording has them
(arc lengths [m], positions [m], velocities [m/s]), for a model started mid-motion.
``relative``: kinds compared as changes since the first sample (both measured and predicted),
e.g. joint torques whose absolute level carries a sensor bias. ``linear_filter``: (cut-off [Hz],
delay [s]) of a first-order low-pass after a pure delay that the measured linear kind went through
(Franka's external-torque estimate), applied to the prediction too. ``linear_band``: (low, high)
[Hz], a zero-phase band-pass applied to both the measured and the predicted linear kind (keeps a
ringing, drops what is slow: a sensor's pose-dependent bias, an arm model's errors during a motion).
``use``: which samples the residual compares (bool, (k,); None: all), e.g. not while an arm moves and
its own dynamics model's error swamps the cable's load. ``section_frame``: the grasp
frame's y axis is the held section's first axis d1 (a strip's width), for a cable with a material
frame; otherwise the section's start orientation is the core's default. ``force_delay`` [s]: the measured
force and moment (kinds ``force``, ``moment``) reach the recording this long after the poses they belong to;
the prediction is compared at t - force_delay (interpolated linearly, held at its first value before the
first sample). A dual-arm recording of this package's Bullet scene has one Bullet step: each step's
wrist sensors read the joint reaction to the load the cable put on the gripper over that step, which is the
cable's load of the step before (:mod:`bullet_dlo.data.recording` sets it when it reads one).

Optional ``source``: how a simulated recording was made, {"integrator": name, "dt": seconds}, so
a fit can say (or reproduce) the numerical damping its integrator put into the data.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
from scipy.spatial.transform import Rotation

from bullet_dlo.core.enums import RecordingHold, ResidualKind, name_of
from bullet_dlo.core.validate import ParameterError

KINDS = ResidualKind.names()  # what a recording can be compared on (bullet_dlo.core.enums.ResidualKind)
UNITS = {"force": "N", "moment": "N m", "linear": "recording units", "marker": "m"}
HELD = RecordingHold.names()  # how each end is held (bullet_dlo.core.enums.RecordingHold)
CLAMP_SIGN = (1.0, -1.0)
"""Cable tangent = sign * grasp-frame x axis, per arm (left, right)."""
RIGHT_FROM_LEFT = Rotation.from_rotvec([0.0, 0.0, math.pi])
"""A right grasp frame from the left one at the same place: turned by pi about z, so that its x axis
points into the cable (:data:`CLAMP_SIGN`)."""


@dataclass(frozen=True)
class Recording:
    """What a fit needs from a measurement, arms in the order (left, right), k samples.

    t: times [s], (k,), increasing; grasp_pos: grasp-frame positions [m], (k, 2, 3); grasp_quat:
    grasp-frame orientations as quaternions (x, y, z, w), (k, 2, 4); force: tared wrist forces on
    the tool in world frame [N], (k, 2, 3) (the force the cable exerts on each gripper), or None
    when the recording has another kind; moment: the matching moments about the grasp points
    [N m], (k, 2, 3), optional; linear_map (k, q, 12) and linear_obs (k, q): an optional generic
    linear observation of the end wrenches (module doc); name: a label for reports; source:
    {"integrator": str, "dt": float [s]} of a simulated recording, optional; markers (k, m, 3) [m]
    with marker_s (m,) [m]; held, length [m], initial, relative: see the module doc; linear_filter:
    (cut-off [Hz], delay [s]) of a first-order filter the linear kind went through, or None;
    linear_band: (low, high) [Hz] of a zero-phase band both sides are compared in, or None;
    section_frame: the grasp frame's axis that is a flat section's width (module doc); use: which
    samples the residual compares (bool, (k,); None: all); force_delay: how long [s] the measured force
    and moment lag the poses they belong to (module doc; 0: none).
    """

    t: np.ndarray
    grasp_pos: np.ndarray
    grasp_quat: np.ndarray
    force: np.ndarray | None
    moment: np.ndarray | None = None
    linear_map: np.ndarray | None = None
    linear_obs: np.ndarray | None = None
    name: str = ""
    source: dict[str, Any] | None = field(default=None, compare=False)
    markers: np.ndarray | None = None
    marker_s: np.ndarray | None = None
    held: tuple[str, str] = ("clamped", "clamped")
    length: float | None = None
    initial: tuple[np.ndarray, np.ndarray, np.ndarray] | None = field(default=None, compare=False)
    relative: tuple[str, ...] = ()
    linear_filter: tuple[float, float] | None = None
    linear_band: tuple[float, float] | None = None
    section_frame: bool = False
    use: np.ndarray | None = field(default=None, compare=False)
    force_delay: float = 0.0

    def __post_init__(self) -> None:
        t = _finite("t", self.t, np.shape(self.t)) if np.ndim(self.t) == 1 else np.zeros((0, 0))
        k = len(t)
        if t.ndim != 1 or k < 3 or np.any(np.diff(t) <= 0):
            raise ParameterError("recording t must hold at least 3 strictly increasing times [s]")
        object.__setattr__(self, "t", t)
        for name, width in (("grasp_pos", 3), ("grasp_quat", 4), ("force", 3), ("moment", 3)):
            if getattr(self, name) is None and name in ("force", "moment"):
                continue
            object.__setattr__(self, name, _finite(name, getattr(self, name), (k, 2, width)))
        if np.any(np.linalg.norm(self.grasp_quat, axis=2) < 1e-9):
            raise ParameterError("recording grasp_quat holds a zero quaternion; grasp orientations must be unit "
                                 "quaternions (x, y, z, w)")
        if (self.linear_map is None) != (self.linear_obs is None):
            raise ParameterError("recording linear_map and linear_obs must be given together")
        if self.linear_obs is not None:
            obs = np.asarray(self.linear_obs, dtype=float)
            obs = obs[:, None] if obs.ndim == 1 else obs
            q = obs.shape[1] if obs.ndim == 2 else 0
            object.__setattr__(self, "linear_obs", _finite("linear_obs", obs, (k, q)))
            object.__setattr__(self, "linear_map", _finite("linear_map", self.linear_map, (k, q, 12)))
        if self.use is not None:
            use = np.asarray(self.use)
            if use.shape != (k,) or use.dtype != bool or use.sum() < 3:
                raise ParameterError(f"recording use must be a boolean mask of shape ({k},) selecting >= 3 samples")
            object.__setattr__(self, "use", use)
        delay = float(self.force_delay) if isinstance(self.force_delay, (int, float)) else math.nan
        if not (math.isfinite(delay) and 0.0 <= delay < 0.5 * (t[-1] - t[0])):
            raise ParameterError(f"recording force_delay must be >= 0 and below half the recording's span "
                                 f"({0.5 * (t[-1] - t[0]):g} s) [s], got {self.force_delay!r}")
        object.__setattr__(self, "force_delay", delay)
        self._check_markers(k)
        self._check_holding()
        if not self.kinds():
            raise ParameterError("recording must hold force, moment, linear_map/linear_obs or markers/marker_s")

    def _check_markers(self, k: int) -> None:
        if (self.markers is None) != (self.marker_s is None):
            raise ParameterError("recording markers and marker_s must be given together")
        if self.markers is None:
            return
        s = np.asarray(self.marker_s, dtype=float)
        if s.ndim != 1 or len(s) < 1 or not np.all(np.isfinite(s)):
            raise ParameterError("recording marker_s must be a finite 1-D array of arc lengths [m]")
        object.__setattr__(self, "marker_s", s)
        object.__setattr__(self, "markers", _finite("markers", self.markers, (k, len(s), 3)))

    def _check_holding(self) -> None:
        held = tuple(self.held)
        if len(held) != 2 or any(h not in HELD for h in held) or held == ("free", "free"):
            raise ParameterError(f"recording held must name each end's hold among {', '.join(HELD)} (at least one "
                                 f"clamped), got {self.held!r}")
        object.__setattr__(self, "held", held)
        if self.length is not None and not (math.isfinite(self.length) and self.length > 0):
            raise ParameterError(f"recording length must be > 0 [m], got {self.length!r}")
        object.__setattr__(self, "relative", tuple(name_of("recording relative kind", k, ResidualKind)
                                                   for k in self.relative))
        if self.linear_filter is not None:
            cut, delay = (float(v) for v in self.linear_filter)
            if not (math.isfinite(cut) and cut > 0 and math.isfinite(delay) and delay >= 0):
                raise ParameterError(f"recording linear_filter must be (cut-off > 0 [Hz], delay >= 0 [s]), got "
                                     f"{self.linear_filter!r}")
            object.__setattr__(self, "linear_filter", (cut, delay))
        if self.linear_band is not None:
            low, high = (float(v) for v in self.linear_band)
            nyquist = 0.5 / float(np.median(np.diff(self.t)))
            if not 0 < low < high < nyquist:
                raise ParameterError(f"recording linear_band must be 0 < low < high < {nyquist:g} Hz (the Nyquist "
                                     f"frequency), got {self.linear_band!r}")
            object.__setattr__(self, "linear_band", (low, high))
        if self.initial is not None:
            s, x, v = (np.asarray(a, dtype=float) for a in self.initial)
            if s.ndim != 1 or len(s) < 2 or np.any(np.diff(s) <= 0) or x.shape != (len(s), 3) or v.shape != x.shape \
                    or not (np.all(np.isfinite(x)) and np.all(np.isfinite(v))):
                raise ParameterError("recording initial must be (arc lengths (p >= 2,) increasing [m], positions "
                                     "(p, 3) [m], velocities (p, 3) [m/s]), finite")
            object.__setattr__(self, "initial", (s, x, v))

    def kinds(self) -> list[str]:
        """The residual kinds this recording can give (of :data:`KINDS`)."""
        have = {"force": self.force is not None, "moment": self.moment is not None,
                "linear": self.linear_obs is not None, "marker": self.markers is not None}
        return [k for k in KINDS if have[k]]

    def observed(self, kind: str) -> np.ndarray:
        """The measured quantity of ``kind``, one row per sample: (k, channels)."""
        return compared(self, kind, self._raw(kind))

    def _raw(self, kind: str) -> np.ndarray:
        if kind == "linear":
            return self.linear_obs
        if kind == "marker":
            return self.markers.reshape(len(self.t), -1)
        return getattr(self, kind).reshape(len(self.t), 6)

    def clamp_directions(self) -> np.ndarray:
        """Cable tangent held by each gripper (unit), (k, 2, 3)."""
        out = np.empty_like(self.grasp_pos)
        for arm in (0, 1):
            out[:, arm] = CLAMP_SIGN[arm] * Rotation.from_quat(self.grasp_quat[:, arm]).as_matrix()[:, :, 0]
        return out


def _finite(name: str, value: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a float array of ``shape`` (ParameterError naming it otherwise)."""
    a = np.asarray(value) if value is not None else np.zeros(0)
    if a.dtype.kind not in "fiu":
        what = "complex numbers" if a.dtype.kind == "c" else f"{a.dtype} values"
        raise ParameterError(f"recording {name} holds {what}; it must hold real numbers")
    a = a.astype(float)
    if a.shape != shape or not np.all(np.isfinite(a)):
        raise ParameterError(f"recording {name} must be finite with shape ({', '.join(map(str, shape))})")
    return a


class ModelRun(NamedTuple):
    """What the model did at the recorded times: end forces [N] and clamp moments [N m] (the loads the
    cable exerts on each holder), each (k, 2, 3); x: node positions [m], (k, n, 3), and s: the nodes' arc
    lengths from the first end [m], (n,), when a kind needs them (else None)."""

    forces: np.ndarray
    moments: np.ndarray
    x: np.ndarray | None = None
    s: np.ndarray | None = None


def predicted(rec: Recording, kind: str, run: ModelRun) -> np.ndarray:
    """The model's prediction of ``kind`` from its run at the recorded times: (k, channels)."""
    return compared(rec, kind, _predicted_raw(rec, kind, run))


def compared(rec: Recording, kind: str, y: np.ndarray) -> np.ndarray:
    """A measured or predicted ``kind`` (k, channels) as the residual compares it: band-passed (the linear
    kind, when ``rec.linear_band``) and as changes since the first sample (kinds in ``rec.relative``)."""
    if kind == "linear" and rec.linear_band is not None:
        y = band_passed(y, rec.t, *rec.linear_band)
    return y - y[0] if kind in rec.relative else y


def _predicted_raw(rec: Recording, kind: str, run: ModelRun) -> np.ndarray:
    k = len(rec.t)
    if kind == "force":
        return delayed(run.forces.reshape(k, 6), rec.t, rec.force_delay)
    if kind == "moment":
        return delayed(run.moments.reshape(k, 6), rec.t, rec.force_delay)
    if kind == "marker":
        return markers_on(run.x, run.s, rec.marker_s).reshape(k, -1)
    f, m = run.forces, run.moments
    wrench = np.concatenate([f[:, 0], m[:, 0], f[:, 1], m[:, 1]], axis=1)  # (k, 12)
    y = np.einsum("kqj,kj->kq", rec.linear_map, wrench)
    return y if rec.linear_filter is None else low_pass_delayed(y, rec.t, *rec.linear_filter)


def delayed(y: np.ndarray, t: np.ndarray, delay: float) -> np.ndarray:
    """``y`` (k, c) at times ``t`` [s] as seen ``delay`` [s] later: its value at t - delay, linearly interpolated
    between samples and held at y[0] before t[0] (``y`` itself when ``delay`` is 0)."""
    if delay == 0.0:
        return y
    return np.stack([np.interp(t - delay, t, y[:, c]) for c in range(y.shape[1])], axis=1)


def band_passed(y: np.ndarray, t: np.ndarray, low: float, high: float) -> np.ndarray:
    """``y`` (k, ...) at uniform times ``t`` [s] through a zero-phase 2nd-order Butterworth band-pass
    [low, high] [Hz] along axis 0 (forward and backward: no delay, gain 1 in the band)."""
    from scipy.signal import butter, sosfiltfilt

    sos = butter(2, (low, high), btype="bandpass", fs=1.0 / float(np.median(np.diff(t))), output="sos")
    return sosfiltfilt(sos, y, axis=0)


def low_pass_delayed(y: np.ndarray, t: np.ndarray, cutoff: float, delay: float) -> np.ndarray:
    """``y`` (k, ...) at times ``t`` [s] (uniform) delayed by ``delay`` [s] (whole samples) and then through a
    first-order low-pass of cut-off ``cutoff`` [Hz] (discretised exactly for a held input), starting at rest
    at y[0]: a sensor's filtered estimate of y."""
    from scipy.signal import lfilter

    dt = float(np.median(np.diff(t)))
    a = 1.0 - math.exp(-2.0 * math.pi * cutoff * dt)
    shift = int(round(delay / dt))
    delayed = np.concatenate([np.repeat(y[:1], shift, axis=0), y[:len(y) - shift]]) if shift else y
    return lfilter([a], [1.0, a - 1.0], delayed, axis=0, zi=(1.0 - a) * delayed[:1])[0]


def markers_on(x: np.ndarray, s_nodes: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Positions [m] of marks at arc lengths ``s`` [m] on the mass chain ``x`` (k, n, 3) whose nodes sit
    at ``s_nodes`` [m]: linear between neighbouring nodes (the chain's own shape), extrapolated along
    the end segment beyond the ends; (k, len(s), 3)."""
    j = np.clip(np.searchsorted(s_nodes, s) - 1, 0, len(s_nodes) - 2)
    w = (s - s_nodes[j]) / (s_nodes[j + 1] - s_nodes[j])
    return (1.0 - w)[None, :, None] * x[:, j] + w[None, :, None] * x[:, j + 1]


def noise_scale(y: np.ndarray) -> float:
    """A robust per-entry noise level of a signal (k, channels) [its units]: the median absolute first
    difference / (0.6745 sqrt 2), floored at 1e-6 of the signal's largest magnitude (and 1e-12)."""
    d = np.diff(y, axis=0)
    mad = float(np.median(np.abs(d - np.median(d, axis=0)))) / (0.6745 * np.sqrt(2.0)) if len(d) else 0.0
    return max(mad, 1e-6 * float(np.abs(y).max()), 1e-12)
