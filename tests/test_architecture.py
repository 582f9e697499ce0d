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
