"""``anima studio``: the local web app (drop a video, watch the progress, download the animation)."""

from __future__ import annotations

from anima.cli.options import number
from anima.studio.server import DEFAULT_MAX_UPLOAD_MB, default_root, serve


def register(sub) -> None:
    p = sub.add_parser(
        "studio",
        help="the local web app: drop a video, speech or a sentence; watch the progress; download FBX, VRMA, BVH",
        description="Serve anima studio on 127.0.0.1 and print its address (studio: http://127.0.0.1:PORT/?token=...). "
        "In the page: drop a video (capture), a speech file (gesture) or type a sentence (text2face), choose the "
        "options that matter (face only, the rig's joint names, your own VRM / glTF avatar), follow each job's "
        "progress in a queue (one job at a time, cancellable), open a finished job in the viewer and download "
        "avatar.glb, FBX, VRM Animation, BVH and arkit.csv. Each job is a folder under --root (default "
        f"{default_root()}) whose result/ is an ordinary anima result folder: every command and `anima view` work "
        "on it. Needs no network; "
        "stops with Ctrl-C (docs/studio.md).",
    )
    p.add_argument("--root", metavar="DIR", default=None, help="the folder of the studio's jobs and results "
                   f"(default: {default_root()}; a new folder, or one the studio made)")  # fmt: skip
    p.add_argument(
        "--port",
        type=number(int, 0, 65535),
        default=0,
        help="port to serve on (default 0: a free one; a port in use is replaced by a free one, with a note)",
    )
    p.add_argument("--no-browser", action="store_true", help="print the address only; do not open a browser")
    p.add_argument(
        "--max-upload-mb",
        type=number(float, 1.0, 1_000_000.0),
        default=float(DEFAULT_MAX_UPLOAD_MB),
        metavar="MB",
        help=f"the largest file the page accepts, in MB (default {DEFAULT_MAX_UPLOAD_MB})",
    )
    p.set_defaults(func=cmd_studio)


def cmd_studio(a) -> int:
    return serve(a.root, a.port, browser=not a.no_browser, max_upload_mb=a.max_upload_mb)
