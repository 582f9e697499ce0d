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
import re
import subprocess
import tempfile
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

try:
    import fcntl
except ImportError:  # not on Windows
    fcntl = None

FFMPEG = imageio_ffmpeg.get_ffmpeg_exe()
MIN_FPS, MAX_FPS = 1.0, 1000.0  # frame rates anima reads (a 1000-fps high-speed clip included)


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


def _packet_pts(path: str, raw: bool = False) -> tuple[np.ndarray, float]:
    """Presentation timestamps (s) of the video packets, sorted, read without decoding (ffmpeg framemd5).
    ``raw``: on the file's own clock (``-copyts``: what a decoder reports), not shifted to start near 0."""
    cmd = [
        FFMPEG,
        "-hide_banner",
        "-nostdin",
        "-v",
        "error",
        *(["-copyts"] if raw else []),
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
    if "size" not in meta:
        raise InputError(f"no video stream in {p}")
    w, h = meta["size"]
    pts, _ = _packet_pts(str(p))
    fps = float(meta.get("fps") or 0)
    if fps <= 0 and len(pts) >= 2:  # ffmpeg prints "1k fps" for 1000 fps, which imageio does not read
        d = np.diff(pts)
        fps = round(1.0 / float(np.median(d[d > 0])), 3) if (d > 0).any() else 0.0
    if fps <= 0:
        raise InputError(f"no video stream in {p} (no frame rate)")
    if not MIN_FPS <= fps <= MAX_FPS:
        raise InputError(
            f"{p}: {fps:g} frames per second; anima reads videos of {MIN_FPS:g} to {MAX_FPS:g} fps (below 1 fps a "
            "video holds no motion to track)"
        )
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


def frame_times(path: str | os.PathLike) -> np.ndarray:
    """Presentation time (s, on the file's own clock) of each frame, in display order, read without decoding:
    the frame numbering that :func:`iter_frame_range` takes."""
    return _packet_pts(str(path), raw=True)[0]


_SHOWINFO = re.compile(r"pts_time:\s*(-?[0-9.]+(?:e[-+]?[0-9]+)?)")


def _stamped_decoder(info: VideoInfo, seek: float | None, prefetch: int):
    """An ffmpeg decoding ``info``'s video (from the keyframe before ``seek`` seconds, original timestamps kept)
    and its two reader threads, started: ``(process, queue of (timestamp, frame) then None, stop event, threads,
    the log's last lines)``."""
    q: queue.Queue = queue.Queue(maxsize=prefetch)
    stop_ev = threading.Event()
    proc = subprocess.Popen(
        [FFMPEG, "-hide_banner", "-nostdin", "-loglevel", "info"]
        + (["-ss", f"{seek:.6f}", "-noaccurate_seek"] if seek is not None else [])
        + ["-copyts", "-i", info.path, "-map", "0:v:0", "-vf", "showinfo", "-vsync", "0"]
        + ["-f", "rawvideo", "-pix_fmt", "rgb24", "-"],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    stamps: queue.Queue = queue.Queue()
    tail: list[str] = []

    def read_log(proc=proc, stamps=stamps, tail=tail):
        for raw_line in proc.stderr:
            line = raw_line.decode(errors="replace")
            m = _SHOWINFO.search(line)
            if m:
                stamps.put(float(m.group(1)))
            elif line.strip():
                tail[:] = (tail + [line.strip()])[-3:]
        stamps.put(None)

    def read_frames(proc=proc, q=q, stop_ev=stop_ev, stamps=stamps):
        size = info.width * info.height * 3
        try:
            while not stop_ev.is_set():
                buf = proc.stdout.read(size)
                if len(buf) < size:
                    break
                ts = stamps.get()
                if ts is None:
                    break
                q.put((ts, np.frombuffer(buf, np.uint8).reshape(info.height, info.width, 3)))
        finally:
            q.put(None)

    threads = [threading.Thread(target=f, daemon=True) for f in (read_log, read_frames)]
    for th in threads:
        th.start()
    return proc, q, stop_ev, threads, tail


def _stop_decoder(proc, q: queue.Queue, stop_ev: threading.Event, threads: list) -> None:
    """Stop a :func:`_stamped_decoder`: its process killed, its threads drained and joined."""
    stop_ev.set()
    proc.kill()
    while any(th.is_alive() for th in threads):
        try:
            q.get(timeout=0.05)
        except queue.Empty:
            pass
    for th in threads:
        th.join(timeout=1)
    proc.wait()


def iter_frame_range(
    info: VideoInfo,
    start: int,
    stop: int | None = None,
    times: np.ndarray | None = None,
    prefetch: int = 8,
    errors: list[str] | None = None,
) -> Iterator[tuple[int, np.ndarray]]:
    """Frames ``start`` to ``stop - 1`` of a constant-frame-rate video, as ``(index, RGB uint8 frame)``: the
    same pixels :func:`iter_frames` yields at those indices, without decoding what lies before.

    ffmpeg seeks to the keyframe before the first frame (a second of margin) and keeps the original
    timestamps (``-copyts``); each decoded frame's timestamp (``showinfo``) is matched to :func:`frame_times`
    (``times``, read here when not given), so the range is exact whatever the container's seek precision
    (timestamp seeks alone land a frame early on FLV and on the last frames of some MP4s). Should the seek land
    after ``start``, decoding restarts from the beginning. Frames whose packets do not decode are absent
    (their index is skipped), as they are from :func:`iter_frames`."""
    if info.variable_frame_rate:
        raise ValueError("iter_frame_range needs a constant-frame-rate video (iter_frames resamples the others)")
    t = frame_times(info.path) if times is None else times
    stop = len(t) if stop is None else min(stop, len(t))
    if start >= stop:
        return
    gap = float(np.median(np.diff(t))) if len(t) > 1 else 1.0 / info.fps
    tol = 0.25 * gap
    t_first, t_end = t[start] - tol, (t[stop] - tol if stop < len(t) else np.inf)
    seek = t[start] - 1.0 if start > 0 and t[start] - 1.0 > t[0] else None
    for attempt in (seek, None) if seek is not None else (None,):
        proc, q, stop_ev, threads, tail = _stamped_decoder(info, attempt, prefetch)
        overshot = False
        try:
            first = True
            while True:
                item = q.get()
                if item is None:
                    break
                ts, frame = item
                if first and attempt is not None and ts > t_first + 2 * tol:
                    overshot = True  # the seek landed after the range's first frame: decode from the start
                    break
                first = False
                if ts < t_first:
                    continue
                if ts >= t_end:
                    break
                k = int(np.clip(np.searchsorted(t, ts + tol) - 1, 0, len(t) - 1))
                yield k, frame
        finally:
            _stop_decoder(proc, q, stop_ev, threads)
        if not overshot:
            if proc.returncode not in (0, -9) and errors is not None and tail:
                errors.append(f"decoding stopped early ({tail[-1]}); keeping the frames decoded so far")
            return


def sampled_frames(path: str | os.PathLike, seconds: float, n: int) -> Iterator[np.ndarray]:
    """``n`` frames (BGR, OpenCV's) evenly spaced over a video's first ``seconds``, read in order (seeking is
    slower than decoding here, and unreliable in old codecs); fewer when the video ends first."""
    import cv2

    cap = cv2.VideoCapture(str(path))
    try:
        fps = cap.get(cv2.CAP_PROP_FPS) or 25.0
        total = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
        last = max(0, min(total - 1, int(seconds * (fps if 1 <= fps <= 240 else 25.0))))
        want = set(np.linspace(0, last, n).astype(int).tolist())
        for i in range(last + 1):
            if i not in want:
                if not cap.grab():
                    break
                continue
            ok, f = cap.read()
            if not ok:
                break
            yield f
    finally:
        cap.release()


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


def even_size(size: tuple[int, int]) -> tuple[int, int]:
    """(W, H) rounded up to even numbers, as H.264 in 4:2:0 needs."""
    w, h = size
    return int(w) + (int(w) % 2), int(h) + (int(h) % 2)


def to_i420(frame: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """An RGB (or grey) uint8 frame -> the planar YUV 4:2:0 buffer ``[H * 3 / 2, W]`` that
    :meth:`VideoWriter.write_i420` takes, zero-padded to ``size`` (W, H; even). Pure: call it on the threads
    that render, so the conversion runs beside the encoder instead of in the writing loop."""
    frame = np.ascontiguousarray(frame, dtype=np.uint8)
    if frame.ndim == 2:
        frame = np.repeat(frame[..., None], 3, -1)
    h, w = frame.shape[:2]
    if (w, h) != tuple(size):
        pad = np.zeros((size[1], size[0], 3), np.uint8)
        pad[:h, :w] = frame[: size[1], : size[0]]
        frame = pad
    return cv2.cvtColor(frame, cv2.COLOR_RGB2YUV_I420)


def _widen_pipe(f) -> None:
    """Give the pipe to an encoder 1 MB (Linux's default limit) instead of 64 kB: a frame goes through in one
    or two writes instead of a dozen wake-ups of both processes (measured: 900 frames of 736x400 took 0.29
    s of CPU instead of 0.47). Elsewhere, or where the limit is lower, the pipe stays as it is."""
    op = getattr(fcntl, "F_SETPIPE_SZ", None) if fcntl is not None else None
    if op is None:
        return
    try:
        fcntl.fcntl(f.fileno(), op, 1 << 20)
    except OSError:
        pass


PRESET = "veryfast"  # x264: 1.7x less encode time than its default (medium) at the same CRF and file size here
DRAWN = ["-preset", "ultrafast", "-threads", "1"]
"""x264 settings for drawn frames (flat background, lines, a small shaded mesh), measured on the avatar
preview at 1024x512: 1.5-1.7 ms of CPU a frame against 4.8 at ``veryfast`` with its threads, frames that
differ by 0.2 grey levels on average, files about twice as large. One encoder thread: the frames are drawn on
the other threads, and x264's frame threads only add synchronisation there."""


class VideoWriter:
    """H.264 MP4 writer; ``audio_path`` (any file with an audio track) is muxed in as AAC. ``quality`` 1-10
    (imageio's scale: 7 is CRF 15, 6 is CRF 20); ``drawn`` for synthetic frames (:data:`DRAWN`), whose audio
    (the speech the motion goes with) is muxed in mono: 0.25 s of CPU for a minute of 48 kHz stereo.

    Atomic: frames go to a unique temporary sibling of ``path``, which replaces ``path`` only when
    :meth:`close` finishes the encode. A run killed or failing mid-render (:meth:`abort`, or leaving a
    ``with`` block by an exception) leaves the previous file, or none, never a truncated video."""

    def __init__(
        self,
        path: str | os.PathLike,
        fps: float,
        size: tuple[int, int],
        audio_path: str | os.PathLike | None = None,
        quality: float = 7,
        drawn: bool = False,
    ):
        self.path = str(path)
        Path(self.path).parent.mkdir(parents=True, exist_ok=True)
        self._tmp = temp_sibling(self.path)
        self.size = even_size(size)
        w, h = self.size
        cmd = [FFMPEG, "-y", "-v", "error", "-f", "rawvideo", "-pix_fmt", "yuv420p", "-s", f"{w}x{h}"]
        cmd += ["-r", f"{float(fps):.02f}", "-i", "-"]  # frames converted here by OpenCV: no swscale
        cmd += ["-i", str(audio_path)] if audio_path is not None else ["-an"]
        cmd += ["-vcodec", "libx264", "-pix_fmt", "yuv420p", "-crf", str(int((1 - quality / 10.0) * 51))]
        cmd += DRAWN if drawn else ["-preset", PRESET]
        if audio_path is not None:  # a drawn preview's audio is speech: mono, half the AAC work
            cmd += [*(["-ac", "1"] if drawn else []), "-acodec", "aac", "-map", "0:v:0", "-map", "1:a:0"]
        cmd += ["-movflags", "+faststart", "-f", "mp4", str(self._tmp)]
        self._err = tempfile.TemporaryFile()  # ffmpeg's messages, for the error if it fails
        # started by vfork + exec (no pre-exec hook, see above); Ctrl-C stops it too, and the abort below
        # removes its temporary file
        self._proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=self._err)
        _widen_pipe(self._proc.stdin)
        self.n = 0

    def write(self, frame: np.ndarray) -> None:
        """One RGB (or grey) uint8 frame; a smaller one is zero-padded, a larger one cropped."""
        self.write_i420(to_i420(frame, self.size))

    def write_i420(self, buf: np.ndarray) -> None:
        """One frame already converted by :func:`to_i420` to this writer's :attr:`size`."""
        w, h = self.size
        if buf.shape != (h * 3 // 2, w) or buf.dtype != np.uint8:
            raise ValueError(f"an I420 frame of {w}x{h} is uint8 [{h * 3 // 2}, {w}], got {buf.dtype} {buf.shape}")
        if self._proc is None:
            raise ValueError("write to a closed VideoWriter")
        try:
            self._proc.stdin.write(memoryview(np.ascontiguousarray(buf)))
        except BrokenPipeError:
            self._proc.wait()
            raise OSError(f"ffmpeg stopped while encoding {self.path}: {self._messages()}") from None
        self.n += 1

    def close(self) -> None:
        """Finish the encode and put the video in place."""
        if self._proc is None:
            return
        try:
            try:
                self._proc.stdin.close()
            except BrokenPipeError:
                pass
            if self._proc.wait() != 0:
                raise OSError(f"ffmpeg could not encode {self.path}: {self._messages()}")
        except BaseException:
            self._stop()
            self._remove_tmp()
            raise
        self._stop()
        commit(self._tmp, self.path)

    def abort(self) -> None:
        """Stop without touching ``path`` (the temporary file is removed)."""
        if self._proc is not None and self._proc.poll() is None:
            self._proc.kill()
        self._stop()
        self._remove_tmp()

    def _stop(self) -> None:
        if self._proc is not None:
            try:
                self._proc.stdin.close()
            except OSError:
                pass
            self._proc.wait()
            self._proc = None
            self._err.close()

    def _messages(self) -> str:
        self._err.seek(0)
        text = self._err.read().decode("utf-8", "replace").strip()
        return " ".join(text.split()[-60:]) or "no message"

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
