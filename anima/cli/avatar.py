"""``anima retarget``: any anima motion on a user's own VRM or glTF avatar."""

from __future__ import annotations

from dataclasses import dataclass, field

from anima.cli.common import Json, add_args, command_line, emit
from anima.export import retarget


@dataclass
class RetargetIn:
    result: str = field(default="", metadata={"positional": True, "metavar": "result"})
    """result folder or sequence file (capture.npz, gesture.npz, motion.npz)"""
    avatar: str = field(default="", metadata={"required": True, "metavar": "AVATAR"})
    """the avatar: .vrm (VRM 1.0) or .glb (skinned glTF binary)"""
    out: str = field(default="", metadata={"required": True, "metavar": "OUT"})
    """output .vrm or .glb (its report beside it as OUT.json)"""


def register(sub) -> None:
    r = sub.add_parser(
        "retarget",
        help="put a result's motion on your own VRM or glTF avatar",
        description="Put the body and face motion of RESULT (a capture, gesture or text2face folder, or its "
        "capture.npz / gesture.npz / motion.npz) on AVATAR (a VRM 1.0 .vrm, or a skinned .glb with Mixamo, "
        "Ready Player Me, Unreal, VRM or anima bone names) and write the avatar with the motion as its first "
        "animation to OUT (.vrm from a .vrm avatar, or .glb), with OUT.json saying which bones and face "
        "channels found a home. Rest-pose aware: T-pose, A-pose and rolled bone axes are measured, not assumed "
        "(docs/rig.md).",
    )
    add_args(r, RetargetIn, Json)
    r.set_defaults(func=cmd_retarget)


def cmd_retarget(a) -> int:
    return emit(retarget.run(a.result, a.avatar, a.out, command=command_line(a)), a.json, summary)


def summary(r: dict) -> str:
    body = r["body"] if isinstance(r["body"], str) else f"{len(r['bones'])} bones ({r['convention']})"
    face = r["face"]
    lines = [
        f"  frames      {r['frames']} @ {r['fps']:g} fps",
        f"  body        {body}",
        f"  face        {face['via']}: {len(face['found_a_home'])} channels found a home"
        + (f", none for {', '.join(face['no_home'][:8])}{' ...' if len(face['no_home']) > 8 else ''}"
           if face["no_home"] else ""),
    ]  # fmt: skip
    if r["bones_not_on_avatar"]:
        lines.append(f"  not on the avatar  {', '.join(r['bones_not_on_avatar'][:10])}"
                     + (" ..." if len(r["bones_not_on_avatar"]) > 10 else ""))  # fmt: skip
    lines += [f"  wrote {p}" for p in r["outputs"]]
    return "\n".join(lines)
