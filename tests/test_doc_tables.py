"""Doc tables are generated from result JSON: every ``<!-- results: ... -->`` block in docs/ and the
README equals what ``tools/doc_tables.py`` renders from its JSON file, and the tool notices a hand edit."""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _tool():
    spec = importlib.util.spec_from_file_location("doc_tables", ROOT / "tools" / "doc_tables.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_every_generated_doc_table_matches_its_result_json(tmp_path):
    tool = _tool()
    docs = [d for d in tool.documents() if tool.blocks(d.read_text())]
    assert len(docs) >= 3, docs
    n = 0
    for d in docs:
        text, changed = tool.refresh(d)
        assert not changed, changed
        n += len(tool.blocks(text))
    assert n >= 3
    # a number typed over a generated one is caught
    doc = docs[0]
    m = tool.blocks(doc.read_text())[0]
    body = m.group(4)
    digit = next(i for i, c in enumerate(body) if c.isdigit())
    edited = body[:digit] + str((int(body[digit]) + 1) % 10) + body[digit + 1 :]
    fake = tmp_path / "docs" / "x.md"
    fake.parent.mkdir()
    (tmp_path / m.group(3)).parent.mkdir(parents=True, exist_ok=True)
    (tmp_path / m.group(3)).write_bytes((ROOT / m.group(3)).read_bytes())
    fake.write_text(m.group(1) + edited + m.group(5) + "\n")
    _, changed = tool.refresh(fake, tmp_path)
    assert changed


def test_a_number_in_the_prose_is_generated_from_its_json_pointer(tmp_path):
    tool = _tool()
    (tmp_path / "r.json").write_text('{"rows": {"a b": {"x": [0.5, 0.0721]}}}')
    doc = tmp_path / "docs" / "x.md"
    doc.parent.mkdir()
    line = "reads <!--v:test r.json /rows/a%20b/x/1 .3f-->{}<sup>test</sup><!--/v--> on "
    line += "<!--v:development r.json /rows/a%20b/x/0-->{}<sup>development</sup><!--/v-->"
    line += " of <!--v:count r.json /rows/a%20b/x len-->2<sup>count</sup><!--/v-->\n"
    doc.write_text(line.format("0.072", "0.5"))
    assert tool.refresh(doc, tmp_path) == (doc.read_text(), [])
    doc.write_text(line.format("0.07", "0.5"))  # typed over, or the JSON changed since
    text, changed = tool.refresh(doc, tmp_path)
    assert text == line.format("0.072", "0.5") and len(changed) == 1


def test_every_generated_number_says_its_kind_where_it_appears(tmp_path):
    """Every generated block and value names its kind (a held-out test, a validation or development figure, a
    consistency check; or a count, cost or setting, which are not scores), and the generated text shows it to
    the reader: a value ends with the kind as a small tag, a block opens with a line naming its kind(s).
    ``--check`` fails on a block or value without a kind, or with one it does not know, and on a tag typed
    over."""
    tool = _tool()
    for d in tool.documents():
        assert tool.untagged(d) == [], d
    (tmp_path / "README.md").write_text("Nothing generated.\n")
    (tmp_path / "r.json").write_text('{"rows": [{"name": "a", "r": 0.91}], "x": 0.5}')
    doc = tmp_path / "docs" / "x.md"
    doc.parent.mkdir()
    good = (
        "The mouth reads r <!--v:consistency r.json /x .2f-->0.50<sup>consistency</sup><!--/v--> on it.\n\n"
        "<!-- results:test table:/rows r.json -->\n"
        f"{tool.block_head(['test'])}| name | r |\n|---|---|\n| a | 0.91 |\n<!-- /results -->\n"
    )
    doc.write_text(good)
    assert tool.refresh(doc, tmp_path) == (good, []) and tool.untagged(doc, tmp_path) == []
    assert tool.main(["--check"], root=tmp_path) == 0
    assert "<sup>**test**: held out" in good
    for bad in (
        good.replace("<!--v:consistency ", "<!--v ").replace("<sup>consistency</sup>", ""),  # a value, no kind
        good.replace("<!-- results:test ", "<!-- results: ").replace(tool.block_head(["test"]), ""),  # a block
        good.replace("consistency", "evidence"),  # a kind it does not know
    ):
        doc.write_text(bad)
        assert len(tool.untagged(doc, tmp_path)) == 1, bad
        assert tool.main(["--check"], root=tmp_path) == 1
    doc.write_text(good.replace("<sup>consistency</sup>", "<sup>test</sup>"))  # the tag typed over
    assert tool.refresh(doc, tmp_path)[1] and tool.main(["--check"], root=tmp_path) == 1
    # a block of several kinds names each
    assert tool.kinds_of("<!-- results:test+validation x y -->") == ["test", "validation"]
    assert "**test**" in tool.block_head(["test", "validation"]) and "**validation**" in tool.block_head(
        ["test", "validation"]
    )


def test_the_face_read_back_is_a_consistency_check_and_the_round_trip_its_evidence():
    """The face's Face Mesh read-back (driven, calibrated and judged by Face Mesh) is tagged consistency
    wherever a number of it appears; the face round trip's test identities are the test; the emotion checks on
    the shared clips are development figures; the text-to-face prompt suites' detector tables are consistency
    checks and the held-out suite's judge is the test."""
    tool = _tool()
    seen = {}  # a block's name (EVAL or EVAL:SECTION) and every file named -> the kinds given to it
    for d in tool.documents():
        text = d.read_text()
        for m in tool.BLOCK.finditer(text):
            for key in (m.group(2), m.group(3)):
                seen.setdefault(key, set()).update(tool.kinds_of(m.group(1)))
        for m in tool.VALUE.finditer(text):
            seen.setdefault(m.group(2), set()).update(tool.kinds_of(m.group(1)))
    readback = {k for k in seen if "face_readback" in k}
    assert readback and all(seen[k] <= {"consistency", "count"} for k in readback)
    assert seen["benchmarks/results/emotion_facs.json"] <= {"development", "count"}
    assert "test" in seen["benchmarks/results/roundtrip_face.json"]
    assert seen["text2face_prompts_heldout:detectors"] == {"consistency"}
    assert seen["text2face_prompts_heldout:judge"] == {"test"}
    assert seen["text2face_prompts:judge"] == seen["text2face_prompts_dev2:judge"] == {"development"}


def test_a_range_in_the_prose_is_reduced_from_every_row_of_a_result(tmp_path):
    """``*`` takes every row; min/max/median before the format reduce them (a range over an ablation's rows)."""
    tool = _tool()
    f = tmp_path / "r.json"
    f.write_text('{"rows": [{"v": {"n": 0.0374}}, {"v": {"n": 0.0385}}, {"v": {"n": 0.0380}}], "a": {"x": 1}}')
    assert tool.lookup({"a": {"x": 1, "y": 2}}, "/a/*") == [1, 2]
    assert tool.lookup({"a": {"x": {"l": [1, 2]}, "y": {"l": [3]}}}, "/a/*/l/*") == [1, 2, 3]
    got = [tool.value(f, "/rows/*/v/n", fmt) for fmt in ("min.2%", "max.2%", "median.4f", "mean.4f", "len")]
    assert got == ["3.74%", "3.85%", "0.0380", "0.0380", "3"]


def test_no_result_is_typed_in_the_docs():
    """Outside generated blocks and values every number that reads as a result is listed as a setting,
    a criterion or a quotation (``TYPED_OK``, each with why); none is typed."""
    tool = _tool()
    assert [t for d in tool.documents() for t in tool.typed_results(d)] == []
    assert all(why for why in tool.TYPED_OK.values())


def test_a_typed_result_is_caught_and_a_bound_is_not(tmp_path):
    tool = _tool()
    doc = tmp_path / "x.md"
    for typed in (
        "the mouth reads r 0.84 on it",
        "MAE 3.37 mm on test",
        "1.7x less encode time",
        "9 ms a frame",
        "recall 100 % on d3",
        "the ratio was 1.46 beside it",
    ):
        doc.write_text(f"Intro.\n\n{typed}.\n")
        assert len(tool.typed_results(doc)) == 1, typed
    for fine in (
        "targets r >= 0.8 for the mouth",
        "fit NME > 5 % is flagged",
        "F1 at 1.0 (sigma)",
        "MAE <!--v r.json /a .2f-->3.37<!--/v--> mm",
        "the command `x --ratio 1.5`",
        "n 100 frames",
    ):
        doc.write_text(f"{fine}.\n")
        assert tool.typed_results(doc) == [], fine


EVAL_ALL = "benchmarks/results/eval_all/results.json"


def test_the_docs_render_every_evaluation_number_from_the_one_run():
    """`anima eval all`'s results.json is the one evaluation result the docs render from: every block and
    inline number that names a file under benchmarks/results/eval_all/ names that one file, the folder holds only
    it and its summary, and the run is complete, every registered row ok, on a clean commit."""
    import json

    from anima.eval.registry import Context, rows

    tool = _tool()
    named = set()
    for d in tool.documents():
        text = d.read_text()
        named |= {m.group(3) for m in tool.BLOCK.finditer(text)} | {m.group(2) for m in tool.VALUE.finditer(text)}
    assert {n for n in named if "eval_all" in n} == {EVAL_ALL}
    folder = ROOT / "benchmarks" / "results" / "eval_all"
    assert sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file()) == [
        "results.json",
        "summary.md",
    ]
    res = json.loads((ROOT / EVAL_ALL).read_text())
    registered = [name for _, name, _ in rows(Context("ds", Path("evals"), Path("work"), False))]
    assert res["complete"] is True and res["quick"] is False and res["failed"] == []
    assert list(res["rows"]) == registered and all(e["status"] == "ok" for e in res["rows"].values())
    commit = res["provenance"]["commit"]
    assert commit and not commit.endswith("-dirty")


# What the one run's commands could execute: `anima dataset build` and `anima eval ...` (the CLI loads only the
# named command's module), every module the registry names, and everything those import, at any depth.
RUN_ENTRIES = ("anima.cli.main", "anima.cli.dataset", "anima.cli.evaluate", "anima.eval.all", "anima.eval.registry")
RUN_FILES = ("pyproject.toml", "requirements.txt", "requirements-nodeps.txt")  # the installed libraries


def run_reach(root: Path) -> tuple[set[str], set[str]]:
    """``(module files, data files)`` under ``root/anima`` that the one run's commands can reach: the closure of
    :data:`RUN_ENTRIES` over every ``anima`` import (module top or inside a function) and every string naming an
    ``anima.`` module; a data file is reached when a reached module's source names it (its file name, or a folder
    of it below its package other than a generic ``data``). Static and conservative: a module that might run
    counts."""
    import ast
    import re

    from anima.architecture import imports, modules, resolve

    known = modules(root / "anima")
    named = re.compile(r"^anima(\.[A-Za-z_][A-Za-z0-9_]*)+")
    seen: set[str] = set()
    todo = list(RUN_ENTRIES)
    while todo:
        m = todo.pop()
        if m in seen or m not in known:
            continue
        seen.add(m)
        parts = m.split(".")
        todo += [".".join(parts[:i]) for i in range(2, len(parts))]  # parent packages run their __init__
        todo += [resolve(t, n, known) for t, _, _, n in imports(known[m])]
        for node in ast.walk(ast.parse(known[m].read_text(encoding="utf-8"))):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and named.match(node.value):
                name = named.match(node.value).group(0)
                while name not in known and "." in name:
                    name = name.rsplit(".", 1)[0]
                todo.append(name)
    files = {str(known[m].relative_to(root)) for m in seen}
    text = "\n".join(known[m].read_text(encoding="utf-8") for m in seen)
    data = set()
    for f in (root / "anima").rglob("*"):
        if not f.is_file() or f.suffix in (".py", ".pyc"):
            continue
        rel = f.relative_to(root)
        folders = [d for d in rel.parts[2:-1] if d != "data"]
        if f.name in text or any(f'"{d}"' in text or f"/{d}/" in text or f"'{d}'" in text for d in folders):
            data.add(str(rel))
    return files, data


def test_the_one_run_stands_on_the_code_of_this_checkout():
    """No file the one run could execute or read changed since its commit: its numbers are this code's.
    Changes elsewhere in anima/ (the live package, the viewer, the character's look, exports) leave them
    standing; a changed dependency pin does not. Between two runs (the code moved on, the next run not made
    yet) docs/results.md must say so beside the numbers: that they are the previous run's, at its commit."""
    import json
    import subprocess

    import pytest

    commit = json.loads((ROOT / EVAL_ALL).read_text())["provenance"]["commit"]
    known = subprocess.run(["git", "-C", str(ROOT), "cat-file", "-e", f"{commit}^{{commit}}"], capture_output=True)
    if known.returncode != 0:
        pytest.skip(f"the run's commit {commit[:12]} is not in this clone's history (a shallow clone)")
    diff = subprocess.run(
        ["git", "-C", str(ROOT), "diff", "--name-only", commit, "--", "anima", *RUN_FILES],
        capture_output=True,
        text=True,
        check=True,
    )
    changed = {line for line in diff.stdout.splitlines() if "__pycache__" not in line}
    files, data = run_reach(ROOT)
    gone = {c for c in changed if c.endswith(".py") and not (ROOT / c).exists()}  # moved or removed: reached before?
    reached = sorted(changed & (files | data | set(RUN_FILES)) | gone)
    said = PREVIOUS_RUN.format(commit=commit[:12]) in " ".join((ROOT / "docs" / "results.md").read_text().split())
    assert reached == [] or said, (
        f"changed since the run behind the docs ({commit[:12]}), and the run reaches them: {reached}; docs/results.md "
        f"does not say its numbers are the previous run's ({PREVIOUS_RUN.format(commit=commit[:12])!r})"
    )


PREVIOUS_RUN = "are the previous run's, at commit {commit}"


def test_the_run_reach_follows_imports_strings_and_data(tmp_path):
    """The reach rule on a made-up package: a function-level import, a module named in a string and a data file
    named by a reached module are reached; a module nothing reaches, and its data, are not."""
    pkg = tmp_path / "anima"
    for d in ("cli", "eval", "live", "eval/prompts", "live/data"):
        (pkg / d).mkdir(parents=True, exist_ok=True)
        (pkg / d / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("")
    (pkg / "cli" / "main.py").write_text("def f():\n    from anima.eval import all\n")
    (pkg / "eval" / "all.py").write_text('MODULE = "anima.eval.rows"\n')
    (pkg / "eval" / "rows.py").write_text('SUITE = "prompts/suite.json"\n')
    (pkg / "eval" / "prompts" / "suite.json").write_text("{}")
    (pkg / "eval" / "prompts" / "__init__.py").unlink()
    (pkg / "live" / "run.py").write_text('ASSET = "look.npz"\n')
    (pkg / "live" / "data" / "look.npz").write_text("")
    files, data = run_reach(tmp_path)
    assert {"anima/eval/rows.py", "anima/eval/all.py", "anima/cli/main.py"} <= files
    assert "anima/live/run.py" not in files and "anima/live/__init__.py" not in files
    assert data == {"anima/eval/prompts/suite.json"}


def test_the_one_run_rule_catches_a_block_pointing_elsewhere():
    tool = _tool()
    text = "<!-- results: pose benchmarks/results/eval_all/rerun_pose/results.json -->\nx\n<!-- /results -->\n"
    assert [m.group(3) for m in tool.BLOCK.finditer(text)] == ["benchmarks/results/eval_all/rerun_pose/results.json"]
