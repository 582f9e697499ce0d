"""Live video sources (``anima reenact --live``, ``anima live``): a camera index, a video file, or an allowed
network stream, read on a thread (:class:`PacedReader`)."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import cv2

from anima.errors import AssetNotFound, InputError
from anima.io.video import probe_video

NETWORK_SCHEMES = ("rtsp://", "rtsps://", "rtmp://", "rtmps://", "http://", "https://")


def check_live_source(source: str, allow_network: bool = False) -> str:
    """A ``--live`` source: a camera index, an existing video file, or (with ``allow_network``) an
    rtsp/rtmp/http(s) URL. Anything else OpenCV's FFmpeg would interpret (``concat:``, ``subfile,``,
    ``file:``, image patterns, other protocols) is refused."""
    s = str(source).strip()
    if s.isdigit() and len(s) <= 3:
        return s
    low = s.lower()
    if low.startswith(NETWORK_SCHEMES):
        if not allow_network:
            raise InputError(f"--live {s!r} is a network stream: pass --allow-network to read it")
        return s
    if "://" in s or (":" in s.split("/")[0] and not Path(s).exists()) or "%" in s or "," in s.split("/")[0]:
        raise InputError(f"--live {s!r}: not a camera index, a video file or an rtsp/rtmp/http(s) URL")
    p = Path(s)
    if not p.is_file():
        raise InputError(f"--live source not found: {s} (a camera index, a video file, or a URL with --allow-network)")
    probe_video(p)  # a file must be a readable video
    return str(p.resolve())


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
        self.is_file = not str(source).isdigit() and Path(str(source)).exists()
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
