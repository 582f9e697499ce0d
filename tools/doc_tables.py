"""Doc tables generated from result JSON, never typed by hand (issue 38).

A block in any markdown file under ``docs/`` or in ``README.md``::

    <!-- results: EVAL benchmarks/results/FILE.json -->
    ...generated lines...
    <!-- /results -->

is replaced by ``summary(result)`` of evaluation ``EVAL`` (``anima.eval.registry``: the same lines ``anima
eval all`` writes into its ``summary.md``) on that JSON file (an ``anima eval EVAL --json`` output, or the row
``EVAL`` of an ``anima eval all`` ``results.json``). ``EVAL`` = ``all``: the run's provenance and the minutes of
each row (the head of its ``summary.md``).

    .venv/bin/python tools/doc_tables.py           # rewrite every block
    .venv/bin/python tools/doc_tables.py --check   # exit 1 when a block differs from its JSON (a test runs it)
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from anima.io.atomic import write_text  # noqa: E402

BLOCK = re.compile(r"(<!-- results: (\S+) (\S+) -->\n)(.*?)(<!-- /results -->)", re.S)


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
    else:
        # a row of eval all is named after its evaluation (text2face_prompts: a row of text2face)
        ev = BY_NAME.get(name) or next(BY_NAME[e] for e in BY_NAME if name.startswith(e + "_"))
        lines = ev.runner().summary(result_of(name, path))
    return "\n".join(lines) + "\n"


def blocks(text: str):
    return list(BLOCK.finditer(text))


def refresh(doc: Path, root: Path = ROOT) -> tuple[str, list[str]]:
    """The document with every block regenerated, and the names of the blocks that changed."""
    text = doc.read_text()
    changed = []

    def sub(m):
        new = render(m.group(2), root / m.group(3))
        if new != m.group(4):
            changed.append(f"{doc.relative_to(root)}: {m.group(2)} ({m.group(3)})")
        return m.group(1) + new + m.group(5)

    return BLOCK.sub(sub, text), changed


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
