"""Command-line options made from config dataclasses: one source of defaults and help.

A config field becomes an option named after it (``max_gap`` -> ``--max-gap``), typed by its annotation, with
its docstring (the string right below the field) as help and its default shown. ``field(metadata=...)``
refines it:

* ``flag``: another option name (``--sigma`` for ``smooth_sigma``);
* ``choices``: allowed values;
* ``range``: ``(low, high)`` inclusive bounds of a number (NaN and infinity are always refused);
* ``metavar``; ``repeat``: a list filled by repeating the option;
* ``positional``: a positional argument (a list field: any number of them);
* ``required``: the option must be given; ``nargs``: e.g. ``"+"`` for a list after one option;
* ``parse``: the name of a parser in this module (``step_grid``); ``const``: the option may be given without a
  value, which then is ``const``.

A ``bool`` field that defaults to False is a switch (``--face-only``); one that defaults to True gets a
``--no-...`` switch (or the ``flag`` given). :func:`config_from_args` builds the config back from the parsed
options, so the command and the Python API share defaults.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import inspect
import math
import re
import textwrap
from functools import cache


@cache
def field_docs(cls) -> dict[str, str]:
    """``{field: docstring}`` of a dataclass: the string literal right below each annotated field."""
    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        if not dataclasses.is_dataclass(klass):
            continue
        try:
            tree = ast.parse(textwrap.dedent(inspect.getsource(klass)))
        except (OSError, TypeError):
            continue
        body = tree.body[0].body
        for node, nxt in zip(body, body[1:] + [None]):
            if (
                isinstance(node, ast.AnnAssign)
                and isinstance(node.target, ast.Name)
                and isinstance(nxt, ast.Expr)
                and isinstance(nxt.value, ast.Constant)
                and isinstance(nxt.value.value, str)
            ):
                text = re.sub(r":(?:mod|func|class|meth|data):`([^`]*)`", r"\1", nxt.value.value)
                docs[node.target.id] = " ".join(text.replace("``", "").split())
    return docs


SEED_RANGE = (0, 2**32 - 1)  # what numpy's and torch's generators take


def number(kind, low=None, high=None):
    """An argparse type: a finite ``kind`` (int or float) within ``[low, high]``."""

    def parse(text: str):
        try:
            v = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {'an integer' if kind is int else 'a number'}") from None
        if isinstance(v, float) and not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
        if (low is not None and v < low) or (high is not None and v > high):
            lo = "-inf" if low is None else low
            hi = "inf" if high is None else high
            raise argparse.ArgumentTypeError(f"{text} is outside [{lo}, {hi}]")
        return v

    parse.__name__ = kind.__name__
    return parse


def _kind(annotation: str):
    a = str(annotation).replace(" ", "")
    optional = "|None" in a or "Optional[" in a
    base = a.replace("|None", "").replace("Optional[", "").rstrip("]")
    return base, optional


def add_options(parser: argparse.ArgumentParser, cls, names: list[str], help_extra: dict | None = None) -> None:
    """Add the options of ``cls``'s fields ``names`` to ``parser``."""
    fields = {f.name: f for f in dataclasses.fields(cls)}
    docs = field_docs(cls)
    inst = cls()
    for name in names:
        f = fields[name]
        md = dict(f.metadata)
        default = getattr(inst, name)
        base, optional = _kind(f.type)
        flag = md.get("flag", "--" + name.replace("_", "-"))
        help_ = docs.get(name, "") + ((" " + help_extra[name]) if help_extra and name in help_extra else "")
        help_ = help_.replace("%", "%%")
        kw: dict = {"dest": name}
        if md.get("positional"):
            is_list = base.startswith("list")
            nargs = md.get("nargs", "*" if is_list else None)
            kw = {
                "nargs": nargs,
                "metavar": md.get("metavar", None if "choices" in md else name.upper()),
                "help": help_,
            }
            if "choices" in md:
                kw["choices"] = md["choices"]
            if is_list:
                kw["default"] = []
            parser.add_argument(name, **{k: v for k, v in kw.items() if v is not None})
            continue
        if base == "bool":
            if default:
                kw.update(action="store_false", help=help_)
                flag = md.get("flag", "--no-" + name.replace("_", "-"))
            else:
                kw.update(action="store_true", help=help_)
            parser.add_argument(flag, **kw)
            continue
        if md.get("repeat"):
            kw.update(action="append", default=[], metavar=md.get("metavar"), help=help_)
            parser.add_argument(flag, **kw)
            continue
        if md.get("nargs"):
            kw["nargs"] = md["nargs"]
        if md.get("required"):
            kw["required"] = True
        if "const" in md:
            kw.update(nargs="?", const=md["const"])
        if "parse" in md:
            kw["type"] = globals()[md["parse"]]
        elif base in ("int", "float"):
            lo, hi = md.get("range", SEED_RANGE if name == "seed" else (None, None))
            kw["type"] = number(int if base == "int" else float, lo, hi)
        elif base == "str":
            kw["type"] = str
        if "choices" in md:
            kw["choices"] = md["choices"]
        if "metavar" in md or "choices" not in md:
            kw["metavar"] = md.get("metavar", flag.lstrip("-").upper().replace("-", "_"))
        shown = "none" if default is None else str(default).replace("%", "%%")
        if md.get("required"):
            kw.update(help=help_)
            parser.add_argument(flag, **kw)
            continue
        if "default" not in help_.lower():
            help_ = f"{help_} (default: {shown})".strip()
        kw.update(default=default, help=help_)
        del optional
        parser.add_argument(flag, **kw)


def config_from_args(cls, args: argparse.Namespace, names: list[str], base=None, **overrides):
    """``cls`` (or ``base``) with the parsed values of ``names`` and ``overrides``."""
    values = {n: getattr(args, n) for n in names if hasattr(args, n)}
    return dataclasses.replace(base if base is not None else cls(), **values, **overrides)


def positive_int(text: str) -> int:
    return number(int, 1)(text)


def step_grid(text: str) -> tuple[int, ...]:
    """``250,500,1000``: distinct positive step counts."""
    try:
        values = tuple(sorted({positive_int(x.strip()) for x in text.split(",") if x.strip()}))
    except argparse.ArgumentTypeError:
        values = ()
    if not values:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of positive step counts")
    return values
