"""``anima reenact``."""

from __future__ import annotations

from anima.cli.common import add_json_quiet, emit, notes
from anima.cli.options import add_options, config_from_args
from anima.errors import InputError
from anima.live import reenact as live_reenact
from anima.live.config import SourceConfig
from anima.reenact import run as reenact
from anima.reenact.config import ReenactConfig

REENACT_OPTIONS = ["n", "a", "smooth", "detail", "map_expressions", "color_transfer"]
SOURCE_OPTIONS = ["allow_network", "max_seconds"]


def register(sub) -> None:
    re_ = sub.add_parser(
        "reenact",
        help="put an actor's lower-face expression on a target person's video",
        description="Seed 001: fit the ICT face model to actor and target, build a database of "
        "the target's lower-face vertex colours per frame, and for every actor frame synthesise "
        "the texture as the weighted median of the n most similar target frames, render the "
        "target's face with the actor's expression and blend it in (Laplacian pyramid). The "
        "actor's audio is muxed in. --live reads a camera index, a stream URL or a file (paced "
        "at its frame rate), dropping frames rather than falling behind.",
    )
    re_.add_argument("--actor", help="actor video (its audio is used)")
    re_.add_argument(
        "--live",
        default=None,
        metavar="SOURCE",
        help="camera index, video file, or rtsp/rtmp/http(s) URL (with --allow-network)",
    )
    re_.add_argument(
        "--target", nargs="+", required=True, help="target video(s) of one person; the first is the background"
    )
    re_.add_argument("--out", help="output MP4")
    re_.add_argument("--db", default=None, help="database file: read if it exists, else written after building")
    re_.add_argument("--side-by-side", action="store_true", help="actor | output")
    add_options(re_, ReenactConfig, REENACT_OPTIONS)
    add_options(re_, SourceConfig, SOURCE_OPTIONS)  # the live source's options, as `anima live` declares them
    add_json_quiet(re_)  # --quiet: no progress bars (the summary is still printed)
    re_.set_defaults(func=cmd_reenact)


def cmd_reenact(a) -> int:
    cfg = config_from_args(ReenactConfig, a, REENACT_OPTIONS)
    if a.live is not None:
        if a.actor:
            raise InputError("give --actor or --live, not both")
        src = config_from_args(SourceConfig, a, SOURCE_OPTIONS)
        r = live_reenact.run(a.live, a.target, a.out, cfg, a.db, src.max_seconds, not a.quiet, src.allow_network)
    else:
        if not a.actor:
            raise InputError("give --actor VIDEO or --live SOURCE")
        if a.max_seconds is not None or a.allow_network:
            raise InputError("--max-seconds and --allow-network are for --live")
        r = reenact.run(a.target, a.out, cfg, a.actor, a.side_by_side, a.db, progress=not a.quiet)
    notes(r.get("notes"))
    return emit(r, a.json, _text)


def _text(r: dict) -> str:
    if "frames_received" in r:
        return (
            f"processed {r['frames_processed']} of {r['frames_received']} frames (median latency "
            f"{r['latency_ms']['median']:.0f} ms)" + (f", wrote {r['output']}" if r["output"] else "")
        )
    return f"wrote {r['output']}"
