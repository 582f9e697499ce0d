"""The layers of anima and the import rule, in one place (explained in docs/architecture.md; enforced by
tests/test_architecture.py, which walks ``anima/`` with ``ast``).

A module may import from its own package or from a package of a *lower* layer; never upwards, never
sideways between two packages of the same layer (the feature packages do not know each other). Internal
imports sit at module top; a function-level internal import is allowed only when its target is *heavy*
(loads torch, MediaPipe, Ray, matplotlib or a sentence encoder when imported), so that light commands and
``--help`` stay fast.
"""

from __future__ import annotations

import ast
from pathlib import Path

LAYERS: dict[str, int] = {
    "errors": 0,
    "architecture": 0,
    "core": 0,  # pure maths, conventions, the data contract
    "io": 1,  # files: assets, artifacts, checkpoints, writers
    "track": 1,  # trackers: the models that find faces, bodies and hands in frames (MediaPipe)
    "facemodel": 2,
    "audio": 2,  # models of data: the face model, speech features
    "render": 3,
    "pose3d": 3,  # renderers; the 2D->3D lifter (used by capture)
    "export": 4,  # motion to files (the one motion writer)
    "capture": 5,  # stage: video -> tracked sequence
    "dataset": 6,  # stage: tracked sequences -> training pairs
    "library": 6,  # the built-in motion library (data the features use when no dataset is given)
    "text2face": 7,
    "gesture": 7,
    "reenact": 7,
    "view": 7,  # features (independent of each other)
    "live": 8,  # real time: a live source tracked into the page, Live Link, VMC, a take; live re-enactment
    "eval": 8,  # metrics and evaluation runners
    "studio": 8,  # the local web app: jobs run by the commands of the features, their results in the viewer
    "cli": 9,
    "__main__": 10,  # the command line, and `python -m anima`
}
HEAVY_THIRD_PARTY = (
    "torch",
    "mediapipe",
    "ray",
    "matplotlib",
    "sentence_transformers",
    "transformers",
    "open_clip",
    "pyarrow",  # 0.1 s: the gesture command reads its database from a memory-mapped cache, not Arrow
)


def package_of(module: str) -> str:
    """``anima.capture.fit`` -> ``capture``; ``anima`` -> ``anima`` (the root: version only)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "anima"


def layer_of(module: str) -> int:
    pkg = package_of(module)
    return -1 if pkg == "anima" else LAYERS[pkg]


def modules(root: Path) -> dict[str, Path]:
    """``{dotted name: path}`` of every module under ``root`` (the ``anima`` folder)."""
    out = {}
    for f in sorted(root.rglob("*.py")):
        rel = f.relative_to(root.parent).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = f
    return out


def imports(path: Path) -> list[tuple[str, int, bool, str]]:
    """``(imported module, line, at module top, first imported name)`` for every ``anima`` import in ``path``
    (``from anima.x import y`` names module ``anima.x.y`` when that is a module, else ``anima.x``)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    top = {id(n) for n in tree.body}
    out = []
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.ImportFrom)
            and node.module
            and node.level == 0
            and (node.module == "anima" or node.module.startswith("anima."))
        ):
            for a in node.names:
                out.append((node.module, node.lineno, id(node) in top, a.name))
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name == "anima" or a.name.startswith("anima."):
                    out.append((a.name, node.lineno, id(node) in top, ""))
    return out


def third_party_top(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = set()
    for node in tree.body:
        if isinstance(node, ast.Import):
            out |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.add(node.module.split(".")[0])
    return out


def resolve(target: str, name: str, known: dict[str, Path]) -> str:
    return f"{target}.{name}" if f"{target}.{name}" in known else target


def heavy_modules(root: Path) -> set[str]:
    """Modules that load a heavy third-party library when imported (directly or through their top-level
    internal imports)."""
    known = modules(root)
    heavy = {m for m, p in known.items() if third_party_top(p) & set(HEAVY_THIRD_PARTY)}
    deps = {m: {resolve(t, n, known) for t, _, top, n in imports(p) if top} for m, p in known.items()}
    changed = True
    while changed:
        changed = False
        for m, ds in deps.items():
            if m not in heavy and ds & heavy:
                heavy.add(m)
                changed = True
    return heavy


def violations(root: Path) -> list[str]:
    """Every import that breaks the rule, as ``file:line: reason``."""
    known = modules(root)
    heavy = heavy_modules(root)
    out = []
    for mod, path in known.items():
        src_pkg, src_layer = package_of(mod), layer_of(mod)
        for target, line, top, name in imports(path):
            tgt = resolve(target, name, known)
            pkg, layer = package_of(tgt), layer_of(tgt)
            where = f"{path.relative_to(root.parent)}:{line}"
            if pkg != src_pkg and pkg != "anima":
                if layer > src_layer:
                    out.append(f"{where}: {src_pkg} (layer {src_layer}) imports {tgt} from a higher layer ({layer})")
                elif layer == src_layer:
                    out.append(f"{where}: {src_pkg} imports {tgt} sideways (both layer {layer})")
            if not top and tgt not in heavy:
                out.append(f"{where}: function-level import of {tgt}, which is light: import it at module top")
    return out
