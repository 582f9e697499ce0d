"""Renders: the rasterizer's banded (multi-threaded) pass against the single pass, the preview head's level of
detail on the ICT head, and the video writer's colours (RGB converted to YUV 4:2:0 before the pipe)."""

import numpy as np

from anima.facemodel.ict import load_face_model
from anima.render import raster
from anima.render.face import raster_mesh, shade
from anima.render.lod import decimate_morph_mesh


def _head():
    skin = load_face_model().skin()
    return skin, np.asarray(skin.neutral, np.float64), np.asarray(skin.triangles(), np.int64)


def test_banded_raster_equals_one_pass(monkeypatch):
    skin, V, tris = _head()
    X = V * 20.0 + np.array([300.0, -300.0, 0.0])  # a head about 400 px tall: above the band threshold
    uvz = np.stack([X[:, 0], -X[:, 1], X[:, 2]], -1)
    col = shade(X, tris).astype(np.float32)
    banded = raster.rasterize(uvz, tris, col, (600, 600))
    monkeypatch.setattr(raster, "BAND_MIN_PIXELS", 10**12)
    one = raster.rasterize(uvz, tris, col, (600, 600))
    assert one[1].sum() > 50_000  # the head covers the image
    for a, b in zip(banded, one):
        np.testing.assert_array_equal(a, b)


def test_preview_head_keeps_its_shape_and_its_blendshapes():
    skin, V, tris = _head()
    D = np.asarray(skin.expr_deltas, np.float64)
    names = list(skin.expr_names)
    w = np.zeros(len(D))
    w[names.index("jawOpen")] = 0.8
    hv, ht, hd = decimate_morph_mesh(V, tris, D, 4000)
    assert len(ht) <= 4100 and hd.shape == (len(D), len(hv), 3)
    full = V + np.tensordot(w, D, 1)
    dec = hv + np.tensordot(w, hd, 1)
    from scipy.spatial import cKDTree

    dist, _ = cKDTree(full).query(dec)
    assert np.percentile(dist, 95) < 0.5  # cm: every kept vertex stays on the open-mouthed head
    # drawn 90 px tall (the avatar preview), the silhouettes agree
    s, c = 90.0 / np.ptp(V[:, 1]), V.mean(0)

    def mask(P, T):
        X = (P - c) * s + np.array([60.0, -60.0, 0.0])  # the same camera for both
        return raster_mesh(X.astype(np.float32), T, (120, 120))

    a, b = mask(full, tris), mask(dec, ht)
    ma = np.zeros((120, 120), bool)
    mb = np.zeros((120, 120), bool)
    for m, r in ((ma, a), (mb, b)):
        x0, y0, w_, h_ = r[0]
        m[y0 : y0 + h_, x0 : x0 + w_] = r[2]
    assert (ma & mb).sum() / (ma | mb).sum() > 0.97
    # the mouth opened in the decimated mesh too: its lowest lip-region point moved down like the full one's
    assert abs((dec - hv)[:, 1].min() - (full - V)[:, 1].min()) < 0.3 * abs((full - V)[:, 1].min())


def test_video_writer_keeps_colours(tmp_path):
    from anima.io.assets import asset
    from anima.io.video import VideoWriter, read_video

    frames, info = read_video(asset("liveportrait-examples/assets/examples/driving/d0.mp4"), max_frames=8)
    with VideoWriter(tmp_path / "v.mp4", info.fps, (frames.shape[2], frames.shape[1])) as w:
        for f in frames:
            w.write(f)
    back, _ = read_video(tmp_path / "v.mp4")
    assert back.shape == frames.shape
    diff = back.astype(np.float64) - frames
    assert np.abs(diff).mean() < 3.0 and np.abs(diff.mean((0, 1, 2))).max() < 2.0  # no colour or level shift
