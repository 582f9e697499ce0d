"""Doc tables generated from result JSON, never typed by hand (issue 38).

A block in any markdown file under ``docs/`` or in ``README.md``::

    <!-- results: EVAL benchmarks/results/FILE.json -->
    ...generated lines...
    <!-- /results -->

is replaced by ``summary(result)`` of evaluation ``EVAL`` (``anima.eval.registry``: the same lines ``anima
eval all`` writes into its ``summary.md``) on that JSON file (an ``anima eval EVAL --json`` output, or the row
``EVAL`` of an ``anima eval all`` ``results.json``). ``EVAL`` = ``all``: the run's provenance and the minutes of
each row (the head of its ``summary.md``); ``EVAL:SECTION``: one part of the result, rendered by the
evaluation module's ``SECTION_summary`` (e.g. ``annotations:capture_emotions``); ``table:POINTER[:COLS]``: the
list of records at that JSON pointer of any result file (a benchmark's rows) as a table.

A number in the prose is generated the same way, inline::

    ... the neutral clip reads mouthSmile <!--v FILE POINTER FORMAT-->0.072<!--/v--> ...

where ``POINTER`` is a JSON pointer into ``FILE`` (``/rows/annotations/result/capture_emotions/neutral_mouth_smile``;
``%20`` for a space in a key) and ``FORMAT`` a Python format spec (``.3f``, ``.0%``, ``,d``; default ``g``)
or ``len`` (how many items a list holds); ``*`` in the pointer takes every item of a list, and ``min``,
``max`` or ``median`` before the spec (``min.2%``) reduce them to one number.

    .venv/bin/python tools/doc_tables.py           # rewrite every block
    .venv/bin/python tools/doc_tables.py --check   # exit 1 when a block differs from its JSON (a test runs it)
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import sys
from pathlib import Path
from urllib.parse import unquote

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from anima.io.atomic import write_text  # noqa: E402

BLOCK = re.compile(r"(<!-- results: (\S+) (\S+) -->\n)(.*?)(<!-- /results -->)", re.S)
VALUE = re.compile(r"(<!--v (\S+) (\S+?)(?: (\S+?))?-->)(.*?)(<!--/v-->)")


def documents(root: Path = ROOT) -> list[Path]:
    return sorted((root / "docs").glob("*.md")) + [root / "README.md"]


def result_of(name: str, path: Path) -> dict:
    """The result of evaluation ``name`` in ``path``: a command's JSON, or the row of that name of an ``eval
    all`` results.json."""
    data = json.loads(path.read_text())
    rows = data.get("rows") if isinstance(data, dict) else None
    if isinstance(rows, dict) and "provenance" in data:  # eval all
        row = rows.get(name)
        if not row or row.get("status") != "ok":
            raise KeyError(f"{path}: no ok row {name!r}")
        return row["result"]
    return data


def render(name: str, path: Path) -> str:
    from anima.eval.all import timing_lines
    from anima.eval.registry import BY_NAME

    if name == "all":
        lines = timing_lines(json.loads(path.read_text()))
    elif name.startswith("table:"):  # table:POINTER[:COL,COL...]: a list of records as a table
        pointer, _, cols = name[len("table:") :].partition(":")
        lines = table_lines(lookup(json.loads(path.read_text()), pointer), cols.split(",") if cols else None)
    elif ":" in name:  # EVAL:SECTION, one part of a result: the evaluation module's SECTION_summary
        row, section = name.split(":", 1)
        ev = BY_NAME.get(row) or next(BY_NAME[e] for e in BY_NAME if row.startswith(e + "_"))
        lines = getattr(ev.runner(), f"{section}_summary")(result_of(row, path))
    else:
        # a row of eval all is named after its evaluation (text2face_prompts: a row of text2face)
        ev = BY_NAME.get(name) or next(BY_NAME[e] for e in BY_NAME if name.startswith(e + "_"))
        lines = ev.runner().summary(result_of(name, path))
    return "\n".join(lines) + "\n"


def lookup(node, pointer: str):
    """The node at JSON ``pointer`` (``/a/0/b``; ``%20`` for a space in a key; ``*`` for every item of a list
    or every value of a record, which makes the result a list, one flat list for several stars)."""
    return _walk(node, [unquote(k) for k in filter(None, pointer.strip("/").split("/"))])


def _walk(node, keys: list[str]):
    for i, key in enumerate(keys):
        if key == "*":
            items = node if isinstance(node, list) else list(node.values())
            got = [_walk(x, keys[i + 1 :]) for x in items]
            return [y for g in got for y in g] if "*" in keys[i + 1 :] else got
        node = node[int(key)] if isinstance(node, list) else node[key]
    return node


REDUCE = {"min": min, "max": max, "median": statistics.median_high}


def value(path: Path, pointer: str, fmt: str | None) -> str:
    """The number (or text) at JSON ``pointer`` of ``path``, formatted; ``len`` counts a list's items, and
    ``min``/``max``/``median`` followed by a format spec (``min.2%``) reduce a list (a ``*`` pointer) first."""
    node = lookup(json.loads(path.read_text()), pointer)
    if fmt == "len":  # how many items a list (or keys a record) holds
        return str(len(node))
    for name, f in REDUCE.items():
        if fmt and fmt.startswith(name):
            node, fmt = f(node), fmt[len(name) :]
    return format(node, fmt or ("g" if isinstance(node, float) else ""))


def table_lines(records: list[dict], cols: list[str] | None = None) -> list[str]:
    """A markdown table of ``records`` (a benchmark's rows), the columns named by their keys (``a/b``: the key
    ``b`` of the record's ``a``)."""
    cols = cols or list(records[0])

    def get(r, c):
        for k in c.split("/"):
            r = r.get(k) if isinstance(r, dict) else None
        return r

    def cell(v):
        return "-" if v is None else format(v, "g") if isinstance(v, float) else str(v).replace("|", "\\|")

    out = ["| " + " | ".join(c.replace("_", " ") for c in cols) + " |", "|---" * len(cols) + "|"]
    return out + ["| " + " | ".join(cell(get(r, c)) for c in cols) + " |" for r in records]


def blocks(text: str):
    return list(BLOCK.finditer(text)) + list(VALUE.finditer(text))


def refresh(doc: Path, root: Path = ROOT) -> tuple[str, list[str]]:
    """The document with every block regenerated, and the names of the blocks that changed."""
    text = doc.read_text()
    changed = []

    def sub(m):
        new = render(m.group(2), root / m.group(3))
        if new != m.group(4):
            changed.append(f"{doc.relative_to(root)}: {m.group(2)} ({m.group(3)})")
        return m.group(1) + new + m.group(5)

    def sub_value(m):
        new = value(root / m.group(2), m.group(3), m.group(4))
        if new != m.group(5):
            changed.append(f"{doc.relative_to(root)}: {m.group(3)} ({m.group(2)}): {m.group(5)} -> {new}")
        return m.group(1) + new + m.group(6)

    return VALUE.sub(sub_value, BLOCK.sub(sub, text)), changed


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", action="store_true", help="only say which blocks are stale (exit 1 if any)")
    args = ap.parse_args(argv)
    stale = []
    for doc in documents():
        if not blocks(doc.read_text()):
            continue
        text, changed = refresh(doc)
        stale += changed
        if changed and not args.check:
            write_text(doc, text)
    for s in stale:
        print(("stale: " if args.check else "rewrote: ") + s)
    return 1 if stale and args.check else 0


if __name__ == "__main__":
    sys.exit(main())
