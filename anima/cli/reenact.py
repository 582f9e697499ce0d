"""``anima reenact``."""

from __future__ import annotations

from anima.cli.common import add_json_quiet, emit, notes
from anima.cli.options import add_options, config_from_args, number
from anima.reenact import run as reenact
from anima.reenact.config import ReenactConfig

REENACT_OPTIONS = ["n", "a", "smooth", "detail", "map_expressions", "color_transfer"]


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
    re_.add_argument("--allow-network", action="store_true", help="let --live read a network stream")
    re_.add_argument(
        "--target", nargs="+", required=True, help="target video(s) of one person; the first is the background"
    )
    re_.add_argument("--out", help="output MP4")
    re_.add_argument("--db", default=None, help="database file: read if it exists, else written after building")
    re_.add_argument("--side-by-side", action="store_true", help="actor | output")
    add_options(re_, ReenactConfig, REENACT_OPTIONS)
    re_.add_argument(
        "--max-seconds", type=number(float, 0.1, 86_400.0), default=None, help="--live: stop after this long"
    )
    add_json_quiet(re_)  # --quiet: no progress bars (the summary is still printed)
    re_.set_defaults(func=cmd_reenact)


def cmd_reenact(a) -> int:
    r = reenact.run(
        a.target,
        a.out,
        config_from_args(ReenactConfig, a, REENACT_OPTIONS),
        actor=a.actor,
        live=a.live,
        sbs=a.side_by_side,
        db_path=a.db,
        max_seconds=a.max_seconds,
        progress=not a.quiet,
        allow_network=a.allow_network,
    )
    notes(r.get("notes"))
    return emit(r, a.json, _text)


def _text(r: dict) -> str:
    if "frames_received" in r:
        return (
            f"processed {r['frames_processed']} of {r['frames_received']} frames (median latency "
            f"{r['latency_ms']['median']:.0f} ms)" + (f", wrote {r['output']}" if r["output"] else "")
        )
    return f"wrote {r['output']}"
