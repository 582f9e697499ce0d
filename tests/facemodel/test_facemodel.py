import numpy as np
import pytest

from anima.errors import AssetNotFound
from anima.facemodel.correspondence import ANCHORS_IBUG, ANCHORS_MP, build_correspondence, load_correspondence
from anima.facemodel.ict import N_EXPR, N_ID, import_ict_obj, region_names
from anima.io.assets import asset


def test_importer_reproduces_npz_on_upstream_objs(face_model):
    d = import_ict_obj(asset("ict-facekit/orig/FaceXModel"))
    ref = np.load(asset("ict-facekit/ict_facekit_light.npz"))
    assert np.array_equal(d["neutral"], ref["neutral"])
    assert np.array_equal(d["faces"], ref["faces"])
    assert np.array_equal(d["uvs"], ref["uvs"]) and np.array_equal(d["face_uvs"], ref["face_uvs"])
    assert np.array_equal(d["landmarks68"], ref["landmarks68"])
    names = list(ref["expr_names"])
    assert sorted(d["expr_names"]) == ["eyeBlink_L", "jawOpen", "mouthSmile_L"]
    for n, delta in zip(d["expr_names"], d["expr_deltas"]):
        assert np.allclose(delta, ref["expr_deltas"][names.index(n)], atol=1e-6), n


def test_evaluate_batched_and_linear(face_model):
    m = face_model
    assert m.id_deltas.shape[0] == N_ID and m.expr_deltas.shape[0] == N_EXPR
    rng = np.random.default_rng(0)
    ident = rng.normal(size=(2, 3, N_ID)).astype(np.float32)
    expr = rng.uniform(0, 1, size=(2, 3, N_EXPR)).astype(np.float32)
    V = m.vertices(ident, expr)
    assert V.shape == (2, 3, m.n_vertices, 3)
    one = m.vertices(ident[1, 2], expr[1, 2])
    assert np.allclose(V[1, 2], one, atol=1e-4)
    j = m.expr_names.index("jawOpen")
    e = np.zeros(N_EXPR, np.float32)
    e[j] = 1
    chin = m.landmarks68[8]
    assert m.vertices(None, e)[chin, 1] < m.neutral[chin, 1] - 0.5  # jaw opens downwards (+y is up)
    with pytest.raises(ValueError):
        m.vertices(np.zeros(5))


def test_regions_and_skin_subset(face_model):
    m = face_model
    for r in region_names():
        idx = m.region(r)
        assert len(idx) > 0 and idx.max() < m.n_vertices, r
    mouth = m.region("mouth")
    assert set(m.landmarks68[48:68]).issubset(set(mouth))
    skin = m.skin()
    assert skin.n_vertices == 11248 and skin.faces.max() < skin.n_vertices
    assert np.allclose(skin.neutral[skin.landmarks68], m.neutral[m.landmarks68])


def test_correspondence_artifact_is_dense_and_close(face_model):
    c = load_correspondence()
    assert c.vertex_ids.shape == (478, 3) and c.valid.sum() >= 470
    assert np.allclose(c.bary.sum(1), 1, atol=1e-5)
    assert c.dist_cm[c.valid].mean() < 0.15  # sub-2 mm surface agreement after non-rigid ICP
    # anchors: MediaPipe eye corners / nose / mouth corners / chin land near the iBUG vertices
    P = np.einsum("kcd,kc->kd", face_model.neutral[c.vertex_ids[ANCHORS_MP]], c.bary[ANCHORS_MP])
    d = np.linalg.norm(P - face_model.neutral[face_model.landmarks68[ANCHORS_IBUG]], axis=1)
    assert d.mean() < 1.0, d


def test_correspondence_rebuild_is_deterministic(face_model):
    """Rebuilding from the stored template lands on the same surface points (within 0.5 mm)."""
    c = load_correspondence()
    c2 = build_correspondence(c.template.astype(np.float64), face_model)
    P = np.einsum("kcd,kc->kd", face_model.neutral[c.vertex_ids], c.bary)
    P2 = np.einsum("kcd,kc->kd", face_model.neutral[c2.vertex_ids], c2.bary)
    assert np.median(np.linalg.norm(P - P2, axis=1)) < 0.05


def test_missing_asset_names_upstream(monkeypatch, tmp_path):
    monkeypatch.setenv("ANIMA_DATA", str(tmp_path))
    with pytest.raises(AssetNotFound, match="ICT-VGL/ICT-FaceKit"):
        asset("ict-facekit/ict_facekit_light.npz")


def test_face_model_cache_is_made_once_and_maps_the_same_arrays(tmp_path, monkeypatch):
    """The first load inflates the npz and writes the memory-mapped cache; the next maps it and holds the same
    model; a cache that cannot be written falls back to the npz."""
    from anima.facemodel.ict import _from_arrays, _mapped_arrays, _npz_arrays

    p = asset("ict-facekit/ict_facekit_light.npz")
    monkeypatch.setenv("ANIMA_HOME", str(tmp_path / "home"))
    first = _mapped_arrays(p)
    (folder,) = (tmp_path / "home" / "cache" / "face_model").iterdir()
    assert (folder / "complete").is_file() and not list(folder.parent.glob(".tmp-*"))
    second = _mapped_arrays(p)
    assert isinstance(second["id_deltas"], np.memmap)
    ref = _npz_arrays(p)
    assert set(second) == set(ref) == set(first)
    for k in ref:
        np.testing.assert_array_equal(np.asarray(second[k]), ref[k])
    m = _from_arrays(second)
    assert m.expr_names == _from_arrays(ref).expr_names and m.vertex_indices == _from_arrays(ref).vertex_indices
    (tmp_path / "ro").write_text("a file where the cache folder would go")
    monkeypatch.setenv("ANIMA_HOME", str(tmp_path / "ro"))
    np.testing.assert_array_equal(_mapped_arrays(p)["neutral"], ref["neutral"])
