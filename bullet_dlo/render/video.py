"""Videos from headless runs.

* :class:`VideoWriter`: browser-playable H.264 MP4 (yuv420p, faststart) through PyAV, which
  ships its own FFmpeg with libx264; falls back to VP9 WebM, then to a PNG sequence, and
  reports what it wrote.
* :class:`Recorder`: renders frames at a chosen fps, independent of the physics rate, from
  a :class:`~bullet_dlo.bullet.world.BulletWorld` hook.
* :func:`side_by_side`: the scene on the left, a force plot with a moving time cursor on the right.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from bullet_dlo.core.timing import RateGate
from bullet_dlo.core.validate import ParameterError, check_positive
from bullet_dlo.render.camera import Camera, Frame, Renderer, render_frame
from bullet_dlo.render.plots import PlotInfo, plot_wrenches  # noqa: F401  (re-exported: their home before 0.2)
from bullet_dlo.render.tube import CableTube

FORMATS = ("mp4", "webm", "png")


class VideoWriter:
    """Write RGB frames (H, W, 3) uint8 to ``path`` (suffix chosen by the format that works).

    fmt: ``auto`` (H.264 MP4, else VP9 WebM, else PNG sequence) or one of mp4 | webm | png.
    After :meth:`close`, ``path``, ``format`` and ``codec`` say what was written. A video is written under a
    temporary name in the same folder (``.scene.mp4.part-<pid>``) and renamed to ``path`` by :meth:`close`,
    so a file under its final name is always a whole video; :meth:`abort` (or leaving a ``with`` block by an
    exception, a Ctrl-C included) removes the partial file.
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
        self._partial: Path | None = None

    def __enter__(self) -> "VideoWriter":
        return self

    def __exit__(self, kind, *_) -> None:
        if kind is None:
            self.close()
        else:
            self.abort()

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
                partial = path.with_name(f".{path.name}.part-{os.getpid()}")
                options = {"movflags": "+faststart"} if fmt == "mp4" else {}
                container = av.open(str(partial), "w", format=fmt, options=options)
                self._partial = partial
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
        """Flush the encoder and close the file (a no-op for PNG sequences and when closed)."""
        if self._container is not None:
            for packet in self._stream.encode():
                self._container.mux(packet)
            self._container.close()
            self._container = None
            os.replace(self._partial, self.path)
            self._partial = None

    def abort(self) -> None:
        """Stop writing and remove the partial video (the final name is never written; PNG frames stay)."""
        container, self._container = self._container, None
        if container is not None:
            try:
                container.close()
            except Exception:  # noqa: BLE001 - the file goes anyway
                pass
        if self._partial is not None:
            self._partial.unlink(missing_ok=True)
            self._partial = None


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
    """Render frames of a Bullet world at ``fps`` [Hz], independent of its step.

    Attach with ``world.after_step.append(recorder.on_step)``; frames go to ``writer`` (if
    any) and the last one is kept in ``last``; ``times`` holds the time [s] of each frame.
    ``tube``: a CableTube to update before each frame; ``progress``: anything with
    ``update(1)`` (a tqdm bar), called per frame.
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
        self._gate = RateGate(check_positive("fps", self.fps))

    def on_step(self) -> None:
        """Render if the world's time reached the next frame time."""
        if self._gate.due(self.world.time):
            self.snap()

    def snap(self) -> Frame:
        """Render one frame now."""
        if self.tube is not None:
            self.tube.update()
        mass_of_body = self.tube.mass_of_body() if self.tube is not None else None
        self.last = render_frame(self.world.client, self.camera, self.renderer, mass_of_body)
        self.times.append(self.world.time)
        if self.writer is not None:
            self.writer.write(self.last.rgb)
        if self.progress is not None:
            self.progress.update(1)
        return self.last


def side_by_side(scene_video: str | Path, plot: PlotInfo, t_frames: np.ndarray, out_path: str | Path,
                 fps: float) -> VideoWriter:
    """Video with the scene (left) and the force plot with a moving time cursor (right).

    scene_video: a video written by :class:`VideoWriter` (decoded again); t_frames: the time
    [s] of each of its frames; the cursor is drawn inside each of the plot's time axes.
    """
    import av

    image = cv2.imread(str(plot.path))[:, :, ::-1]
    writer = VideoWriter(out_path, fps)
    t0, t1 = plot.t_range
    with writer, av.open(str(scene_video)) as container:
        for k, frame in enumerate(container.decode(video=0)):
            scene = frame.to_ndarray(format="rgb24")
            h = scene.shape[0]
            scale = h / image.shape[0]
            right = np.ascontiguousarray(cv2.resize(image, (int(image.shape[1] * scale), h),
                                                    interpolation=cv2.INTER_AREA))
            t = t_frames[min(k, len(t_frames) - 1)]
            for x0, x1, y0, y1 in plot.axes_px:
                x = int((x0 + (x1 - x0) * (t - t0) / max(t1 - t0, 1e-9)) * scale)
                cv2.line(right, (x, int(y0 * scale)), (x, int(y1 * scale)), (220, 30, 30), 2)
            writer.write(np.concatenate([scene, right], axis=1))
    return writer
