"""The character's morph targets as every file anima writes carries them: ARKit's 52 names (``eyeBlinkLeft`` ...
``tongueOut``) in ``avatar.glb`` and the ``.vrm`` (and so the FBX, converted from ``avatar.glb``), made from its
53 ICT-named morphs by the one table (``anima.io.arkit.arkit_sources``), and animated with the weights
``arkit.csv`` carries, every channel."""

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from anima.core.contract import EXPR_NAMES
from anima.facemodel.character import (
    TONGUE_JAW,
    TONGUE_OUT_M,
    arkit_dense,
    arkit_morphs,
    load_character,
    to_arkit,
    tongue_vertices,
)
from anima.io.arkit import ARKIT_NAMES, LIVE_LINK_COLUMNS, arkit_sources, read_live_link_csv
from anima.io.gltf_read import read_gltf

REPO = Path(__file__).resolve().parents[2]
TOLERANCE = 0.02


@pytest.fixture(scope="module")
def d0_files(d0_capture, tmp_path_factory):
    """The d0 capture written as a capture writes it: ``capture.npz`` read back, ``avatar.glb``, the ``.vrm`` of
    ``anima export avatar --out x.vrm`` and ``arkit.csv``."""
    from anima.export.avatar import write_avatar
    from anima.export.formats import export_arkit_csv
    from anima.io.sequence import read_sequence, write_sequence

    d = tmp_path_factory.mktemp("arkit_morphs")
    seq = read_sequence(write_sequence(d0_capture, d / "capture.npz"))
    write_avatar(seq, d / "avatar.glb")
    write_avatar(seq, d / "x.vrm")
    export_arkit_csv(seq, d / "arkit.csv")
    return d


def _morphs(path: Path) -> tuple[list[str], np.ndarray]:
    """The character mesh's morph target names and its animated weights ``[F, 52]``."""
    g = read_gltf(path)
    (node, _), (_, w) = next((k, v) for k, v in g.animation(0).items() if k[1] == "weights")
    return list(g.doc["meshes"][g.nodes[node]["mesh"]]["extras"]["targetNames"]), w


def _differences(d: Path) -> dict[str, float]:
    """Per ARKit channel, the largest difference over the clip between ``avatar.glb``'s morph weight and
    ``arkit.csv``'s column."""
    names, w = _morphs(d / "avatar.glb")
    cols, csv = read_live_link_csv(d / "arkit.csv")
    assert len(w) == len(csv)
    return {a: float(np.abs(w[:, names.index(a)] - csv[:, cols.index(c)]).max()) for a, c in zip(ARKIT_NAMES,
            LIVE_LINK_COLUMNS)}  # fmt: skip


def test_the_files_morph_targets_are_arkits_52_names(d0_files):
    """``avatar.glb`` and the ``.vrm`` carry exactly ARKit's 52 names (lower camelCase, as Apple names them), the
    glTF still valid (Khronos validator); the VRM's expression presets bind the morphs of their names."""
    for f in ("avatar.glb", "x.vrm"):
        names, w = _morphs(d0_files / f)
        assert sorted(names) == sorted(ARKIT_NAMES) and len(names) == 52, f
        assert {"eyeBlinkLeft", "browInnerUp", "cheekPuff", "tongueOut", "mouthSmileRight"} <= set(names)
        assert w.shape[1] == 52 and np.isfinite(w).all()
        r = subprocess.run([shutil.which("node"), str(REPO / "tools" / "validate_gltf.js"), str(d0_files / f)],
                           capture_output=True, text=True, timeout=300, cwd=REPO)  # fmt: skip
        report = json.loads(r.stdout)
        assert report["issues"]["numErrors"] == 0, (f, report["issues"]["messages"][:5])
    g = read_gltf(d0_files / "x.vrm")
    names = _morphs(d0_files / "x.vrm")[0]
    preset = g.vrm["expressions"]["preset"]
    bound = {p: sorted(names[b["index"]] for b in e["morphTargetBinds"]) for p, e in preset.items()}
    assert bound["blink"] == ["eyeBlinkLeft", "eyeBlinkRight"] and bound["aa"] == ["jawOpen"]
    assert bound["happy"] == ["mouthSmileLeft", "mouthSmileRight"] and bound["ou"] == ["mouthPucker"]


def test_the_arkit_morphs_are_made_from_the_characters_own():
    """Each ARKit morph is its ICT morph; browInnerUp and cheekPuff the two halves' deltas summed (driven by their
    mean weight, as ``arkit.csv`` averages them); tongueOut brings the tongue's tip out past the lips."""
    ch = load_character()
    D53, D52 = ch.morph_dense(), arkit_dense()
    for k, (a, src) in enumerate(zip(ARKIT_NAMES, arkit_sources(EXPR_NAMES))):
        if a != "tongueOut":
            np.testing.assert_allclose(D52[k], D53[src].sum(0), atol=1e-6, err_msg=a)
            assert len(src) == (2 if a in ("browInnerUp", "cheekPuff") else 1), a
    W = np.zeros((1, 53))
    W[0, [EXPR_NAMES.index("browInnerUp_L"), EXPR_NAMES.index("browInnerUp_R")]] = 0.6
    W[0, EXPR_NAMES.index("eyeBlink_L")] = 0.3
    A = to_arkit(W)
    np.testing.assert_allclose(A @ D52.reshape(52, -1), W @ D53.reshape(53, -1), atol=1e-6)  # a symmetric face
    assert A[0, ARKIT_NAMES.index("browInnerUp")] == pytest.approx(0.6) and A[0, -1] == 0.0
    # tongueOut: the tongue (MakeHuman's, in the body's mesh, the piece the jaw moves), its tip well out
    T = tongue_vertices()
    i, d = arkit_morphs()[0][-1], arkit_morphs()[1][-1]
    assert ARKIT_NAMES[-1] == "tongueOut" and np.isin(T, i).all() and len(T) > 100
    V = ch.vertices
    tip = T[np.argmax(V[T, 2])]
    moved = V[tip] + dict(zip(i.tolist(), d))[int(tip)]
    lips = V[: ch.n_body][np.abs(V[: ch.n_body, 0]) < 0.01]
    lips = lips[(np.abs(lips[:, 1] - V[tip, 1]) < 0.02)][:, 2].max()  # the face's front around the mouth
    assert moved[2] - V[tip, 2] > 0.5 * TONGUE_OUT_M and moved[2] > lips + 0.01, (moved, lips)
    beyond = D52[-1] - TONGUE_JAW * D53[EXPR_NAMES.index("jawOpen")]  # all but the jaw's share: the tongue's own
    assert np.isin(np.flatnonzero(np.abs(beyond).max(1) > 1e-6), T).all()


def test_the_morph_animation_is_arkit_csv(d0_files):
    """On a real clip (d0), every one of the 52 channels of the character's face (``avatar.glb``, the ``.vrm``)
    moves as ``arkit.csv``'s column does, within 0.02: the lids, brows and lips the landmarks set included, so
    what the character shows is what a user's rig gets."""
    diff = _differences(d0_files)
    print("max |avatar.glb - arkit.csv| per channel:", {a: round(v, 3) for a, v in sorted(diff.items(),
          key=lambda x: -x[1])})  # fmt: skip
    far = {a: round(diff[a], 3) for a in ARKIT_NAMES if diff[a] > TOLERANCE}
    assert not far, far
    names, w = _morphs(d0_files / "avatar.glb")
    names_v, w_v = _morphs(d0_files / "x.vrm")
    np.testing.assert_allclose(w_v[:, [names_v.index(n) for n in names]], w, atol=1e-3)
