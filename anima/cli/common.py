"""What every command group shares: printing results, the recorded command line, group parsers."""

from __future__ import annotations

import argparse
import dataclasses
import json
import shlex
import sys
from dataclasses import dataclass, field

from anima.cli.options import add_options
from anima.core.rig import PRESETS as RIG_PRESETS  # the conventions' one table
from anima.facemodel.character import BUILDS, DEFAULT_BUILD


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


@dataclass
class Rig:
    rig: str = field(default="anima", metadata={"choices": RIG_PRESETS})
    """joint names of body.bvh and avatar.glb: anima (Mixamo-style, no prefix), mixamo (mixamorig:), vrm (VRM 1.0
    humanoid) or unreal (UE mannequin); the same skeleton (docs/rig.md)"""


@dataclass
class Body:
    body: str = field(default=DEFAULT_BUILD, metadata={"choices": BUILDS})
    """the character's build in avatar.glb, body.bvh and avatar.mp4: neutral (neither sex's: a nearly flat chest,
    shoulders and hips between), female or male; the captured proportions adjust its size and limbs (docs/rig.md)"""


@dataclass
class Json:
    json: bool = False
    """print the result as JSON"""


@dataclass
class JsonQuiet(Json):
    quiet: bool = False
    """no progress bars"""


def add_args(p, *classes, help_extra: dict | None = None) -> None:
    """The options of every field of ``classes`` (a command's own arguments, declared as dataclasses like the
    features' configs: :mod:`anima.cli.options`), in their order; ``help_extra``: text added to a field's help
    (what is known only when the parser is built, e.g. a table's entries)."""
    for cls in classes:
        add_options(p, cls, [f.name for f in dataclasses.fields(cls)], help_extra)


def add_rig(p) -> None:
    """``--rig``: the naming of the skeleton's joints in body.bvh and avatar.glb."""
    add_args(p, Rig)


def add_json_quiet(p, quiet: bool = True) -> None:
    add_args(p, JsonQuiet if quiet else Json)


def time_split(t: dict) -> str:
    """``{stage: seconds}`` as one line: ``start 1.2 s, capture 4.1 s, ... (total 9.0 s)``."""
    parts = [f"{k} {v:.1f} s" for k, v in t.items() if k != "total" and v is not None]
    return ", ".join(parts) + f"  (total {t.get('total', 0):.1f} s)"
