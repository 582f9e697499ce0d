"""What every command group shares: printing results, the recorded command line, group parsers."""

from __future__ import annotations

import argparse
import json
import shlex
import sys


def command_line(a: argparse.Namespace) -> str:
    """The command that made an artifact, as typed (recorded in manifests and checkpoints)."""
    return "anima " + shlex.join(getattr(a, "argv", []))


def emit(result: dict, as_json: bool, text=None) -> int:
    """Print ``result`` as JSON, or with ``text(result)`` (default: one ``key  value`` line per entry)."""
    if as_json:
        print(json.dumps(result, indent=2))
    elif text is not None:
        print(text(result))
    else:
        w = max((len(k) for k in result), default=0)
        print("\n".join(f"  {k:<{w}}  {v}" for k, v in result.items()))
    return 0


def notes(lines, prefix: str = "note") -> None:
    for n in lines or []:
        print(f"anima: {prefix}: {n}", file=sys.stderr)


def group(sub, name: str, help_: str, dest: str, metavar: str):
    """A command group (``anima eval ...``): its parser, and the subparsers of its commands. ``anima GROUP``
    alone prints the group's help."""
    p = sub.add_parser(name, help=help_, description=help_)
    p.set_defaults(group_parser=p)
    return p.add_subparsers(dest=dest, metavar=metavar, parser_class=type(p))


RIG_PRESETS = ("anima", "mixamo", "vrm", "unreal")  # anima.core.rig.PRESETS (the CLI does not load the rig)


def add_rig(p) -> None:
    """``--rig``: the naming of the skeleton's joints in body.bvh and avatar.glb."""
    p.add_argument(
        "--rig",
        choices=RIG_PRESETS,
        default="anima",
        help="joint names of body.bvh and avatar.glb: anima (Mixamo-style, no prefix), mixamo (mixamorig:), "
        "vrm (VRM 1.0 humanoid) or unreal (UE mannequin); the same skeleton (docs/rig.md)",
    )


def add_json_quiet(p, quiet: bool = True) -> None:
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    if quiet:
        p.add_argument("--quiet", action="store_true", help="no progress bars")


def time_split(t: dict) -> str:
    """``{stage: seconds}`` as one line: ``start 1.2 s, capture 4.1 s, ... (total 9.0 s)``."""
    parts = [f"{k} {v:.1f} s" for k, v in t.items() if k != "total" and v is not None]
    return ", ".join(parts) + f"  (total {t.get('total', 0):.1f} s)"
