"""Packaging: every library anima imports is declared in pyproject.toml (the core install or an extra), the core
commands run without the extras, and a command whose extra is missing says which to install (exit 3)."""

import ast
import json
import re
import subprocess
import sys
import tomllib
from importlib.metadata import packages_distributions
from pathlib import Path

import pytest

from anima.errors import EXTRAS
from anima.io.sequence import write_sequence

ROOT = Path(__file__).resolve().parents[1]
BLENDER = {"bpy", "bmesh", "bpy_extras", "io_scene_fbx", "mathutils"}  # Blender's own, inside Blender only
NOT_INSTALLED = {"open_clip": "open-clip-torch"}  # optional, not installed by ./dev setup
HEAVY = ("torch", "ray", "mediapipe", "sentence_transformers", "transformers", "pyarrow", "matplotlib", "librosa")


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _req_name(req: str) -> str:
    return _norm(re.split(r"[\[=<>~!; ]", req, maxsplit=1)[0])


def _declared() -> tuple[set[str], dict[str, set[str]]]:
    """``(core distributions, {extra: distributions, self-references expanded})``."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    raw = project["optional-dependencies"]

    def expand(extra: str, seen=()) -> set[str]:
        out = set()
        for r in raw[extra]:
            if _req_name(r) == "anima":
                for e in re.search(r"\[(.*)\]", r).group(1).split(","):
                    if e.strip() not in seen:
                        out |= expand(e.strip(), (*seen, extra))
            else:
                out.add(_req_name(r))
        return out

    return {_req_name(r) for r in project["dependencies"]}, {e: expand(e) for e in raw}


def _third_party_imports() -> dict[str, set[str]]:
    std = set(sys.stdlib_module_names)
    out: dict[str, set[str]] = {}
    for f in (ROOT / "anima").rglob("*.py"):
        for n in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
            names = [a.name for a in n.names] if isinstance(n, ast.Import) else []
            if isinstance(n, ast.ImportFrom) and n.level == 0 and n.module:
                names = [n.module]
            for m in names:
                top = m.split(".")[0]
                if top not in std and top != "anima" and top not in BLENDER:
                    out.setdefault(top, set()).add(str(f.relative_to(ROOT)))
    return out


def test_every_import_is_declared_and_the_heavy_ones_are_extras():
    core, extras = _declared()
    dists = packages_distributions()
    every = core.union(*extras.values())
    undeclared = {}
    for mod, files in _third_party_imports().items():
        names = {_norm(d) for d in dists.get(mod, [])} or {_norm(NOT_INSTALLED.get(mod, mod))}
        if not names & every:
            undeclared[mod] = sorted(files)
    assert undeclared == {}, f"imported but not in pyproject.toml: {undeclared}"
    heavy = {_norm(d) for m in HEAVY for d in dists.get(m, [m])}
    assert not core & heavy, f"the core install pulls {core & heavy}"
    assert extras["all"] >= set().union(*(v for k, v in extras.items() if k not in ("all", "clip")))


def test_the_missing_library_messages_name_an_extra_that_installs_it():
    _, extras = _declared()
    dists = packages_distributions()
    for mod, extra in EXTRAS.items():
        names = {_norm(d) for d in dists.get(mod, [])} or {_norm(NOT_INSTALLED.get(mod, mod))}
        assert names & extras[extra], f"{mod}: the message says anima[{extra}], which does not install it"


# A Python with the extras' libraries hidden, as in an environment with the core install only.
WITHOUT_EXTRAS = f"""
import importlib.abc, json, sys
BLOCKED = {sorted(set(EXTRAS))!r}
class Hidden(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
sys.meta_path.insert(0, Hidden())
from anima.cli.main import main
def rc(argv):
    try:
        return main(argv)
    except SystemExit as e:  # --help
        return e.code
rcs = [rc(argv) for argv in json.loads(sys.argv[1])]
print("RESULT", json.dumps({{"rcs": rcs, "loaded": sorted({{m.split(".")[0] for m in sys.modules}} & set(BLOCKED))}}))
"""


def _without_extras(*commands: list) -> tuple[dict, str]:
    r = subprocess.run(
        [sys.executable, "-c", WITHOUT_EXTRAS, json.dumps([[str(a) for a in c] for c in commands])],
        capture_output=True, text=True, timeout=600, cwd=ROOT,
    )  # fmt: skip
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr[-3000:]
    last = [x for x in r.stdout.splitlines() if x.startswith("RESULT ")]
    assert last, (r.stdout[-2000:], r.stderr[-2000:])
    return json.loads(last[-1].removeprefix("RESULT ")), r.stderr


@pytest.mark.slow
def test_core_commands_run_without_the_extras(d0_path, tmp_path):
    """A BVH, a glTF avatar and ``anima info`` from a real capture.npz (made here, with every library) with torch,
    Ray, MediaPipe, PyArrow and the text encoders unimportable."""
    from anima.capture.config import CaptureConfig
    from anima.capture.pipeline import capture_video

    seq = capture_video(str(d0_path), CaptureConfig(max_frames=30), progress=False)
    npz = write_sequence(seq, tmp_path / "capture.npz")
    out, err = _without_extras(
        ["export", "bvh", npz, "--out", tmp_path / "a.bvh"],
        ["export", "avatar", npz, "--out", tmp_path / "a.glb"],
        ["info", npz, "--json"],
        ["capture", "--help"],
    )
    assert out["rcs"] == [0, 0, 0, 0], err[-2000:]
    assert out["loaded"] == []
    assert (tmp_path / "a.bvh").read_text().startswith("HIERARCHY") and (tmp_path / "a.glb").stat().st_size > 0


def test_a_command_whose_extra_is_missing_names_it(d0_path, tmp_path):
    out, err = _without_extras(["capture", d0_path, "--out", tmp_path / "c", "--max-frames", "5"])
    assert out["rcs"] == [3], err
    line = [x for x in err.splitlines() if x.startswith("anima: error:")]
    assert len(line) == 1 and "mediapipe" in line[0] and "pip install 'anima[capture]'" in line[0], err
    assert not (tmp_path / "c").exists() or not any((tmp_path / "c").iterdir())
