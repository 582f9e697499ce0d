"""The structure rules of docs/architecture.md, checked on the code itself."""

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

from anima.architecture import LAYERS, heavy_modules, modules, violations

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "anima"


def test_no_import_goes_up_a_layer_or_sideways_and_lazy_imports_are_heavy():
    assert violations(PKG) == []


def test_every_package_has_a_layer():
    pkgs = {p.name for p in PKG.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    pkgs |= {p.stem for p in PKG.glob("*.py") if p.stem != "__init__"}
    assert pkgs <= set(LAYERS), pkgs - set(LAYERS)


def test_the_rule_catches_a_bad_import(tmp_path):
    """The checker itself: an upward import, a sideways one and a light lazy import are each reported."""
    root = tmp_path / "anima"
    for pkg in ("core", "capture", "gesture", "text2face"):
        (root / pkg).mkdir(parents=True)
        (root / pkg / "__init__.py").write_text("")
    (root / "__init__.py").write_text("")
    (root / "core" / "maths.py").write_text("from anima.capture import run\n")
    (root / "capture" / "run.py").write_text("def f():\n    from anima.core import maths\n")
    (root / "gesture" / "g.py").write_text("from anima.text2face import t\n")
    (root / "text2face" / "t.py").write_text("import torch\n")
    v = "\n".join(violations(root))
    assert "higher layer" in v and "sideways" in v and "light" in v
    assert "anima.text2face.t" in heavy_modules(root)


def test_no_import_cycle_between_modules():
    known = modules(PKG)
    graph = {}
    for mod, path in known.items():
        tree = ast.parse(path.read_text())
        deps = set()
        for node in tree.body:
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("anima"):
                for a in node.names:
                    t = f"{node.module}.{a.name}"
                    deps.add(t if t in known else node.module)
        graph[mod] = {d for d in deps if d in known and d != mod}
    state = {}

    def visit(m, stack):
        state[m] = 1
        for d in graph[m]:
            if state.get(d) == 1:
                raise AssertionError(" -> ".join(stack + [m, d]))
            if d not in state:
                visit(d, stack + [m])
        state[m] = 2

    for m in graph:
        if m not in state:
            visit(m, [])


def _contract_names() -> set[str]:
    tree = ast.parse((PKG / "core" / "contract.py").read_text())
    names = set()
    for node in tree.body:
        targets = (
            node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(node, ast.AnnAssign) else []
        )
        for t in targets:
            for n in ast.walk(t):
                if isinstance(n, ast.Name) and n.id.isupper():
                    names.add(n.id)
    return names


MAGIC = {30.0, 15.0, 53, 56}  # the text and gesture rates, the expression count, the face frame size
NOT_THE_CONTRACT = "# contract: not"  # a line that writes one of them for another reason says so


def test_the_data_contract_is_assigned_once():
    """Every name of the data contract (rates, window layout, sizes, the 53 expression names, the
    tracked skeleton's joints) is assigned in anima/core/contract.py only, and no module writes its numbers
    (30.0, 15.0, 53, 56) as literals: they import them."""
    names = _contract_names()
    assert {"TEXT_FPS", "GESTURE_FPS", "WINDOW", "HOP", "FACE_DIM", "EXPR_NAMES", "JOINT_NAMES"} <= names
    found = []
    for path in sorted(PKG.rglob("*.py")):
        if path == PKG / "core" / "contract.py":
            continue
        lines = path.read_text().splitlines()
        for node in ast.walk(ast.parse("\n".join(lines))):
            targets = []
            if isinstance(node, ast.Assign):
                targets = node.targets
            elif isinstance(node, (ast.AnnAssign, ast.AugAssign)):
                targets = [node.target]
            for t in targets:  # a name bound (alone or in a tuple), not a subscript that uses one
                for n in [t] + (list(t.elts) if isinstance(t, ast.Tuple) else []):
                    if isinstance(n, ast.Name) and n.id in names:
                        found.append(f"{path.relative_to(ROOT)}:{node.lineno} assigns {n.id}")
            if (
                isinstance(node, ast.Constant)
                and type(node.value) in (int, float)
                and node.value in MAGIC
                and (type(node.value) is float) == (node.value in (30.0, 15.0))
                and NOT_THE_CONTRACT not in lines[node.lineno - 1]
            ):
                found.append(f"{path.relative_to(ROOT)}:{node.lineno} writes {node.value!r}")
    assert found == []


def test_the_contract_rule_catches_a_copy(tmp_path):
    """The checker itself, on a module that re-declares a rate and slices with a literal."""
    bad = "TEXT_FPS = 30.0\nx = y[..., :53]\n"
    tree = ast.parse(bad)
    assigned = [n.id for node in ast.walk(tree) if isinstance(node, ast.Assign) for n in node.targets]
    literals = [n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and n.value in MAGIC]
    assert "TEXT_FPS" in _contract_names() and assigned == ["TEXT_FPS", "x"] and literals == [30.0, 53]


def _event_literals(tree: ast.AST, names: set[str]) -> set[str]:
    return {
        n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str) and n.value in names
    }


# the modules that may spell an event's name: the vocabulary itself, the independent judge (its own list and
# rules), the importers of other datasets' words (their annotation keywords), and the exporters'
# expression names (VRM's "blink" is the avatar's expression, not the event)
OWN_WORDS = {"core/events.py", "eval/text2face/judge.py", "dataset/annotations.py", "dataset/config.py",
             "export/vrm.py", "export/vmc.py"}  # fmt: skip


def test_the_event_vocabulary_is_declared_once():
    """Every facial event (its channels, side, hold, strength and phrases) is declared in
    anima/core/events.py; the parser, composer, detectors, descriptions and evaluations read it and name events
    by its constants, so no other module writes a detected event's name as a string."""
    from anima.core.events import DETECTED, VOCABULARY

    names = set(DETECTED) | {"close eyes"}  # ("neutral" names other things too: a pose, a face)
    found = {}
    for path in sorted(PKG.rglob("*.py")):
        rel = str(path.relative_to(PKG))
        if rel in OWN_WORDS:
            continue
        hits = _event_literals(ast.parse(path.read_text()), names)
        if hits:
            found[rel] = sorted(hits)
    assert found == {}
    assert sum("raise eyebrows" in p.read_text() for p in PKG.rglob("*.py")) <= 2
    # every table the parts read is the vocabulary's
    from anima.dataset import attributes, describe
    from anima.text2face import compose, prompt

    assert attributes.ATTRIBUTES == list(DETECTED)
    assert set(prompt.LEXICON) == {n for n, e in VOCABULARY.items() if e.parsed}
    assert compose.CHANNELS == {n: e.channels for n, e in VOCABULARY.items() if e.channels}
    assert describe.VERBS == {n: e.verbs for n, e in VOCABULARY.items() if e.verbs}


def test_the_vocabulary_rule_catches_a_spelled_event():
    tree = ast.parse('if e.attribute == "raise eyebrows" or e.pose == "wink":\n    x = {"mouth open": 1}\n')
    assert _event_literals(tree, {"raise eyebrows", "mouth open"}) == {"raise eyebrows", "mouth open"}


def test_options_come_from_configs():
    """A command's options are declared as dataclass fields (a feature's config, or the command's own
    arguments in its cli module) and generated by anima/cli/options.py; at most 40 hand-written add_argument
    calls are left in anima/cli (the generator's own excluded)."""
    calls = 0
    for f in (PKG / "cli").glob("*.py"):
        if f.name == "options.py":
            continue
        tree = ast.parse(f.read_text())
        calls += sum(
            isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute) and n.func.attr == "add_argument"
            for n in ast.walk(tree)
        )
    assert calls <= 40, calls


def test_cli_is_thin():
    main = PKG / "cli" / "main.py"
    assert len(main.read_text().splitlines()) <= 200
    for f in (PKG / "cli").glob("*.py"):
        tree = ast.parse(f.read_text())
        for node in tree.body:
            if isinstance(node, ast.FunctionDef) and node.name.startswith("cmd_"):
                n = node.end_lineno - node.lineno + 1
                assert n <= 30, f"{f.name}:{node.name} is {n} lines"


def test_nothing_loads_pickles_from_user_files():
    pat = re.compile(r"weights_only\s*=\s*False|allow_pickle\s*=\s*True")
    hits = [
        f"{p.relative_to(ROOT)}:{i}"
        for p in list(PKG.rglob("*.py")) + list((ROOT / "benchmarks").glob("*.py"))
        for i, line in enumerate(p.read_text().splitlines(), 1)
        if pat.search(line)
    ]
    assert hits == []


@pytest.mark.parametrize("args", [["check"], ["format", "--check"]], ids=["lint", "format"])
def test_ruff(args):
    r = subprocess.run(
        [sys.executable, "-m", "ruff", *args, "anima", "tests", "benchmarks", "tools"],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, (r.stdout + r.stderr)[-4000:]
