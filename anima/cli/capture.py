"""``anima capture``, ``anima info``, ``anima export``."""

from __future__ import annotations

from dataclasses import dataclass, field

from anima.capture import run as capture
from anima.capture.config import CaptureConfig
from anima.cli.common import Body, JsonQuiet, Rig, add_args, command_line, emit, notes, time_split
from anima.cli.options import add_options, config_from_args
from anima.errors import InputError
from anima.export import livelink, vmc
from anima.export.fbx import UNITS
from anima.export.formats import EXPORTS, FORMATS, export
from anima.facemodel.character import BUILDS
from anima.io.sequence import read_sequence

CAPTURE_OPTIONS = [
    "max_frames",
    "smooth_sigma",
    "face_only",
    "tracker",
    "max_gap",
    "fixed_bones",
    "body_3d",
    "pose_model",
    "posture",
]


@dataclass
class CaptureIn:
    video: str = field(default="", metadata={"positional": True, "metavar": "video"})
    """input video (mp4/mov/mkv/webm; H.264, HEVC, VP9...)"""
    out: str = field(default="", metadata={"required": True, "metavar": "OUT"})
    """output folder (created; checked before any work)"""


@dataclass
class CaptureOut:
    no_smooth: bool = False
    """disable temporal smoothing (--sigma 0)"""
    no_render: bool = False
    """skip the videos"""
    audio_optional: bool = False
    """if --audio cannot be read, capture the motion without speech features (default: refuse)"""
    audio: str | None = field(default=None, metadata={"metavar": "AUDIO"})
    """separate WAV/MP3/FLAC for the speech features (default: the video's own audio track)"""
    neutral: str | None = field(default=None, metadata={"metavar": "REST"})
    """a clip (or its capture.npz) of the same person with a relaxed face: its face is the rest taken out of every
    animation (default: estimated from VIDEO itself, which eats an expression held all clip long)"""


@dataclass
class InfoArgs:
    file: str = field(default="", metadata={"positional": True, "metavar": "file"})
    json: bool = False
    """print JSON"""


@dataclass
class ExportArgs:
    format: str = field(default="", metadata={"positional": True, "choices": FORMATS})
    file: str = field(default="", metadata={"positional": True, "metavar": "file"})
    out: str = field(default="", metadata={"required": True, "metavar": "OUT"})
    """the file to write"""
    fps: float | None = field(default=None, metadata={"range": (1.0, 240.0), "metavar": "FPS"})
    """BVH only: resample to this rate (1-240), e.g. 15 for gesture work"""
    units: str = field(default="m", metadata={"choices": UNITS})
    """FBX only: the file's unit, m (default: Unity 1:1, Unreal converts) or cm (Maya, MotionBuilder scenes)"""
    body: str | None = field(default=None, metadata={"choices": BUILDS})
    """avatar, bvh, vrma, fbx: the character's build, neutral, female or male (default: the one FILE was made
    with, else neutral)"""


@dataclass
class LiveLinkArgs:
    file: str = field(default="", metadata={"positional": True, "metavar": "file"})
    to: str = field(default="", metadata={"required": True, "metavar": "TO"})
    """HOST:PORT of the machine running Unreal (e.g. 127.0.0.1:11111)"""
    subject: str = field(default="anima", metadata={"metavar": "SUBJECT"})
    """the Live Link subject name (default: anima)"""
    loops: int = field(default=1, metadata={"range": (1, 10_000), "metavar": "LOOPS"})
    """play it this many times"""


@dataclass
class VmcArgs:
    result: str = field(default="", metadata={"positional": True, "metavar": "result"})
    """result folder or sequence file (capture.npz, gesture.npz, motion.npz)"""
    to: str = field(default="", metadata={"required": True, "metavar": "TO"})
    """HOST:PORT of the receiver (e.g. 127.0.0.1:39539)"""
    loop: bool = False
    """play it again and again until Ctrl-C"""


def register(sub) -> None:
    c = sub.add_parser(
        "capture",
        help="track a 3D face, body and hands (and speech) in a video",
        description="Track face, body and hands in VIDEO with MediaPipe Holistic (or the face "
        "only with --face-only), fit the ICT face model (identity per clip; pose, camera and 53 "
        "expressions per frame), build the cleaned 55-joint upper-body+hands skeleton, compute "
        "speech features from the audio, and write into --out: capture.npz (tracked sequence), "
        "arkit.csv (Live Link Face), face.glb (morph-target animation), body.bvh, overlay.mp4, "
        "mesh.mp4, skeleton videos, info.json and manifest.json (written last).",
    )
    add_args(c, CaptureIn)
    add_options(c, CaptureConfig, CAPTURE_OPTIONS)
    add_args(c, CaptureOut, Rig, Body, JsonQuiet)
    c.set_defaults(func=cmd_capture)

    i = sub.add_parser(
        "info",
        help="summarise a tracked-sequence file",
        description="Frames, fps, tracked fraction, mean fit error (px and NME), body and hands "
        "tracked, speech of FILE (capture.npz, motion.npz, gesture.npz).",
    )
    add_args(i, InfoArgs)
    i.set_defaults(func=cmd_info)

    x = sub.add_parser(
        "export",
        help="export a tracked sequence (ARKit CSV, face GLB, character GLB/VRM, BVH or VRM Animation)",
        description="Export FILE (capture.npz, motion.npz or gesture.npz) as a Live Link Face "
        "CSV (arkit), the face with morph targets (glb), the animated character (avatar: body and face, "
        "one timeline; --out x.vrm writes it as a VRM 1.0 with its humanoid map and expression presets), "
        "a BVH of the character's skeleton (bvh: metres, T-pose rest, docs/rig.md) or a VRM Animation "
        "(vrma: plays on any VRM in three-vrm, UniVRM, VRoid apps; the face as VRM expression presets).",
    )
    formats = "; ".join(f"{k}: {v.help}" for k, v in EXPORTS.items())
    suffixes = "(" + ", ".join(f"{k} {'/'.join(v.suffixes)}" for k, v in EXPORTS.items()) + ")"
    add_args(x, ExportArgs, Rig, help_extra={"format": formats, "out": suffixes})
    x.set_defaults(func=cmd_export)

    ll = sub.add_parser(
        "livelink",
        help="play a sequence into Unreal's Live Link (Live Link Face UDP packets)",
        description="Send FILE (capture.npz, motion.npz or gesture.npz) to Unreal's Live Link as the Live Link "
        "Face iPhone app does: one UDP packet per frame at the sequence's rate, 52 ARKit blendshapes plus head "
        "and eye rotations (the values of arkit.csv). In Unreal: Live Link > Source > Live Link Face, port "
        "11111; the subject appears under --subject. Layout: docs/artifacts.md.",
    )
    add_args(ll, LiveLinkArgs, JsonQuiet)
    ll.set_defaults(func=cmd_livelink)

    v = sub.add_parser(
        "vmc",
        help="play a result into a VTuber app over the VMC protocol (VSeeFace, Warudo, VNyan, VMagicMirror)",
        description="Send RESULT (a capture, gesture or text2face folder, or its sequence file) to a VMC protocol "
        "receiver at the sequence's own frame rate: every frame one OSC bundle of the humanoid bones (Unity "
        "names, left-handed, relative to the T-pose), the 52 ARKit blend values (perfect sync names) and the VRM "
        "presets. In VSeeFace: General settings > OSC/VMC receiver, port 39539 (docs/live.md).",
    )
    add_args(v, VmcArgs, JsonQuiet)
    v.set_defaults(func=cmd_vmc)


def cmd_capture(a) -> int:
    cfg = config_from_args(CaptureConfig, a, CAPTURE_OPTIONS)
    if a.no_smooth:
        cfg.smooth_sigma = 0.0
    s = capture.run(
        a.video,
        a.out,
        cfg,
        audio=a.audio,
        render=not a.no_render,
        progress=not a.quiet,
        command=command_line(a),
        audio_optional=a.audio_optional,
        preset=a.rig,
        neutral=a.neutral,
        body=a.body,
    )
    return emit(s, a.json, summary_table)


def cmd_info(a) -> int:
    return emit(read_sequence(a.file, landmarks=False).summary(), a.json, summary_table)


def cmd_export(a) -> int:
    if a.units != "m" and a.format != "fbx":
        raise InputError("--units applies to the FBX export only")
    path, said = export(a.format, a.file, a.out, a.fps, a.rig, a.units, a.body)
    notes(said)
    print(f"wrote {path}")
    return 0


def cmd_vmc(a) -> int:
    loops = 1_000_000 if a.loop else 1
    return emit(vmc.send(a.result, a.to, loops, progress=not a.quiet and not a.json), a.json)


def cmd_livelink(a) -> int:
    return emit(livelink.send(a.file, a.to, a.subject, a.loops, progress=not a.quiet and not a.json), a.json)


def summary_table(s: dict) -> str:
    """A tracked sequence's summary (and a capture run's speed, files, warnings) as aligned text."""
    rows = [
        ("frames", f"{s['frames']} @ {s['fps']:g} fps ({s['duration_s']} s)"),
        ("size", "x".join(map(str, s["size"]))),
        ("face tracked", f"{100 * s['tracked_fraction']:.1f} %"),
        ("low-confidence frames", str(s["low_confidence_frames"])),
        (
            "mean fit error",
            f"{s['mean_fit_error_px']} px  (NME {100 * (s['mean_fit_nme'] or 0):.2f} %)"
            if s["mean_fit_error_px"] is not None
            else "-",
        ),
    ]
    if s.get("body_tracked_fraction") is not None:
        rows += [
            ("body tracked", f"{100 * s['body_tracked_fraction']:.1f} %"),
            (
                "hands tracked (L / R)",
                f"{100 * s['left_hand_tracked_fraction']:.1f} % / "
                f"{100 * s['right_hand_tracked_fraction']:.1f} %  (after interpolation "
                f"{100 * s['left_hand_after_interpolation']:.1f} / "
                f"{100 * s['right_hand_after_interpolation']:.1f})",
            ),
        ]
    rows.append(("speech features", _speech_line(s.get("speech"))))
    if "capture_fps" in s:
        rows += [
            ("capture speed", f"{s['capture_fps']} frames/s (decode+track+fit)"),
            ("total time", f"{s.get('total_s', '-')} s"),
        ]
    if s.get("time_s"):
        rows.append(("time split", time_split(s["time_s"])))
    w = max(len(k) for k, _ in rows)
    lines = [f"  {k:<{w}}  {v}" for k, v in rows]
    lines += [f"  wrote {p}" for p in s.get("outputs", [])]
    lines += [f"  warning: {m}" for m in s.get("warnings", [])]
    return "\n".join(lines)


def _speech_line(sp) -> str:
    if not sp:
        return "-"
    if not sp.get("present"):
        return f"none ({sp.get('reason')})"
    return f"{sp['duration_s']} s of audio" + (" (silent!)" if sp.get("silent") else "")
