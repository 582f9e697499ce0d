"""Doc tables generated from result JSON, never typed by hand.

A block in any markdown file under ``docs/`` or in ``README.md``::

    <!-- results:KIND EVAL benchmarks/results/FILE.json -->
    ...generated lines...
    <!-- /results -->

is replaced by ``summary(result)`` of evaluation ``EVAL`` (``anima.eval.registry``: the same lines ``anima
eval all`` writes into its ``summary.md``) on that JSON file (an ``anima eval EVAL --json`` output, or the row
``EVAL`` of an ``anima eval all`` ``results.json``). ``EVAL`` = ``all``: the run's provenance and the minutes of
each row (the head of its ``summary.md``); ``EVAL:SECTION``: one part of the result, rendered by the
evaluation module's ``SECTION_summary`` (e.g. ``annotations:capture_emotions``); ``table:POINTER[:COLS]``: the
list of records at that JSON pointer of any result file (a benchmark's rows) as a table.

A number in the prose is generated the same way, inline::

    ... the neutral clip reads mouthSmile <!--v:development FILE POINTER FORMAT-->0.072<sup>development</sup><!--/v-->

where ``POINTER`` is a JSON pointer into ``FILE`` (``/rows/annotations/result/capture_emotions/neutral_mouth_smile``;
``%20`` for a space in a key) and ``FORMAT`` a Python format spec (``.3f``, ``.0%``, ``,d``; default ``g``)
or ``len`` (how many items a list holds); ``*`` in the pointer takes every item of a list, and ``min``,
``max``, ``median`` or ``mean`` before the spec (``min.2%``) reduce them to one number.

Every generated number says what kind of number it is (``KINDS``): ``KIND`` after ``results:`` or ``v:`` is
one of them (a block may name several joined by ``+`` when its own rows or columns say which is which), and the
generated text carries it where a reader sees it: a value ends with the kind as a small tag
(``0.072<sup>development</sup>``), a block opens with a line naming its kinds. A held-out ``test`` is run once
on data never used to choose anything; a ``validation`` figure is on data that chose a setting; a
``development`` figure on data looked at while building; a ``consistency`` check scores a method by what drives
it (the face's Face Mesh read-back, the text-to-face timeline read by the detectors that labelled its
segments); ``count``, ``cost`` and ``setting`` are not scores (how many, how long or how much memory, a value
the code uses). ``--check`` fails on a block or value without a known kind.

A result is never typed: :func:`typed_results` finds a number in the prose (outside blocks, inline
values and code) that reads as a measurement (after a metric word such as r, F1, MAE, SSIM, recall, mean or
took; "1.7x faster"; "9 ms a frame"), unless a comparison or bound precedes it (a target or a threshold);
``TYPED_OK`` lists the few left that are settings, criteria or numbers quoted from a seed or a reference, each
with why. ``--check`` fails on any other.

    .venv/bin/python tools/doc_tables.py           # rewrite every block
    .venv/bin/python tools/doc_tables.py --check   # exit 1 when a block differs from its JSON, a block or
                                                   # value has no kind, or a result is typed (a test runs it)
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

BLOCK = re.compile(r"(<!-- results(?::\S*)? (\S+) (\S+) -->\n)(.*?)(<!-- /results -->)", re.S)
VALUE = re.compile(r"(<!--v(?::\S*)? (\S+) (\S+?)(?: (\S+?))?-->)(.*?)(<!--/v-->)")
KIND_OF = re.compile(r"^<!--(?: results|v)(?::(\S*))? ")  # the KIND of a block's or a value's opening marker
# what each kind of number is: (the words a block's opening line gives it, scores or not)
KINDS = {
    "test": "held out: run once, on data never used to choose anything",
    "validation": "on data that chose a setting; not a result",
    "development": "on data looked at while building",
    "consistency": "a method scored by what drives it; not evidence of quality",
    "count": "how many; not a score",
    "cost": "time, speed or memory; not a score",
    "setting": "a value the code uses; not a score",
}


def kinds_of(marker: str) -> list[str]:
    """The kinds a block's or a value's opening marker names (``results:test+consistency``); [] when none."""
    m = KIND_OF.match(marker)
    return [k for k in (m.group(1) or "").split("+") if k] if m else []


def kind_problem(marker: str) -> str | None:
    """Why a block's or value's marker has no usable kind, or None."""
    ks = kinds_of(marker)
    if not ks:
        return "no kind (" + " / ".join(KINDS) + ")"
    bad = [k for k in ks if k not in KINDS]
    return f"unknown kind {', '.join(bad)!r} (" + " / ".join(KINDS) + ")" if bad else None


def value_tag(kinds: list[str]) -> str:
    """What follows a generated value: its kind, small."""
    return "<sup>" + "+".join(kinds) + "</sup>" if kinds else ""


def block_head(kinds: list[str]) -> str:
    """A block's first generated line: its kind(s) in words, small."""
    if not kinds:
        return ""
    if len(kinds) == 1:
        return f"<sup>**{kinds[0]}**: {KINDS.get(kinds[0], '?')}</sup>\n\n"
    named = "; ".join(f"**{k}**: {KINDS.get(k, '?')}" for k in kinds)
    return f"<sup>{named} (the rows and columns say which)</sup>\n\n"


_NUM = r"\d+\.\d+(?:\s?%|x\b)?|\d+(?:\s?%|x\b| ?ms\b| ?mm\b| ?fps\b)"
TYPED = re.compile(
    r"\b(?:r|F1|MAE|RMSE|SSIM|LPIPS|NME|MPJPE|PCK|AUC|recall|precision|accuracy|scored?|reads?|measured|took|"
    r"takes|costs?|median|mean|ratio|found in|sliding|error)\b([^.;:()]{0,12}?)(?<![\w.])(" + _NUM + ")"
    r"|()(?<![\w.])(\d+(?:\.\d+)?x) (?:less|more|slower|faster)"
    r"|()(?<![\w.])(\d+(?:\.\d+)? ?ms) a frame"
)
BOUND = re.compile(r"(?:[<>=]|\bwithin|\bbelow|\bunder|\bover|\bat least|\bat most|\bat|\bby construction)\s*$")
# (document, number, words on its line) -> why it is typed: settings, criteria and quoted numbers, not results
TYPED_OK = {
    ("detectors.md", "1.0", "precision and recall are both"): "the selection rule (both are 1)",
    ("gesture.md", "0.61", "For reference, a captured talking clip"): "a reference quoted from a captured clip",
    ("pose3d.md", "150 mm", "PCK@150 mm"): "the metric's name (PCK at 150 mm)",
    ("face_rig.md", "0.8", "eye aspect ratio from open 0.8"): "a setting: the lid opening's open level",
    ("face_rig.md", "0.2", "clip median to shut 0.2"): "a setting: the lid opening's shut level",
    ("rig.md", "1.77", "gets the mean adult"): "a setting: the default character's height",
    ("text2face_model.md", "95 %", "95 % confidence interval"): "the interval's level",
}


def typed_results(doc: Path) -> list[str]:
    """Numbers in ``doc``'s prose that read as typed results and are not listed in ``TYPED_OK``."""
    text = BLOCK.sub(lambda m: m.group(1) + "\n" * m.group(4).count("\n") + m.group(5), doc.read_text())
    text = VALUE.sub("<v>", text)
    text = re.sub(r"```.*?```", lambda m: "\n" * m.group(0).count("\n"), text, flags=re.S)
    text = re.sub(r"`[^`\n]*`", "<c>", text)
    found = []
    for i, line in enumerate(text.splitlines(), 1):
        for m in TYPED.finditer(line):
            gap, num = next((m.group(k), m.group(k + 1)) for k in (1, 3, 5) if m.group(k + 1))
            if BOUND.search(gap or "") or any(d == doc.name and n == num and words in line for d, n, words in TYPED_OK):
                continue
            found.append(f"{doc.name}:{i}: typed result {num!r} in: {line.strip()[:100]}")
    return found


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


REDUCE = {"min": min, "max": max, "median": statistics.median_high, "mean": statistics.fmean, "sum": sum}


def value(path: Path, pointer: str, fmt: str | None) -> str:
    """The number (or text) at JSON ``pointer`` of ``path``, formatted; ``len`` counts a list's items, and
    ``min``/``max``/``median``/``mean``/``sum`` followed by a format spec (``min.2%``, ``sum,``) reduce a list (a
    ``*`` pointer) first."""
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
        new = block_head(kinds_of(m.group(1))) + render(m.group(2), root / m.group(3))
        if new != m.group(4):
            changed.append(f"{doc.relative_to(root)}: {m.group(2)} ({m.group(3)})")
        return m.group(1) + new + m.group(5)

    def sub_value(m):
        new = value(root / m.group(2), m.group(3), m.group(4)) + value_tag(kinds_of(m.group(1)))
        if new != m.group(5):
            changed.append(f"{doc.relative_to(root)}: {m.group(3)} ({m.group(2)}): {m.group(5)} -> {new}")
        return m.group(1) + new + m.group(6)

    return VALUE.sub(sub_value, BLOCK.sub(sub, text)), changed


def untagged(doc: Path, root: Path = ROOT) -> list[str]:
    """The blocks and values of ``doc`` whose marker names no known kind."""
    out = []
    text = doc.read_text()
    for m in blocks(text):
        why = kind_problem(m.group(1))
        if why:
            line = text.count("\n", 0, m.start()) + 1
            where = doc.relative_to(root) if doc.is_relative_to(root) else doc
            out.append(f"{where}:{line}: {why}: {m.group(1).strip()}")
    return out


def main(argv=None, root: Path = ROOT) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", action="store_true", help="only say which blocks are stale (exit 1 if any)")
    args = ap.parse_args(argv)
    stale = []
    docs = [d for d in documents(root) if d.is_file()]
    for doc in docs:
        if not blocks(doc.read_text()):
            continue
        text, changed = refresh(doc, root)
        stale += changed
        if changed and not args.check:
            write_text(doc, text)
    for s in stale:
        print(("stale: " if args.check else "rewrote: ") + s)
    typed = [t for doc in docs for t in typed_results(doc)]
    for t in typed:
        print(t)
    kindless = [u for doc in docs for u in untagged(doc, root)]
    for u in kindless:
        print(u)
    return 1 if (stale and args.check) or typed or kindless else 0


if __name__ == "__main__":
    sys.exit(main())
