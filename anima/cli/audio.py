"""``anima audio features``."""

from __future__ import annotations

from dataclasses import dataclass, field

from anima.audio.features import write_speech_features
from anima.cli.common import Json, add_args, emit, group, notes
from anima.core.contract import TEXT_FPS


@dataclass
class FeaturesIn:
    file: str = field(default="", metadata={"positional": True, "metavar": "file"})
    """audio (WAV/MP3/FLAC) or a video, at most 1 hour"""
    fps: float = field(default=TEXT_FPS, metadata={"range": (1.0, 240.0), "metavar": "FPS"})
    """motion frame rate, 1-240"""
    frames: int | None = field(default=None, metadata={"range": (1, None), "metavar": "FRAMES"})
    """number of motion frames (default: the audio's length; at most 2 x the audio's length)"""
    out: str | None = field(default=None, metadata={"metavar": "OUT"})
    """output .npz (default: FILE.speech.npz)"""


def register(sub) -> None:
    asub = group(sub, "audio", "speech features aligned to motion frames", "audio_command", "TOOL")
    af = asub.add_parser(
        "features",
        help="13 MFCC + log energy and their derivatives (28) per motion frame",
        description="Read the audio of FILE (WAV/MP3/FLAC or a video), normalise loudness, and "
        "compute 28 speech features per motion frame, centred on the frame times i/fps.",
    )
    add_args(af, FeaturesIn, Json)
    af.set_defaults(func=cmd_features)


def cmd_features(a) -> int:
    s = write_speech_features(a.file, a.fps, a.frames, a.out)
    emit(s, a.json)
    if s["silent"]:
        notes(["the audio is silent (below -60 dBFS)"], "warning")
    return 0
