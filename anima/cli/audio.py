"""``anima audio features``."""

from __future__ import annotations

from anima.audio.features import write_speech_features
from anima.cli.common import emit, group, notes
from anima.cli.options import number, positive_int
from anima.core.contract import TEXT_FPS


def register(sub) -> None:
    asub = group(sub, "audio", "speech features aligned to motion frames", "audio_command", "TOOL")
    af = asub.add_parser(
        "features",
        help="13 MFCC + log energy and their derivatives (28) per motion frame",
        description="Read the audio of FILE (WAV/MP3/FLAC or a video), normalise loudness, and "
        "compute 28 speech features per motion frame, centred on the frame times i/fps.",
    )
    af.add_argument("file")
    af.add_argument(
        "--fps",
        type=number(float, 1.0, 240.0),
        default=TEXT_FPS,
        help=f"motion frame rate, 1-240 (default {TEXT_FPS:g})",
    )
    af.add_argument(
        "--frames",
        type=positive_int,
        default=None,
        help="number of motion frames (default: the audio's length; at most 2 x the audio's length)",
    )
    af.add_argument("--out", default=None, help="output .npz (default: FILE.speech.npz)")
    af.add_argument("--json", action="store_true")
    af.set_defaults(func=cmd_features)


def cmd_features(a) -> int:
    s = write_speech_features(a.file, a.fps, a.frames, a.out)
    emit(s, a.json)
    if s["silent"]:
        notes(["the audio is silent (below -60 dBFS)"], "warning")
    return 0
