"""``anima library build``: a user's own footage -> a motion library for ``gesture`` and ``text2face``."""

from __future__ import annotations

from dataclasses import dataclass, field

from anima.cli.common import JsonQuiet, add_args, command_line, emit, group, notes
from anima.dataset.config import FilterConfig
from anima.gesture import library


@dataclass
class LibraryIn:
    data: list = field(default_factory=list, metadata={"positional": True, "nargs": "+", "metavar": "DATA"})
    """videos, folders of videos (searched recursively), glob patterns, or dataset folders from `anima dataset
    build`"""
    out: str = field(default="", metadata={"required": True, "metavar": "NAME"})
    """the library: a folder (library.npz + library.json) or a file ending in .npz"""
    max_frames: int | None = field(default=None, metadata={"range": (1, None), "metavar": "N"})
    """capture at most N frames of each video (default: all)"""
    min_len: float = field(default=FilterConfig().min_s, metadata={"range": (0.5, 3600.0), "metavar": "SECONDS"})
    """shortest (text, motion) clip kept for text2face (a gesture window is always 64 frames at 15 fps, 4.3 s)"""


def register(sub) -> None:
    lsub = group(sub, "library", "bake your own footage into a motion library", "library_command", "TOOL")
    b = lsub.add_parser(
        "build",
        help="videos (or datasets) -> a motion library for `gesture --library` and `text2face --library`",
        description="Capture each video in this process (face, body, hands and speech, as `anima dataset "
        "build` does, one after another), cut it into (text, motion) clips and (audio, motion) windows, and "
        "write a motion library: the arrays the built-in library holds, from your footage. Then "
        "`anima gesture SPEECH --library NAME` searches its windows (with mirrored and speed-varied copies) and "
        "`anima text2face PROMPT --library NAME` composes from its clips, instead of the built-in library's. "
        "Every input is checked first (a missing path, a file that is not a video, a video where no person is "
        "seen in a few sampled frames: one line, exit 2). NAME ending in .npz is one file (replaced only if "
        "anima wrote it), otherwise a result folder (library.npz, library.json, manifest.json). No licence "
        "filter: the library is yours, and its provenance lists every source with its sha256. Gesture windows "
        "need 4.3 s of speech with the upper body and hands in view; for hours of footage build a dataset "
        "(`anima dataset build`: Ray, resumable) and give its folder here.",
    )
    add_args(b, LibraryIn, JsonQuiet)
    b.set_defaults(func=cmd_build)


def cmd_build(a) -> int:
    r = library.build(a.data, a.out, a.max_frames, a.min_len, progress=not (a.quiet or a.json), command=command_line(a))
    notes(r.pop("notes"), "warning")

    def text(r):
        return (
            f"{r['videos']} videos: {r['face_clips']} face clips ({r['face_seconds']} s), {r['gesture_windows']} "
            f"gesture windows ({r['gesture_seconds_distinct']} s of distinct motion) in {r['seconds']} s; wrote "
            + ", ".join(r["written"])
        )

    return emit(r, a.json, text)
