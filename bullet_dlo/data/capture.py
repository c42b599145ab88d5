"""Domain-randomised force datasets: capture (local pool or Ray), storage, reading, summary.

One HDF5 file per episode (``episode_000012.h5``), written under a temporary name and
renamed when complete; a manifest (``manifest.jsonl``, one line per finished episode,
written only by the coordinating process); ``capture.json`` with the spec and its digest so
that a directory never mixes specs. ``--resume`` skips finished episodes, removes temporary
files and re-runs the rest; a crashed episode is retried once and then recorded as failed
with its error; a killed worker is replaced.

Every episode is checked against the core's stability analysis before it runs; the spec's
policy decides what happens to samples the chosen integrator cannot run stably (``reject``
and resample, switch to ``implicit`` Euler, or add ``substeps``), and the decision is stored.
Runs that still go unstable are stopped and kept, flagged, with their time of instability.
"""
from __future__ import annotations

import json
import math
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError

SAFETY = 0.9  # run explicit methods at most at 0.9 x their predicted critical step
MAX_SUBSTEPS = 2000


def version() -> str:
    from bullet_dlo import __version__

    return __version__


# ----- stability-aware sampling ------------------------------------------------------------------
def plan_episode(spec: CaptureSpec, index: int) -> tuple[dict, dict]:
    """Parameters of episode ``index`` after the stability policy, and the recorded decision."""
    from bullet_dlo.core.model import CableModel
    from bullet_dlo.core.stability import critical_dt

    attempt = 0
    while True:
        params = spec.draw(index, attempt)
        resolved_n = None
        if params["n_masses"] == "auto":
            params["n_masses"], params["damping"] = auto_masses(spec, params)
            resolved_n = params["n_masses"]
        cable = cable_spec(params)
        model = CableModel.straight(cable, ends=("clamped", "clamped"))
        crit = critical_dt(model, params["integrator"])
        safe = crit is None or params["dt"] <= SAFETY * crit
        decision = {"policy": spec.policy, "critical_dt": crit, "attempts": attempt + 1, "action": "none",
                    "substeps": 1, "resolved_n_masses": resolved_n}
        if safe:
            return params, decision
        if spec.policy == "reject" and attempt + 1 < spec.max_resamples:
            attempt += 1
            continue
        if spec.policy == "substeps" and crit and params["dt"] / (SAFETY * crit) <= MAX_SUBSTEPS:
            decision["substeps"] = int(math.ceil(params["dt"] / (SAFETY * crit)))
            decision["action"] = f"substeps x{decision['substeps']}"
            return params, decision
        decision["action"] = f"switched {params['integrator']} -> implicit_euler"
        if spec.policy == "reject":
            decision["action"] += f" after {attempt + 1} rejected samples"
        params["integrator"] = "implicit_euler"
        return params, decision


def auto_masses(spec: CaptureSpec, params: dict) -> tuple[int, float]:
    """Number of masses (and its k_d) for ``n_masses: auto``: a convergence test on the episode's
    own motion (both ends clamped, the right end's move), end forces within ``spec.resolve_tol``."""
    from bullet_dlo.analysis.resolve import resolve_masses
    from bullet_dlo.config.scene import Scene
    from bullet_dlo.core.boundary import Move

    disp = (params["displacement_x"], params["displacement_y"], params["displacement_z"])
    dist = float(np.linalg.norm(disp))
    motion = (Move("last", disp, params["move_start"], dist / params["speed"]),) if dist > 0 else ()
    scene = Scene(cable=cable_spec({**params, "n_masses": 10}), motion=motion, duration=spec.duration,
                  initial="static", name="episode")
    return resolve_masses(scene, spec.resolve_tol, "forces")


def cable_spec(params: dict) -> CableSpec:
    return CableSpec(length=params["length"], diameter=params["diameter"], mass=params["mass"],
                     youngs_modulus=params["youngs_modulus"], n_masses=params["n_masses"],
                     damping=params["damping"], friction=params["friction"])


# ----- one episode -------------------------------------------------------------------------------
def quality_metrics(t: np.ndarray, sensor: np.ndarray, model: np.ndarray, cutoff: float = 10.0) -> dict:
    """Force-quality numbers of an episode (sensor, model: (k, 2, 3) [N]).

    hf_energy: share of the sensor force's variance above ``cutoff`` Hz (oscillation);
    peak_to_mean: max |F| / mean |F|; sensor_model_rms: RMS of |F_sensor - F_model| [N].
    """
    if len(t) < 4:
        return {"hf_energy": float("nan"), "peak_to_mean": float("nan"), "sensor_model_rms": float("nan")}
    dt = float(np.median(np.diff(t)))
    sig = sensor.reshape(len(t), -1) - sensor.reshape(len(t), -1).mean(axis=0)
    spec = np.abs(np.fft.rfft(sig, axis=0)) ** 2
    freq = np.fft.rfftfreq(len(t), dt)
    total = spec[1:].sum()
    hf = float(spec[freq > cutoff].sum() / total) if total > 0 else 0.0
    mag = np.linalg.norm(sensor, axis=2)
    return {"hf_energy": hf, "peak_to_mean": float(mag.max() / max(mag.mean(), 1e-12)),
            "sensor_model_rms": float(np.sqrt(np.mean(np.sum((sensor - model) ** 2, axis=2))))}


def run_episode(spec_dict: dict, index: int, out_dir: str) -> dict:
    """Simulate and store episode ``index``; returns its manifest record (runs in a worker)."""
    import h5py
    import pybullet as pb

    from bullet_dlo.render.camera import capture, default_camera
    from bullet_dlo.robots.dual_arm import DualArmConfig, DualArmScene

    spec = CaptureSpec.from_dict(spec_dict)
    params, decision = plan_episode(spec, index)
    config = DualArmConfig(robot=params["robot"], cable=cable_spec(params), dt=params["dt"],
                           integrator=params["integrator"], hold_height=params["hold_height"],
                           sensor_rate=params["sensor_rate"] or None, noise_std=(params["noise_std"],) * 3 + (0.0,) * 3,
                           seed=params["noise_seed"], renderer="tiny" if spec.camera_fps > 0 else None,
                           substeps=decision["substeps"])
    disp = np.array([params["displacement_x"], params["displacement_y"], params["displacement_z"]])
    rows: dict[str, list] = {k: [] for k in ("t", "cable_x", "cable_v", "wrench_world", "wrench_sensor",
                                              "wrench_raw", "end_forces", "end_moments", "joint_q", "joint_qd",
                                              "joint_tau", "ee_pos", "ee_quat")}
    frames, frame_t = [], []
    with DualArmScene(config) as scene:
        scene.grasp()
        distance = float(np.linalg.norm(disp))
        if distance > 0:
            scene.move("right", disp, distance / params["speed"], start=params["move_start"])
        every = max(1, int(round(1.0 / (spec.record_rate * config.dt))))
        cam = default_camera([(-0.6, 0, 0), (0.6, 0, 0), (0, 0, 0.6)], spec.camera_width, spec.camera_height)
        next_frame = [0.0]

        def record() -> None:
            w = scene.world
            if w.steps % every == 0:
                rows["t"].append(w.time)
                rows["cable_x"].append(scene.cable.x.copy())
                rows["cable_v"].append(scene.cable.v.copy())
                rows["wrench_world"].append([s.last.world() for s in scene.sensors])
                rows["wrench_sensor"].append([s.last.sensor() for s in scene.sensors])
                rows["wrench_raw"].append([s.raw() for s in scene.sensors])
                rows["end_forces"].append(scene.cable.end_forces())
                rows["end_moments"].append(scene.cable.end_moments())
                states = [pb.getJointStates(r.body, r.arm_joints, physicsClientId=w.client) for r in scene.robots]
                rows["joint_q"].append([[s[0] for s in st] for st in states])
                rows["joint_qd"].append([[s[1] for s in st] for st in states])
                rows["joint_tau"].append([[s[3] for s in st] for st in states])
                poses = [r.grasp_pose() for r in scene.robots]
                rows["ee_pos"].append([p for p, _ in poses])
                rows["ee_quat"].append([q for _, q in poses])
            if spec.camera_fps > 0 and w.time + 1e-12 >= next_frame[0]:
                frames.append(capture(w.client, cam, w.renderer).rgb)
                frame_t.append(w.time)
                next_frame[0] += 1.0 / spec.camera_fps

        scene.world.after_step.append(record)
        scene.run(spec.duration)
        stable, t_bad = scene.cable.stable, scene.cable.time_to_instability
        reason = scene.cable.reason
    data = {k: np.asarray(v, dtype=float) for k, v in rows.items()}
    metrics = quality_metrics(data["t"], data["wrench_world"][:, :, :3], data["end_forces"])
    name = f"episode_{index:06d}.h5"
    final = Path(out_dir) / name
    tmp = final.with_suffix(f".h5.tmp-{os.getpid()}")
    with h5py.File(tmp, "w", libver="latest") as f:
        for key, arr in data.items():
            f.create_dataset(key, data=arr, track_times=False)
        if frames:
            f.create_dataset("frames", data=np.asarray(frames, dtype=np.uint8), track_times=False,
                             compression="gzip", compression_opts=4, chunks=(1,) + np.asarray(frames[0]).shape)
            f.create_dataset("frame_t", data=np.asarray(frame_t), track_times=False)
        attrs = {"params": json.dumps(params, sort_keys=True), "decision": json.dumps(decision, sort_keys=True),
                 "metrics": json.dumps(metrics, sort_keys=True), "seed": spec.seed, "episode": index,
                 "version": version(), "spec_digest": spec.digest(), "stable": bool(stable),
                 "time_to_instability": -1.0 if t_bad is None else float(t_bad),
                 "columns": "left arm = cable first end, right arm = last end; wrench rows [fx fy fz mx my mz]; "
                            "wrench_world/sensor: tared load on the tool; wrench_raw: PyBullet joint reaction"}
        for k, v in attrs.items():
            f.attrs[k] = v
    os.replace(tmp, final)
    return {"episode": index, "file": name, "status": "ok" if stable else "flagged", "error": None,
            "time_to_instability": t_bad, "reason": reason, "params": params, "decision": decision,
            "metrics": metrics}


def _safe_episode(spec_dict: dict, index: int, out_dir: str) -> dict:
    """run_episode that turns an exception into a failed record (the worker survives)."""
    import traceback

    try:
        return run_episode(spec_dict, index, out_dir)
    except Exception as err:  # noqa: BLE001 - recorded, not swallowed
        return {"episode": index, "file": None, "status": "failed", "error": f"{type(err).__name__}: {err}",
                "traceback": traceback.format_exc(limit=3)}


# ----- capture driver ----------------------------------------------------------------------------
@dataclass
class CaptureResult:
    out: Path
    done: int
    ran: int
    failed: int
    flagged: int
    wall_time_s: float

    @property
    def episodes_per_second(self) -> float:
        return self.ran / self.wall_time_s if self.wall_time_s > 0 else float("nan")


def _read_manifest(out: Path) -> dict[int, dict]:
    records: dict[int, dict] = {}
    path = out / "manifest.jsonl"
    if path.is_file():
        for line in path.read_text().splitlines():
            try:
                rec = json.loads(line)
            except json.JSONDecodeError:
                continue  # a line cut by a kill: the episode will be reconciled or re-run
            records[int(rec["episode"])] = rec
    return records


def _append(out: Path, record: dict) -> None:
    with open(out / "manifest.jsonl", "a") as fh:
        fh.write(json.dumps(record, sort_keys=True, default=float) + "\n")
        fh.flush()
        os.fsync(fh.fileno())


def _prepare(spec: CaptureSpec, out: Path, resume: bool) -> dict[int, dict]:
    """Check the directory belongs to this spec, clean temporaries, reconcile finished files."""
    out.mkdir(parents=True, exist_ok=True)
    meta = out / "capture.json"
    if meta.is_file():
        old = json.loads(meta.read_text())
        if old.get("digest") != spec.digest():
            raise ParameterError(f"{out} holds a capture of a different spec (digest {old.get('digest')} vs "
                                 f"{spec.digest()}); use another directory")
        if not resume and _read_manifest(out):
            raise ParameterError(f"{out} already holds episodes of this spec; pass --resume to continue")
    else:
        meta.write_text(json.dumps({"digest": spec.digest(), "spec": spec.to_dict(), "version": version()},
                                   indent=2, default=str))
    for tmp in out.glob("*.tmp-*"):
        tmp.unlink()
    records = _read_manifest(out)
    for path in sorted(out.glob("episode_*.h5")):  # finished file whose manifest line was lost
        index = int(path.stem.split("_")[1])
        if index not in records or records[index].get("status") == "failed":
            rec = episode_record(path)
            if rec is not None:
                _append(out, rec)
                records[index] = rec
    return records


def episode_record(path: Path) -> dict | None:
    """Rebuild a manifest record from a finished episode file (None if unreadable)."""
    import h5py

    try:
        with h5py.File(path, "r") as f:
            a = f.attrs
            t_bad = float(a["time_to_instability"])
            return {"episode": int(a["episode"]), "file": path.name, "status": "ok" if a["stable"] else "flagged",
                    "error": None, "time_to_instability": None if t_bad < 0 else t_bad, "reason": None,
                    "params": json.loads(a["params"]), "decision": json.loads(a["decision"]),
                    "metrics": json.loads(a["metrics"])}
    except Exception:  # noqa: BLE001 - a corrupt file is re-run
        path.unlink(missing_ok=True)
        return None


def capture(spec: CaptureSpec, out: str | Path, episodes: int, *, workers: int = 1, backend: str = "local",
            resume: bool = False, progress: bool = True, retries: int = 1) -> CaptureResult:
    """Capture episodes 0..episodes-1 of ``spec`` into ``out`` (see module doc)."""
    from tqdm import tqdm

    if backend not in ("local", "ray"):
        raise ParameterError(f"backend must be local or ray, got {backend!r}")
    if episodes < 1 or workers < 1:
        raise ParameterError("episodes and workers must be >= 1")
    out = Path(out)
    records = _prepare(spec, out, resume)
    todo = [i for i in range(episodes) if records.get(i, {}).get("status") not in ("ok", "flagged")]
    tries = {i: 0 for i in todo}
    bar = tqdm(total=episodes, initial=episodes - len(todo), desc="episodes", unit="ep", disable=not progress)
    tic = time.perf_counter()
    spec_dict = spec.to_dict()
    ran = 0
    runner = _run_ray if backend == "ray" else _run_local
    while todo:
        pending = list(todo)
        todo = []
        for index, rec in runner(spec_dict, pending, str(out), workers):
            if rec["status"] == "failed" and tries[index] < retries:
                tries[index] += 1
                todo.append(index)  # retry once
                continue
            _append(out, rec)
            records[index] = rec
            ran += 1
            bar.update(1)
        # episodes lost with a crashed pool come back through the runner's own resubmission
    bar.close()
    wall = time.perf_counter() - tic
    final = _read_manifest(out)
    statuses = [final[i]["status"] for i in range(episodes) if i in final]
    return CaptureResult(out, len(statuses), ran, statuses.count("failed"), statuses.count("flagged"), wall)


def _run_local(spec_dict: dict, indices: list[int], out: str, workers: int) -> Iterable[tuple[int, dict]]:
    """Process pool; a crashed worker (BrokenProcessPool) is replaced and its episodes re-submitted."""
    import multiprocessing as mp

    remaining = list(indices)
    crashes = {i: 0 for i in indices}
    while remaining:
        ctx = mp.get_context("spawn")
        with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
            futures = {pool.submit(_safe_episode, spec_dict, i, out): i for i in remaining}
            finished: set[int] = set()
            try:
                for fut in as_completed(futures):
                    i = futures[fut]
                    finished.add(i)
                    yield i, fut.result()
            except BrokenProcessPool:
                pass
        lost = [i for i in remaining if i not in finished]
        for i in lost:
            crashes[i] += 1
        for i in [i for i in lost if crashes[i] > 1]:  # killed twice: record and move on
            yield i, {"episode": i, "file": None, "status": "failed", "error": "worker process died twice"}
        remaining = [i for i in lost if crashes[i] <= 1]


def _run_ray(spec_dict: dict, indices: list[int], out: str, workers: int) -> Iterable[tuple[int, dict]]:
    """Ray tasks (``ray.init()`` joins RAY_ADDRESS if set, else starts a local instance)."""
    try:
        import ray
    except ImportError:
        raise ParameterError("backend 'ray' needs Ray: pip install 'bullet_dlo[ray]'") from None
    if not ray.is_initialized():
        ray.init(num_cpus=None if os.environ.get("RAY_ADDRESS") else workers, include_dashboard=False,
                 log_to_driver=False)
    task = ray.remote(max_retries=1)(_safe_episode)
    refs = {task.remote(spec_dict, i, out): i for i in indices}
    while refs:
        done, _ = ray.wait(list(refs), num_returns=1)
        for ref in done:
            i = refs.pop(ref)
            try:
                yield i, ray.get(ref)
            except Exception as err:  # noqa: BLE001 - e.g. the worker node died
                yield i, {"episode": i, "file": None, "status": "failed", "error": f"{type(err).__name__}: {err}"}


# ----- reading -----------------------------------------------------------------------------------
def load_episode(path: str | Path) -> dict[str, Any]:
    """All arrays of an episode file plus ``params``, ``decision``, ``metrics`` and attributes."""
    import h5py

    with h5py.File(path, "r") as f:
        out: dict[str, Any] = {k: f[k][()] for k in f.keys()}
        for k, v in f.attrs.items():
            out[k] = json.loads(v) if k in ("params", "decision", "metrics") else v
    return out


class Dataset:
    """A capture directory: its manifest and episodes, filterable by status, parameters, quality."""

    def __init__(self, root: str | Path):
        self.root = Path(root)
        if not (self.root / "capture.json").is_file():
            raise ParameterError(f"{self.root} is not a capture directory (no capture.json)")
        self.records = [r for _, r in sorted(_read_manifest(self.root).items())]

    def select(self, status: str | None = "ok", where: Callable[[dict], bool] | None = None,
               max_hf_energy: float | None = None) -> list[dict]:
        """Manifest records with ``status`` (None: any), ``where(params)`` true, hf energy below the bound."""
        out = []
        for r in self.records:
            if status is not None and r["status"] != status:
                continue
            if where is not None and not where(r.get("params", {})):
                continue
            if max_hf_energy is not None and not r.get("metrics", {}).get("hf_energy", 1.0) <= max_hf_energy:
                continue
            out.append(r)
        return out

    def load(self, record: dict) -> dict[str, Any]:
        return load_episode(self.root / record["file"])

    def summary(self, png: str | Path | None = None) -> dict:
        """Counts, flagged runs, parameter coverage; writes a quality histogram when ``png`` is given."""
        statuses = [r["status"] for r in self.records]
        numeric = {}
        for r in self.records:
            for k, v in (r.get("params") or {}).items():
                if isinstance(v, (int, float)) and not isinstance(v, bool):
                    numeric.setdefault(k, []).append(v)
        coverage = {k: [float(min(v)), float(max(v))] for k, v in numeric.items() if min(v) != max(v)}
        flagged = [{"episode": r["episode"], "time_to_instability": r.get("time_to_instability")}
                   for r in self.records if r["status"] == "flagged"]
        decisions: dict[str, int] = {}
        for r in self.records:
            action = (r.get("decision") or {}).get("action", "n/a")
            key = action.split(" ")[0] if action else "none"
            decisions[key] = decisions.get(key, 0) + 1
        out = {"episodes": len(self.records), "ok": statuses.count("ok"), "flagged": statuses.count("flagged"),
               "failed": statuses.count("failed"), "flagged_runs": flagged, "coverage": coverage,
               "decisions": decisions}
        if png is not None:
            import matplotlib

            matplotlib.use("Agg")
            import matplotlib.pyplot as plt

            hf = [r["metrics"]["hf_energy"] for r in self.records if r.get("metrics")]
            rms = [r["metrics"]["sensor_model_rms"] for r in self.records if r.get("metrics")]
            fig, axes = plt.subplots(1, 2, figsize=(9, 3.5))
            axes[0].hist(hf, bins=20)
            axes[0].set_xlabel("high-frequency share of the F/T signal (> 10 Hz)")
            axes[1].hist(rms, bins=20)
            axes[1].set_xlabel("RMS |sensor - model end force| [N]")
            for ax in axes:
                ax.set_ylabel("episodes")
            fig.tight_layout()
            fig.savefig(png, dpi=100)
            plt.close(fig)
        return out
