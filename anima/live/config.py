"""The settings of ``anima live`` and of every live source (light: the command line builds its options from
them, :mod:`anima.cli.options`). :class:`SourceConfig` is shared by ``anima live`` and ``anima reenact
--live``: one declaration of how a source is read."""

from __future__ import annotations

from dataclasses import dataclass, field

from anima.facemodel.character import BUILDS, DEFAULT_BUILD
from anima.track import DEFAULT as DEFAULT_TRACKER
from anima.track import TRACKERS as TRACKER_NAMES

TRACKERS = 2
"""Holistic trackers in parallel (``anima live`` without ``--face-only``), each on every other frame: one
Holistic pass takes ~60 ms on a laptop core, two on two cores keep up with 25-30 fps (MediaPipe releases the
GIL); each still sees a continuous (half-rate) video, so its tracking state holds."""


@dataclass
class SourceConfig:
    allow_network: bool = False
    """Allow an rtsp/rtmp/http(s) source (a network stream)."""
    max_seconds: float | None = field(default=None, metadata={"range": (0.1, 86_400.0)})
    """Stop after this long."""


@dataclass
class LiveConfig(SourceConfig):
    source: str | None = field(default=None, metadata={"positional": True, "metavar": "SOURCE", "nargs": "?"})
    """Camera index (0, 1, ...), video file, or stream URL (with --allow-network)."""
    face_only: bool = False
    """Track the face only (Face Mesh: faster)."""
    tracker: str = field(default=DEFAULT_TRACKER, metadata={"choices": tuple(TRACKER_NAMES)})
    """The tracker that finds the face, body and hands (docs/architecture.md says how to add one)."""
    realtime: bool = False
    """Play a video file at its own frame rate as a camera would, dropping frames when behind (default for a
    file: every frame, as fast as they are tracked)."""
    record: str | None = field(default=None, metadata={"metavar": "DIR"})
    """Write the take as a result folder into DIR, a new or empty folder (flushed every 2 s while it runs: a
    killed take is kept, see --recover)."""
    recover: str | None = field(default=None, metadata={"metavar": "DIR"})
    """Instead of a SOURCE: write the result folder of a take that was killed (its parts in DIR/take)."""
    livelink: str | None = field(default=None, metadata={"metavar": "HOST:PORT"})
    """Also send the face as Live Link Face UDP packets (Unreal; port 11111)."""
    vmc: str | None = field(default=None, metadata={"metavar": "HOST:PORT"})
    """Also send every frame to a VMC protocol receiver (VSeeFace, Warudo, VNyan, VMagicMirror; port 39539):
    humanoid bones, the 52 ARKit blend values and the VRM presets (docs/live.md)."""
    body: str = field(default=DEFAULT_BUILD, metadata={"choices": BUILDS})
    """anima's character's build (neutral, female, male; docs/rig.md): the page's character and the take's."""
    avatar: str | None = None
    """Your character (.vrm VRM 1.0, or a skinned .glb with humanoid bone names) instead of anima's: each frame
    is retargeted onto its own rest pose (as `anima retarget` does)."""
    port: int | None = field(default=None, metadata={"range": (1, 65535)})
    """Port of the page (default: a free one)."""
    browser: bool = field(default=True, metadata={"flag": "--no-browser"})
    """Open the page in a browser (--no-browser: print the address only)."""
    loop: bool = False
    """Play a video file again when it ends (tests, benchmarks)."""
    max_frames: int | None = field(default=None, metadata={"range": (1, 10_000_000)})
    """Stop after this many frames."""
    trackers: int = field(default=TRACKERS, metadata={"range": (1, 4)})
    """Holistic trackers in parallel, each on every other frame (2: keeps up with 25 fps on 2 cores; 1: every
    frame through one tracker, closest to `anima capture`, slower)."""
