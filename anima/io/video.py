"""Video and audio I/O through imageio-ffmpeg (a static ffmpeg inside the wheel: H.264, HEVC, VP9, AAC...).

* :func:`probe_video` validates a file and returns :class:`VideoInfo` (native fps, size, frame count
  from the container's packet timestamps, variable-frame-rate detection, audio presence).
* :func:`iter_frames` decodes RGB uint8 frames at the native rate (a variable-frame-rate file is
  resampled to constant rate at its nominal fps, with a warning), prefetching on a thread so decode
  overlaps tracking. A truncated file yields the frames that decode and records a warning.
* :class:`VideoWriter` encodes H.264 (yuv420p) and can mux an audio track.
"""

from __future__ import annotations

import os
import queue
import subprocess
import threading
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import imageio_ffmpeg
import numpy as np

# ffmpeg is started by vfork + exec, not fork: imageio-ffmpeg's default (a pre-exec hook that keeps Ctrl-C from
# the child) forces a full fork(), whose pthread_atfork handlers make numba's TBB pool print to stdout when a
# render thread starts an encoder (it corrupted --json output). An interrupted encode is discarded anyway (every
# video is written to a temporary name first).
os.environ.setdefault("IMAGEIO_FFMPEG_NO_PREVENT_SIGINT", "1")

from anima.errors import InputError
from anima.io.atomic import commit, temp_sibling

FFMPEG = imageio_ffmpeg.get_ffmpeg_exe()


@dataclass
class VideoInfo:
    path: str
    fps: float
    width: int
    height: int
    n_frames: int  # packets in the video stream (what decoding will give, barring corruption)
    duration: float
    codec: str
    has_audio: bool
    variable_frame_rate: bool = False
    warnings: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def _packet_pts(path: str) -> tuple[np.ndarray, float]:
    """Presentation timestamps (s) of the video packets, read without decoding (ffmpeg framemd5)."""
    cmd = [
        FFMPEG,
        "-hide_banner",
        "-nostdin",
        "-v",
        "error",
        "-i",
        path,
        "-map",
        "0:v:0",
        "-c",
        "copy",
        "-f",
        "framemd5",
        "-",
    ]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    tb = None
    pts = []
    for line in res.stdout.splitlines():
        if line.startswith("#tb 0:"):
            num, den = line.split(":", 1)[1].strip().split("/")
            tb = float(num) / float(den)
        elif line and not line.startswith("#"):
            parts = [p.strip() for p in line.split(",")]
            if len(parts) >= 3 and parts[0] == "0":
                try:
                    pts.append(int(parts[2]))
                except ValueError:
                    pass
    if tb is None:
        return np.zeros(0), 0.0
    return np.sort(np.asarray(pts, np.float64)) * tb, tb


def probe_video(path: str | os.PathLike) -> VideoInfo:
    """Check that ``path`` is a readable video and describe it. Raises :class:`InputError` otherwise."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"video not found: {p}")
    if p.is_dir():
        raise InputError(f"expected a video file, got a folder: {p}")
    if p.stat().st_size == 0:
        raise InputError(f"video file is empty: {p}")
    try:
        gen = imageio_ffmpeg.read_frames(str(p))
        meta = next(gen)
        gen.close()
    except (RuntimeError, OSError, StopIteration, ValueError) as e:
        first = str(e).strip().splitlines()[-1] if str(e).strip() else type(e).__name__
        raise InputError(
            f"not a readable video (corrupt, truncated before its index, or not a video): {p} ({first})"
        ) from None
    if "size" not in meta or not meta.get("fps"):
        raise InputError(f"no video stream in {p}")
    w, h = meta["size"]
    pts, _ = _packet_pts(str(p))
    fps = float(meta["fps"])
    warn = []
    vfr = False
    if len(pts) >= 3:
        d = np.diff(pts)
        d = d[d > 0]
        irregular = np.abs(d - np.median(d)) > 0.25 * np.median(d) if len(d) else np.zeros(0, bool)
        if irregular.sum() >= 3 and irregular.mean() > 0.05:
            vfr = True
            warn.append(
                f"variable frame rate (frame intervals {d.min() * 1000:.1f}-{d.max() * 1000:.1f} ms): "
                f"resampled to a constant {fps:g} fps"
            )
    n = len(pts) if len(pts) else int(round(float(meta.get("duration", 0)) * fps))
    duration = float(meta.get("duration") or (n / fps))
    expected = int(round(duration * fps))
    if vfr:
        n = expected
    elif len(pts) and n < 0.95 * expected - 1:
        warn.append(
            f"the file holds {n} of the {expected} frames its header announces (truncated?): "
            f"keeping the {n} that are there"
        )
    return VideoInfo(
        str(p), fps, int(w), int(h), int(n), duration, str(meta.get("codec", "?")), "audio_codec" in meta, vfr, warn
    )


def iter_frames(info: VideoInfo, prefetch: int = 8, errors: list[str] | None = None) -> Iterator[np.ndarray]:
    """Yield RGB uint8 frames ``(H, W, 3)``. Decoding runs on a thread ``prefetch`` frames ahead.
    Decode errors after the first frame end the iteration and are appended to ``errors``."""
    out_params = ["-vsync", "cfr", "-r", f"{info.fps:.6f}"] if info.variable_frame_rate else ["-vsync", "0"]
    q: queue.Queue = queue.Queue(maxsize=prefetch)
    stop = threading.Event()
    sentinel = object()

    def worker():
        gen = None
        try:
            gen = imageio_ffmpeg.read_frames(info.path, output_params=out_params)
            meta = next(gen)
            w, h = meta["size"]
            for buf in gen:
                if stop.is_set():
                    break
                q.put(np.frombuffer(buf, np.uint8).reshape(h, w, 3))
        except Exception as e:
            q.put(("__error__", str(e).strip().splitlines()[-1] if str(e).strip() else type(e).__name__))
        finally:
            if gen is not None:
                try:
                    gen.close()
                except Exception:
                    pass
            q.put(sentinel)

    t = threading.Thread(target=worker, daemon=True)
    t.start()
    try:
        while True:
            item = q.get()
            if item is sentinel:
                break
            if isinstance(item, tuple):
                msg = f"decoding stopped early ({item[1]}); keeping the frames decoded so far"
                if errors is not None:
                    errors.append(msg)
                else:
                    warnings.warn(msg, stacklevel=2)
                continue
            yield item
    finally:
        stop.set()
        while t.is_alive():
            try:
                q.get(timeout=0.05)
            except queue.Empty:
                pass
        t.join(timeout=1)


def read_video(path: str | os.PathLike, max_frames: int | None = None) -> tuple[np.ndarray, VideoInfo]:
    """Decode a whole (short) video into ``(T, H, W, 3)`` uint8."""
    info = probe_video(path)
    frames = []
    for i, f in enumerate(iter_frames(info)):
        if max_frames is not None and i >= max_frames:
            break
        frames.append(f)
    if not frames:
        raise InputError(f"no frame could be decoded from {path}")
    return np.stack(frames), info


PRESET = "veryfast"  # x264: 1.7x less encode time than its default (medium) at the same CRF and file size here


class VideoWriter:
    """H.264 MP4 writer; ``audio_path`` (any file with an audio track) is muxed in as AAC.

    Atomic: frames go to a unique temporary sibling of ``path``, which replaces ``path`` only when
    :meth:`close` finishes the encode. A run killed or failing mid-render (:meth:`abort`, or leaving a
    ``with`` block by an exception) leaves the previous file, or none, never a truncated video."""

    def __init__(
        self,
        path: str | os.PathLike,
        fps: float,
        size: tuple[int, int],
        audio_path: str | None = None,
        quality: int = 7,
    ):
        self.path = str(path)
        Path(self.path).parent.mkdir(parents=True, exist_ok=True)
        self._tmp = temp_sibling(self.path)
        w, h = size
        self.size = (int(w) + (int(w) % 2), int(h) + (int(h) % 2))
        self._gen = imageio_ffmpeg.write_frames(
            str(self._tmp),
            self.size,
            fps=float(fps),
            quality=quality,
            codec="libx264",
            macro_block_size=2,
            pix_fmt_in="yuv420p",  # converted here by OpenCV (SIMD): half the bytes through the pipe, no swscale
            audio_path=audio_path,
            audio_codec="aac" if audio_path else None,
            output_params=["-preset", PRESET, "-movflags", "+faststart"],
            ffmpeg_log_level="error",
        )
        self._gen.send(None)
        self.n = 0

    def write(self, frame: np.ndarray) -> None:
        frame = np.ascontiguousarray(frame, dtype=np.uint8)
        if frame.ndim == 2:
            frame = np.repeat(frame[..., None], 3, -1)
        h, w = frame.shape[:2]
        if (w, h) != self.size:
            pad = np.zeros((self.size[1], self.size[0], 3), np.uint8)
            pad[:h, :w] = frame[: self.size[1], : self.size[0]]
            frame = pad
        self._gen.send(cv2.cvtColor(frame, cv2.COLOR_RGB2YUV_I420))
        self.n += 1

    def close(self) -> None:
        """Finish the encode and put the video in place."""
        if self._gen is None:
            return
        try:
            self._gen.close()
        except BaseException:
            self._gen = None
            self._remove_tmp()
            raise
        self._gen = None
        commit(self._tmp, self.path)

    def abort(self) -> None:
        """Stop without touching ``path`` (the temporary file is removed)."""
        if self._gen is not None:
            try:
                self._gen.close()
            except Exception:
                pass
            self._gen = None
        self._remove_tmp()

    def _remove_tmp(self) -> None:
        try:
            Path(self._tmp).unlink()
        except FileNotFoundError:
            pass

    def __enter__(self):
        return self

    def __exit__(self, exc_type, *exc):
        if exc_type is None:
            self.close()
        else:
            self.abort()
