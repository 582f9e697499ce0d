"""``anima view``: look at any result in a browser (served locally, or written as files)."""

from __future__ import annotations

from anima.cli.common import command_line, emit, notes
from anima.cli.options import number
from anima.errors import InputError
from anima.view import live
from anima.view.serve import serve, write_static


def register(sub) -> None:
    register_view(sub)
    register_live(sub)


def register_view(sub) -> None:
    p = sub.add_parser(
        "view",
        help="look at a result in the browser: 3D avatar, videos, audio, curves, evidence",
        description="Show DIR (the folder of a capture, text2face, gesture or reenact run, or a dataset) "
        "in a local web page: the animated avatar with orbit controls, the source and overlay videos and "
        "the speech in sync on one timeline (play, pause, scrub, frame step with the arrow keys), curves of "
        "ARKit weights and wrist speeds, and the evidence of the result (capture flags, gesture joins and "
        "controls, the prompt, a dataset's clips and descriptions). Served on 127.0.0.1 until Ctrl-C, or "
        "written as files with --static. Needs no network.",
    )
    p.add_argument("folder", metavar="DIR", help="a result folder")
    p.add_argument(
        "--port",
        type=number(int, 1, 65535),
        default=None,
        help="port to serve on (default: a free one; a port in use is replaced by a free one, with a note)",
    )
    p.add_argument("--no-browser", action="store_true", help="print the address only; do not open a browser")
    p.add_argument(
        "--static",
        metavar="OUT",
        default=None,
        help="write the page as files into OUT (open OUT/index.html from disk) instead of serving it",
    )
    p.add_argument(
        "--avatar",
        default=None,
        help="play the result on your own avatar: a VRM 1.0 (.vrm: loaded with three-vrm, the motion as a VRM "
        "Animation) or a skinned .glb (the motion retargeted as `anima retarget` does)",
    )
    p.add_argument(
        "--motion",
        choices=("auto", "vrma", "retarget"),
        default="auto",
        help="how the result reaches a VRM --avatar: vrma (three-vrm plays a VRM Animation, relative to the "
        "VRM's rest: right for the T-pose VRM 1.0 asks for), retarget (anima measures the avatar's rest: any "
        "pose), auto (vrma for a T-pose VRM, else retarget)",
    )
    p.set_defaults(func=cmd_view)


def register_live(sub) -> None:
    p = sub.add_parser(
        "live",
        help="a webcam (or a video) drives the character in the browser, live",
        description="Track SOURCE (a camera index such as 0, a video file, or with --allow-network an "
        "rtsp/rtmp/http(s) stream) frame by frame with the capture's models (face, body and hands; --face-only: "
        "the face) and move the character in the viewer page over a WebSocket (served on 127.0.0.1). The page "
        "shows frames/s and the glass-to-avatar latency. --livelink sends the face to Unreal as Live Link Face "
        "packets; --record DIR writes the take as a result folder when it ends (end of the source, "
        "--max-seconds, Ctrl-C). The numbers of the take are printed at the end.",
    )
    p.add_argument(
        "source", nargs="?", help="camera index (0, 1, ...), video file, or stream URL (with --allow-network)"
    )
    p.add_argument("--face-only", action="store_true", help="track the face only (Face Mesh: faster)")
    p.add_argument(
        "--realtime",
        action="store_true",
        help="play a video file at its own frame rate as a camera would, dropping frames when behind "
        "(default for a file: every frame, as fast as they are tracked)",
    )
    p.add_argument(
        "--record",
        metavar="DIR",
        default=None,
        help="write the take as a result folder into DIR (flushed every 2 s while it runs: a killed take is "
        "kept, see --recover)",
    )
    p.add_argument(
        "--recover",
        metavar="DIR",
        default=None,
        help="instead of a SOURCE: write the result folder of a take that was killed (its parts in DIR/take)",
    )
    p.add_argument("--livelink", metavar="HOST:PORT", default=None, help="also send Live Link Face UDP packets")
    p.add_argument(
        "--avatar",
        default=None,
        help="your character (.vrm VRM 1.0, or a skinned .glb with humanoid bone names) instead of anima's: "
        "each frame is retargeted onto its own rest pose (as `anima retarget` does)",
    )
    p.add_argument("--port", type=number(int, 1, 65535), default=None, help="port of the page (default: free)")
    p.add_argument("--no-browser", action="store_true", help="print the address only; do not open a browser")
    p.add_argument("--max-seconds", type=number(float, 0.1, 86400.0), default=None, help="stop after this long")
    p.add_argument("--loop", action="store_true", help="play a video file again when it ends (tests, benchmarks)")
    p.add_argument("--max-frames", type=number(int, 1, 10_000_000), default=None, help="stop after this many frames")
    p.add_argument(
        "--trackers",
        type=number(int, 1, 4),
        default=2,
        help="Holistic trackers in parallel, each on every other frame (default 2: keeps up with 25 fps on 2 "
        "cores; 1: every frame through one tracker, closest to `anima capture`, slower)",
    )
    p.add_argument("--allow-network", action="store_true", help="allow an rtsp/rtmp/http(s) SOURCE")
    p.add_argument("--json", action="store_true", help="print the take's numbers as JSON")
    p.set_defaults(func=cmd_live)


def cmd_live(a) -> int:
    if a.recover is not None:
        if a.source is not None or a.record is not None or a.avatar is not None:
            raise InputError("--recover DIR takes no SOURCE and no --record: it writes the take already in DIR")
        return emit(live.recover(a.recover, command_line(a)), a.json)
    if a.source is None:
        raise InputError("give a SOURCE (a camera index, a video file or a stream URL), or --recover DIR")
    r = live.run(
        a.source,
        face_only=a.face_only,
        realtime=a.realtime,
        record=a.record,
        livelink=a.livelink,
        port=a.port,
        browser=not a.no_browser,
        max_seconds=a.max_seconds,
        allow_network=a.allow_network,
        command=command_line(a),
        max_frames=a.max_frames,
        trackers=a.trackers,
        loop=a.loop,
        avatar=a.avatar,
    )
    return emit(r, a.json)


def cmd_view(a) -> int:
    if a.static:
        r = write_static(a.folder, a.static, command=command_line(a), avatar=a.avatar, motion=a.motion)
        notes(r["notes"])
        print(f"anima view: {r['kind']} page written: open {r['page']}")
        return 0
    return serve(a.folder, a.port, browser=not a.no_browser, avatar=a.avatar, motion=a.motion)
