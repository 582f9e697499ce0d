"""Live video sources: one table of openers (:data:`OPENERS`: camera, stream, file), each saying which specs
it takes, how it checks one before any work, and how it is read. ``anima live`` and ``anima reenact --live``
both open their source here; adding a kind of source is one entry of the table.

Every source is read on a thread by :class:`PacedReader` (OpenCV's capture): a camera or stream delivers frames
at its own rate and only the newest is kept (a slow consumer drops frames, counted, instead of falling behind);
a file is paced at its real frame rate (``realtime``) or handed over frame by frame, none dropped. Specs that
OpenCV's FFmpeg would interpret as something else (``concat:``, ``subfile,``, ``file:``, image patterns, other
protocols) are refused before any table entry is asked."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2

from anima.errors import AssetNotFound, InputError
from anima.io.video import probe_video

NETWORK_SCHEMES = ("rtsp://", "rtsps://", "rtmp://", "rtmps://", "http://", "https://")


def _is_camera(s: str) -> bool:
    return s.isdigit() and len(s) <= 3


def _check_camera(s: str, allow_network: bool) -> str:
    return s


def _is_stream(s: str) -> bool:
    return s.lower().startswith(NETWORK_SCHEMES)


def _check_stream(s: str, allow_network: bool) -> str:
    if not allow_network:
        raise InputError(f"--live {s!r} is a network stream: pass --allow-network to read it")
    return s


def _is_file(s: str) -> bool:
    return True  # the last entry: anything left must be a video file


def _check_file(s: str, allow_network: bool) -> str:
    p = Path(s)
    if not p.is_file():
        raise InputError(f"--live source not found: {s} (a camera index, a video file, or a URL with --allow-network)")
    probe_video(p)  # a file must be a readable video
    return str(p.resolve())


@dataclass(frozen=True)
class Opener:
    """One kind of source: ``matches(spec)``, ``check(spec, allow_network) -> spec`` (InputError else), and
    whether it is a file (paced by the reader, may loop)."""

    kind: str
    matches: Callable[[str], bool]
    check: Callable[[str, bool], str]
    is_file: bool


OPENERS = (
    Opener("camera", _is_camera, _check_camera, False),
    Opener("stream", _is_stream, _check_stream, False),
    Opener("file", _is_file, _check_file, True),
)
"""The kinds of source, asked in order (the first that matches opens it)."""


def check_live_source(source: str, allow_network: bool = False) -> str:
    """A live source spec checked before any work (see the module docstring): the normalised spec."""
    s = str(source).strip()
    if not _is_camera(s) and not _is_stream(s):
        if "://" in s or (":" in s.split("/")[0] and not Path(s).exists()) or "%" in s or "," in s.split("/")[0]:
            raise InputError(f"--live {s!r}: not a camera index, a video file or an rtsp/rtmp/http(s) URL")
    return opener_of(s).check(s, allow_network)


def opener_of(spec: str) -> Opener:
    return next(o for o in OPENERS if o.matches(str(spec)))


class PacedReader:
    """Frames of a camera / stream / file on a thread. A file is paced at its real frame rate (``realtime``,
    as a camera delivers them); only the newest frame is kept, so a slow consumer drops frames instead of
    falling behind (bounded latency; ``read``: frames offered). ``realtime=False`` hands a file's frames over
    one by one, none dropped, as fast as the consumer takes them."""

    def __init__(self, source: str, realtime: bool = True, loop: bool = False):
        self.cap = cv2.VideoCapture(int(source) if str(source).isdigit() else str(source))
        if not self.cap.isOpened():
            if str(source).isdigit():  # no such camera on this machine: a missing device, not a bad argument
                raise AssetNotFound(f"no camera {source} on this machine (or it is busy): cannot open it")
            raise InputError(f"cannot open live source {source!r}")
        self.fps = self.cap.get(cv2.CAP_PROP_FPS) or 30.0  # contract: not ours (a camera that names no rate)
        self.is_file = opener_of(str(source)).is_file and Path(str(source)).exists()
        self.every = self.is_file and not realtime
        self.loop = loop and self.is_file
        self.lock = threading.Lock()
        self.latest = None  # (index, capture time, rgb)
        self.done = False
        self.read = 0
        self.taken = -1
        self.stopped = False
        self.th = threading.Thread(target=self._run, daemon=True)
        self.th.start()

    def _run(self):
        t0 = time.perf_counter()
        i = 0
        while True:
            ok, bgr = self.cap.read()
            if not ok and self.loop and i > 0 and not self.stopped:  # a file played again (benchmarks)
                self.cap.set(cv2.CAP_PROP_POS_FRAMES, 0)
                ok, bgr = self.cap.read()
            if not ok:
                break
            if self.is_file:  # pace at the real frame rate
                delay = t0 + i / self.fps - time.perf_counter()
                if delay > 0:
                    time.sleep(delay)
            item = (i, time.perf_counter(), cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
            while self.every and not self.stopped:  # hand over every frame: wait until the last one is taken
                with self.lock:
                    if self.latest is None or self.latest[0] <= self.taken:
                        break
                time.sleep(0.001)
            with self.lock:
                self.latest = item
            i += 1
            self.read = i
            if self.stopped:
                break
        self.read = i
        self.done = True

    def get(self, after: int):
        """The newest frame with index > ``after`` (waits for one), or None at the end."""
        while True:
            with self.lock:
                if self.latest is not None and self.latest[0] > after:
                    self.taken = self.latest[0]
                    return self.latest
            if self.done:
                return None
            time.sleep(0.001)

    def close(self) -> None:
        self.stopped = True
        self.th.join(2.0)
        self.cap.release()


def open_source(spec: str, realtime: bool = True, loop: bool = False) -> PacedReader:
    """Open a checked spec (:func:`check_live_source`): its reader, started."""
    return PacedReader(spec, realtime=realtime, loop=loop)
