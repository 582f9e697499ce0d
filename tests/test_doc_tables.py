"""Doc tables are generated from result JSON (issue 38): every ``<!-- results: ... -->`` block in docs/ and the
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
    line = "reads <!--v r.json /rows/a%20b/x/1 .3f-->{}<!--/v--> on <!--v r.json /rows/a%20b/x/0-->{}<!--/v-->"
    line += " of <!--v r.json /rows/a%20b/x len-->2<!--/v-->\n"
    doc.write_text(line.format("0.072", "0.5"))
    assert tool.refresh(doc, tmp_path) == (doc.read_text(), [])
    doc.write_text(line.format("0.07", "0.5"))  # typed over, or the JSON changed since
    text, changed = tool.refresh(doc, tmp_path)
    assert text == line.format("0.072", "0.5") and len(changed) == 1


def test_a_range_in_the_prose_is_reduced_from_every_row_of_a_result(tmp_path):
    """``*`` takes every row; min/max/median before the format reduce them (a range over an ablation's rows)."""
    tool = _tool()
    f = tmp_path / "r.json"
    f.write_text('{"rows": [{"v": {"n": 0.0374}}, {"v": {"n": 0.0385}}, {"v": {"n": 0.0380}}], "a": {"x": 1}}')
    assert tool.lookup({"a": {"x": 1, "y": 2}}, "/a/*") == [1, 2]
    assert tool.lookup({"a": {"x": {"l": [1, 2]}, "y": {"l": [3]}}}, "/a/*/l/*") == [1, 2, 3]
    got = [tool.value(f, "/rows/*/v/n", fmt) for fmt in ("min.2%", "max.2%", "median.4f", "len")]
    assert got == ["3.74%", "3.85%", "0.0380", "3"]
