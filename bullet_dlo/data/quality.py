"""Force quality of an episode, and the histograms that show it across a dataset."""
from __future__ import annotations

from pathlib import Path
from typing import Iterable

import numpy as np

HF_CUTOFF = 10.0  # [Hz] above this, force variance counts as oscillation


def quality_metrics(t: np.ndarray, sensor: np.ndarray, model: np.ndarray, cutoff: float = HF_CUTOFF) -> dict:
    """Force-quality numbers of an episode.

    Args:
        t: sample times [s], shape (k,).
        sensor: wrist-sensor forces [N], shape (k, 2, 3) (left, right).
        model: the cable model's end forces [N], shape (k, 2, 3).
        cutoff: frequency [Hz] above which variance counts as high-frequency.

    Returns:
        hf_energy: share of the sensor force's variance above ``cutoff`` (oscillation);
        peak_to_mean: max |F| / mean |F| of the sensor force; sensor_model_rms: RMS of
        |F_sensor - F_model| [N]. NaN for fewer than 4 samples.
    """
    if len(t) < 4:
        return {"hf_energy": float("nan"), "peak_to_mean": float("nan"), "sensor_model_rms": float("nan")}
    dt = float(np.median(np.diff(t)))
    sig = sensor.reshape(len(t), -1) - sensor.reshape(len(t), -1).mean(axis=0)
    power = np.abs(np.fft.rfft(sig, axis=0)) ** 2
    freq = np.fft.rfftfreq(len(t), dt)
    total = power[1:].sum()
    hf = float(power[freq > cutoff].sum() / total) if total > 0 else 0.0
    mag = np.linalg.norm(sensor, axis=2)
    return {"hf_energy": hf, "peak_to_mean": float(mag.max() / max(mag.mean(), 1e-12)),
            "sensor_model_rms": float(np.sqrt(np.mean(np.sum((sensor - model) ** 2, axis=2))))}


def sensor_metrics(check) -> dict:
    """The wrist-sensor check of an episode (:class:`~bullet_dlo.robots.dual_arm.observation.SensorCheck`):
    the worst mismatch of a sample with the cable's load in the same step, force [N] and moment [N m],
    over both arms, and ``sensor_model_rms`` [N], the RMS force mismatch over every step; it replaces
    :func:`quality_metrics`' from recorded rows, whose model force is one step ahead of the sensors'."""
    return {"sensor_check_force": float(check.worst[:, 0].max()), "sensor_check_moment": float(check.worst[:, 1].max()),
            "sensor_model_rms": float(check.rms[0])}


def quality_issues(metrics: dict, weight: float, max_rms_weights: float | None, max_hf: float | None) -> list[str]:
    """Why an episode's forces should not be trusted, as short reasons (empty: none).

    metrics: from :func:`quality_metrics`; weight: the cable's weight [N]; max_rms_weights: limit on
    the RMS of sensor minus model end force, in cable weights (None: no limit); max_hf: limit on the
    high-frequency share (None: no limit). NaN metrics (too few samples) are not flagged.
    """
    issues = []
    rms = metrics.get("sensor_model_rms", float("nan"))
    if max_rms_weights is not None and rms > max_rms_weights * weight:
        limit = max_rms_weights * weight
        issues.append(f"sensor-model RMS {rms:.3g} N > {max_rms_weights:g} cable weights ({limit:.3g} N)")
    hf = metrics.get("hf_energy", float("nan"))
    if max_hf is not None and hf > max_hf:
        issues.append(f"high-frequency share {hf:.3g} > {max_hf:g}")
    return issues


def quality_limits(spec) -> tuple[float | None, float | None]:
    """(max_sensor_model_rms [cable weights], max_hf_energy [share]) of a capture directory's spec: a
    :class:`~bullet_dlo.config.capture.CaptureSpec`, or a rollout spec whose ``randomisation`` is one."""
    from bullet_dlo.config.capture import CaptureSpec

    if hasattr(spec, "randomisation"):
        spec = CaptureSpec.from_dict(spec.randomisation)
    return spec.max_sensor_model_rms, spec.max_hf_energy


def recomputed_issues(metrics: dict, weight: float, max_rms_weights: float | None,
                      max_hf: float | None) -> list[str]:
    """The quality reasons of a stored episode, recomputed from its ``metrics`` (for files that do not
    store them): :func:`quality_issues` plus the wrist-sensor check from its worst mismatch over both
    arms (``sensor_check_force`` [N], ``sensor_check_moment`` [N m]) against the check's limit."""
    from bullet_dlo.robots.dual_arm.observation import SENSOR_CHECK

    issues = quality_issues(metrics, weight, max_rms_weights, max_hf)
    allowed = SENSOR_CHECK[0] * weight + SENSOR_CHECK[1]
    for key, name, unit in (("sensor_check_force", "force", "N"), ("sensor_check_moment", "moment", "N m")):
        worst = metrics.get(key, float("nan"))
        if worst > allowed:
            issues.append(f"wrist {name} differs from the cable's load by {worst:.3g} {unit} (allowed {allowed:.3g})")
    return issues


def plot_quality(records: Iterable[dict], png: str | Path) -> None:
    """Histograms of the episodes' high-frequency share and sensor-model RMS, written to ``png``
    atomically (a new temporary file renamed over ``png``: a link there is replaced, never written through)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    metrics = [r["metrics"] for r in records if r.get("metrics")]
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.5))
    axes[0].hist([m["hf_energy"] for m in metrics], bins=20)
    axes[0].set_xlabel(f"high-frequency share of the F/T signal (> {HF_CUTOFF:g} Hz)")
    axes[1].hist([m["sensor_model_rms"] for m in metrics], bins=20)
    axes[1].set_xlabel("RMS |sensor - model end force| [N]")
    for ax in axes:
        ax.set_ylabel("episodes")
    fig.tight_layout()
    from bullet_dlo.data.safeio import atomic_write

    try:
        atomic_write(Path(png), lambda fh: fig.savefig(fh, dpi=100, format="png"))
    finally:
        plt.close(fig)
