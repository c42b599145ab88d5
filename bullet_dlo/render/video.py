"""Videos and plots from headless runs.

* :class:`VideoWriter`: browser-playable H.264 MP4 (yuv420p, faststart) through PyAV, which
  ships its own FFmpeg with libx264; falls back to VP9 WebM, then to a PNG sequence, and
  reports what it wrote.
* :class:`Recorder`: captures frames at a chosen fps, independent of the physics rate, from
  a :class:`~bullet_dlo.bullet_scene.BulletWorld` hook.
* :func:`plot_wrenches` / :func:`side_by_side`: force time series of both wrists with the
  model's end forces, and a video with the scene on the left and the plot with a moving
  cursor on the right.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from bullet_dlo.core.validate import ParameterError, check_positive
from bullet_dlo.render.camera import CableTube, Camera, Frame, Renderer, capture

FORMATS = ("mp4", "webm", "png")


class VideoWriter:
    """Write RGB frames (H, W, 3) uint8 to ``path`` (suffix chosen by the format that works).

    fmt: ``auto`` (H.264 MP4, else VP9 WebM, else PNG sequence) or one of mp4 | webm | png.
    After :meth:`close`, ``path``, ``format`` and ``codec`` say what was written.
    """

    def __init__(self, path: str | Path, fps: float, fmt: str = "auto"):
        self.fps = check_positive("fps", fps)
        if fmt not in ("auto",) + FORMATS:
            raise ParameterError(f"video format must be auto, mp4, webm or png, got {fmt!r}")
        self.base = Path(path).with_suffix("")
        self.base.parent.mkdir(parents=True, exist_ok=True)
        self.wanted = fmt
        self.format: str | None = None
        self.codec: str | None = None
        self.path: Path | None = None
        self.frames = 0
        self._container = self._stream = None

    def _open(self, width: int, height: int) -> None:
        order = FORMATS if self.wanted == "auto" else (self.wanted,)
        errors = []
        for fmt in order:
            try:
                if fmt == "png":
                    self.path = self.base
                    self.path.mkdir(parents=True, exist_ok=True)
                    self.format, self.codec = "png", "png"
                    return
                import av

                codec = "libx264" if fmt == "mp4" else "libvpx-vp9"
                path = self.base.with_suffix("." + fmt)
                options = {"movflags": "+faststart"} if fmt == "mp4" else {}
                container = av.open(str(path), "w", options=options)
                stream = container.add_stream(codec, rate=int(round(self.fps)))
                stream.width, stream.height, stream.pix_fmt = width, height, "yuv420p"
                if fmt == "mp4":
                    stream.options = {"crf": "23", "preset": "veryfast"}
                self._container, self._stream, self.path = container, stream, path
                self.format, self.codec = fmt, "h264" if fmt == "mp4" else "vp9"
                return
            except Exception as err:  # noqa: BLE001 - try the next format, report all
                errors.append(f"{fmt}: {err}")
        raise RuntimeError("no video format could be written: " + "; ".join(errors))

    def write(self, rgb: np.ndarray) -> None:
        """Append one frame (even width and height are required by yuv420p: odd ones are cropped)."""
        img = np.ascontiguousarray(rgb[: rgb.shape[0] // 2 * 2, : rgb.shape[1] // 2 * 2, :3], dtype=np.uint8)
        if self.format is None:
            self._open(img.shape[1], img.shape[0])
        if self.format == "png":
            cv2.imwrite(str(self.path / f"frame_{self.frames:06d}.png"), img[:, :, ::-1])
        else:
            import av

            for packet in self._stream.encode(av.VideoFrame.from_ndarray(img, format="rgb24")):
                self._container.mux(packet)
        self.frames += 1

    def close(self) -> None:
        if self._container is not None:
            for packet in self._stream.encode():
                self._container.mux(packet)
            self._container.close()
            self._container = None


def probe_video(path: str | Path) -> dict:
    """Codec, frame count and size of a video file, by decoding it (PyAV)."""
    import av

    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        frames = sum(1 for _ in container.decode(video=0))
        return {"codec": stream.codec_context.name, "frames": frames, "width": stream.width,
                "height": stream.height}


@dataclass
class Recorder:
    """Capture frames of a Bullet world at ``fps``, independent of its step.

    Attach with ``world.after_step.append(recorder.on_step)``; frames go to ``writer`` (if
    any) and the last one is kept in ``last``. ``tube``: a CableTube to update before each frame.
    """

    world: object
    camera: Camera
    renderer: Renderer
    fps: float = 30.0
    writer: VideoWriter | None = None
    tube: CableTube | None = None
    times: list = field(default_factory=list)
    last: Frame | None = None
    progress: object = None

    def __post_init__(self) -> None:
        check_positive("fps", self.fps)
        self._next = 0.0

    def on_step(self) -> None:
        """Capture if the world's time reached the next frame time."""
        if self.world.time + 1e-12 < self._next:
            return
        self.snap()
        self._next += 1.0 / self.fps

    def snap(self) -> Frame:
        if self.tube is not None:
            self.tube.update()
        mass_of_body = self.tube.mass_of_body() if self.tube is not None else None
        self.last = capture(self.world.client, self.camera, self.renderer, mass_of_body)
        self.times.append(self.world.time)
        if self.writer is not None:
            self.writer.write(self.last.rgb)
        if self.progress is not None:
            self.progress.update(1)
        return self.last


@dataclass(frozen=True)
class PlotInfo:
    """A written plot: its file, time range [s] and the pixel x-range of each time axis."""

    path: Path
    t_range: tuple[float, float]
    axes_px: tuple[tuple[int, int], ...]


def plot_wrenches(t: np.ndarray, sensor: np.ndarray | None, model: np.ndarray, path: str | Path,
                  title: str = "wrist forces") -> PlotInfo:
    """PNG of sensor forces (k, 2, >=3) and model end forces (k, 2, 3) [N] over t [s], per arm."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 2, figsize=(10, 6.5), sharex=True)
    for a, arm in enumerate(("left / first end", "right / last end")):
        for k, comp in enumerate("xyz"):
            ax = axes[k, a]
            if sensor is not None:
                ax.plot(t, sensor[:, a, k], lw=1.2, label="wrist sensor (tared, world)")
            ax.plot(t, model[:, a, k], "--", lw=1.0, label="model end force")
            ax.set_ylabel(f"F{comp} [N]")
            if k == 0:
                ax.set_title(arm)
    axes[0, 0].legend(fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    fig.suptitle(title)
    fig.tight_layout()
    for ax in axes.ravel():
        ax.set_xlim(float(t[0]), float(t[-1]))
    path = Path(path)
    fig.savefig(path, dpi=100)
    fig.canvas.draw()
    cols = tuple((int(axes[0, a].get_window_extent().x0), int(axes[0, a].get_window_extent().x1)) for a in range(2))
    plt.close(fig)
    return PlotInfo(path, (float(t[0]), float(t[-1])), cols)


def side_by_side(scene_video: str | Path, plot: PlotInfo, t_frames: np.ndarray, out_path: str | Path,
                 fps: float) -> VideoWriter:
    """Video with the scene (left) and the force plot with a moving time cursor (right).

    scene_video: a video written by :class:`VideoWriter` (decoded again); t_frames: the time
    [s] of each of its frames.
    """
    import av

    image = cv2.imread(str(plot.path))[:, :, ::-1]
    writer = VideoWriter(out_path, fps)
    t0, t1 = plot.t_range
    with av.open(str(scene_video)) as container:
        for k, frame in enumerate(container.decode(video=0)):
            scene = frame.to_ndarray(format="rgb24")
            h = scene.shape[0]
            scale = h / image.shape[0]
            right = np.ascontiguousarray(cv2.resize(image, (int(image.shape[1] * scale), h)))
            t = t_frames[min(k, len(t_frames) - 1)]
            for x0, x1 in plot.axes_px:
                x = int((x0 + (x1 - x0) * (t - t0) / max(t1 - t0, 1e-9)) * scale)
                cv2.line(right, (x, 0), (x, h - 1), (220, 30, 30), 2)
            writer.write(np.concatenate([scene, right], axis=1))
    writer.close()
    return writer
