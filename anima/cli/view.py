"""``anima view``: look at any result in a browser (served locally, or written as files)."""

from __future__ import annotations

from anima.cli.common import command_line, notes
from anima.cli.options import number
from anima.view.serve import serve, write_static


def register(sub) -> None:
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


def cmd_view(a) -> int:
    if a.static:
        r = write_static(a.folder, a.static, command=command_line(a), avatar=a.avatar, motion=a.motion)
        notes(r["notes"])
        print(f"anima view: {r['kind']} page written: open {r['page']}")
        return 0
    return serve(a.folder, a.port, browser=not a.no_browser, avatar=a.avatar, motion=a.motion)
