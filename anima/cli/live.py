"""``anima live``: a webcam (or a video, or a stream) drives the character live; its options come from
:class:`anima.live.config.LiveConfig`."""

from __future__ import annotations

import dataclasses

from anima.cli.common import add_json_quiet, command_line, emit
from anima.cli.options import add_options, config_from_args
from anima.errors import InputError
from anima.live import run as live
from anima.live.config import LiveConfig

LIVE_OPTIONS = [f.name for f in dataclasses.fields(LiveConfig)]


def register(sub) -> None:
    p = sub.add_parser(
        "live",
        help="a webcam (or a video) drives the character in the browser, live",
        description="Track SOURCE (a camera index such as 0, a video file, or with --allow-network an "
        "rtsp/rtmp/http(s) stream) frame by frame with the capture's models (face, body and hands; --face-only: "
        "the face) and move the character in the viewer page over a WebSocket (served on 127.0.0.1). The page "
        "shows frames/s and the glass-to-avatar latency. --livelink sends the face to Unreal as Live Link Face "
        "packets, --vmc every frame to a VMC protocol receiver (VSeeFace, Warudo, VNyan, VMagicMirror); "
        "--record DIR writes the take as a result folder when it ends (end of the source, --max-seconds, "
        "Ctrl-C). The numbers of the take are printed at the end.",
    )
    add_options(p, LiveConfig, LIVE_OPTIONS)
    add_json_quiet(p, quiet=False)
    p.set_defaults(func=cmd_live)


def cmd_live(a) -> int:
    cfg = config_from_args(LiveConfig, a, LIVE_OPTIONS)
    if cfg.recover is not None:
        if cfg.source is not None or cfg.record is not None or cfg.avatar is not None:
            raise InputError("--recover DIR takes no SOURCE and no --record: it writes the take already in DIR")
        return emit(live.recover(cfg.recover, command_line(a)), a.json)
    return emit(live.run(cfg, command_line(a)), a.json)
