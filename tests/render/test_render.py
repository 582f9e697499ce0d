"""Renders: the rasterizer's banded (multi-threaded) pass against the single pass and both against the plain
rule, the fused shaded-mesh kernel against raster + compose, the preview head's level of detail on the ICT
head, the avatar preview's framing on a real capture and on a real jump, and the video writer's colours (RGB
converted to YUV 4:2:0 before the pipe)."""

import numpy as np
import pytest

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
    from anima.io.video import VideoWriter, read_video, to_i420

    frames, info = read_video(asset("liveportrait-examples/assets/examples/driving/d0.mp4"), max_frames=8)
    with VideoWriter(tmp_path / "v.mp4", info.fps, (frames.shape[2], frames.shape[1])) as w:
        for f in frames:
            w.write(f)
        with pytest.raises(ValueError, match="I420"):  # a frame of another size is refused, not mis-encoded
            w.write_i420(to_i420(frames[0][:-2], (frames.shape[2], frames.shape[1] - 2)))
    back, _ = read_video(tmp_path / "v.mp4")
    assert back.shape == frames.shape
    diff = back.astype(np.float64) - frames
    assert np.abs(diff).mean() < 3.0 and np.abs(diff.mean((0, 1, 2))).max() < 2.0  # no colour or level shift


def _reference_raster(uvz, tris, colors, size):
    """The rasterizer's rule written plainly in numpy, one triangle at a time in the given order: every pixel
    centre of the triangle's box with all three barycentric weights >= 0, nearest depth wins."""
    W, H = size
    img = np.zeros((H, W, colors.shape[1]), np.float32)
    zbuf = np.full((H, W), -np.inf)
    for i0, i1, i2 in tris:
        (x0, y0, z0), (x1, y1, z1), (x2, y2, z2) = uvz[i0], uvz[i1], uvz[i2]
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if abs(area) < 1e-12:
            continue
        xa, xb = max(int(np.floor(min(x0, x1, x2))), 0), min(int(np.ceil(max(x0, x1, x2))), W - 1)
        ya, yb = max(int(np.floor(min(y0, y1, y2))), 0), min(int(np.ceil(max(y0, y1, y2))), H - 1)
        if xa > xb or ya > yb:
            continue
        px, py = np.meshgrid(np.arange(xa, xb + 1) + 0.5, np.arange(ya, yb + 1) + 0.5)
        w0 = ((y1 - y2) * px + (x2 - x1) * py + (x1 * y2 - x2 * y1)) / area
        w1 = ((y2 - y0) * px + (x0 - x2) * py + (x2 * y0 - x0 * y2)) / area
        w2 = 1.0 - w0 - w1
        z = w0 * z0 + w1 * z1 + w2 * z2
        ys, xs = np.nonzero((w0 >= 0) & (w1 >= 0) & (w2 >= 0))
        for y, x in zip(ys, xs):  # in order: a later triangle at the same depth does not win
            if z[y, x] > zbuf[ya + y, xa + x]:
                zbuf[ya + y, xa + x] = z[y, x]
                img[ya + y, xa + x] = w0[y, x] * colors[i0] + w1[y, x] * colors[i1] + w2[y, x] * colors[i2]
    return img, np.isfinite(zbuf)


def test_raster_matches_the_plain_rule_on_the_preview_head():
    """Small triangles (the preview head: boxes of a few pixels, tested whole) and large ones (the same head
    30x bigger: spans per row) give the pixels of the plain rule."""
    skin, V, tris = _head()
    hv, ht, _ = decimate_morph_mesh(V, tris, np.zeros((1, *V.shape)), 1500)
    for scale, size in ((4.0, (90, 120)), (30.0, (400, 300))):
        X = (hv - hv.mean(0)) * scale
        uvz = np.stack([X[:, 0] + size[0] / 2, size[1] / 2 - X[:, 1], X[:, 2]], -1)
        col = shade(X, ht).astype(np.float32)
        img, mask, _ = raster.rasterize(uvz, ht, col, size)
        ref, ref_mask = _reference_raster(uvz, ht, col, size)
        assert mask.sum() > 3000
        np.testing.assert_array_equal(mask, ref_mask)
        np.testing.assert_allclose(img, ref, atol=1e-5)


def test_draw_shaded_equals_raster_then_compose():
    """The fused kernel of the avatar preview draws the pixels of ``compose(raster_mesh(...))``, into a view of
    a larger canvas; without back faces it differs only where the head's open eye sockets showed their
    inside, and is cheaper."""
    from anima.render.face import SKIN, compose

    skin, V, tris = _head()
    hv, ht, _ = decimate_morph_mesh(V, tris, np.zeros((1, *V.shape)), 4000)
    for yaw in (0.0, -1.0):
        c, s = np.cos(yaw), np.sin(yaw)
        X = (hv - hv.mean(0)) @ np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]).T * 4.0 + [150.0, -70.0, 0.0]
        for back in (True, False):
            canvas = np.full((140, 500, 3), 28, np.uint8)
            want = compose(raster_mesh(X, ht, (250, 140), back_faces=back), (250, 140), canvas[:, 250:].copy())
            raster.draw_shaded(canvas[:, 250:], X, ht, SKIN, back_faces=back)
            np.testing.assert_array_equal(canvas[:, 250:], want)
            assert (canvas[:, :250] == 28).all()  # nothing outside the view
        both = compose(raster_mesh(X, ht, (250, 140)), (250, 140))
        front = compose(raster_mesh(X, ht, (250, 140), back_faces=False), (250, 140))
        assert 0 < (both != front).any(-1).sum() < 0.02 * (both != 24).any(-1).sum()


def _inside_every_view(V, yaws, scale, height, views, margin):
    """Each view's pixels of the points ``V [..., 3]`` (every frame's vertices) as :func:`render_character_video`
    places them: all at least ``margin`` pixels inside the view and under the label's rows."""
    from anima.render.avatar import LABEL_PX, _view

    for yaw, (centre, x0, w, y0) in zip(yaws, views):
        X = _view(np.asarray(V).reshape(-1, 3), 512, yaw, centre, scale, (x0, y0))
        col, row = X[:, 0], -X[:, 1]
        assert col.min() >= margin - 1 and col.max() <= w - margin + 1, (yaw, col.min(), col.max(), w)
        assert row.min() >= LABEL_PX + margin - 1 and row.max() <= height - margin + 1, (yaw, row.min(), row.max())


def test_avatar_preview_frames_the_figure_on_real_motion(tmp_path):
    """The preview of a real capture (a TED-style gesture clip) draws the skinned character: each view is cropped
    to where the figure moves, every vertex of every frame stays inside its view, the figure keeps its size (512
    pixels for 2.1 m), the body is drawn there (a tall figure in each view), and the video has that size and the
    speech."""
    from anima.capture.config import CaptureConfig
    from anima.capture.run import run as capture
    from anima.core import rig
    from anima.export.avatar import character_motion
    from anima.facemodel.character import load_character, skin
    from anima.io.assets import asset
    from anima.io.sequence import read_sequence
    from anima.io.video import probe_video, read_video
    from anima.render.avatar import figure_bounds, framing

    clip = asset("gesture-video/tango-interviews/speaker8_jjRWaMCWs44_00-00-30.16_00-00-33.32.mp4")
    capture(clip, tmp_path / "c", CaptureConfig(max_frames=24), progress=False)
    seq = read_sequence(tmp_path / "c" / "capture.npz")
    m, ch = character_motion(seq), load_character()
    P = m["positions"]
    posed = lambda f0, f1: skin(m["vertices"], m["rest"], m["global"][f0:f1], P[f0:f1], ch)
    yaws = (0.0, np.deg2rad(-60))
    scale, height, views = framing(figure_bounds(posed, len(P), yaws, P, rig.HEAD, 0.16), yaws, 512, margin=20)
    assert scale == pytest.approx(512 / 2.1)  # a person who stays on the floor: the figure at its size
    assert height <= 512 and sum(w for _, _, w, _ in views) < 1024  # smaller than two full squares
    _inside_every_view(posed(0, len(P)), yaws, scale, height, views, 20)
    info = probe_video(tmp_path / "c" / "avatar.mp4")
    assert info.has_audio and info.n_frames == 24 and info.height <= 512 and info.width < 1024
    frames, _ = read_video(tmp_path / "c" / "avatar.mp4", max_frames=1)
    drawn = np.abs(frames[0].astype(int) - 28).max(-1) > 30
    w0, w1 = views[0][2], views[1][2]
    for x0, x1 in ((0, w0), (w0, w0 + w1)):  # a standing figure in each view
        ys, xs = np.nonzero(drawn[40:, x0 : min(x1, drawn.shape[1])])
        assert len(ys) > 5000 and np.ptp(ys) > 0.7 * (drawn.shape[0] - 40) and np.ptp(ys) > 1.5 * np.ptp(xs)


def test_avatar_preview_keeps_a_jump_whole_in_every_frame(tmp_path):
    """A real jump (CMU's "jumping_5" on the character, as ``benchmarks/roundtrip_body.py`` puts it: the hips
    rise half a metre, the arms swing up) in ``avatar.mp4``'s views: the figure's course is taller than the
    2.1 m the views show a person standing in, and on every frame every vertex of the skinned character (head,
    hands, feet) lands inside its view, 20 pixels or more from its edges and under the label's rows; in the
    video, on the jump's highest frame, the figure is drawn whole (no drawn pixel on a view's edge)."""
    import sys
    from pathlib import Path

    from anima.core import rig
    from anima.facemodel.character import skin, vertex_colors
    from anima.io.video import read_video
    from anima.render.avatar import LABEL_PX, figure_bounds, framing, render_character_video

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    from roundtrip_body import clip, truth_motion

    m = truth_motion(clip("cmu", "train/jumping/jumping_5", 0.0, 30.0), 25.0)
    ch, P = m["ch"], m["positions"]
    F = len(P)
    posed = lambda f0, f1: skin(m["vertices"], m["rest"], m["global"][f0:f1], P[f0:f1], ch)
    V = posed(0, F)
    hips = P[:, rig.HIPS, 1]
    assert hips.max() - np.median(hips) > 0.3  # a jump
    assert V[..., 1].max() - V[..., 1].min() > 2.1  # its course would not fit the views at the figure's size
    yaws = (0.0, np.deg2rad(-60))
    scale, height, views = framing(figure_bounds(posed, F, yaws, P, rig.HEAD, 0.16), yaws, 512, margin=20)
    assert 0.6 * 512 / 2.1 < scale < 512 / 2.1 and height <= 512
    _inside_every_view(V, yaws, scale, height, views, 20)
    render_character_video(tmp_path / "jump.mp4", 25.0, P, rig.HEAD, posed, ch.faces, colors=vertex_colors())
    frames, _ = read_video(tmp_path / "jump.mp4")
    assert frames.shape[1] == height and frames.shape[2] >= sum(w for _, _, w, _ in views)
    top = frames[int(np.argmax(V[..., 1].max(-1)))]  # the frame where the figure reaches highest
    x = 0
    for _, _, w, _ in views:
        view = top[:, x : x + w].astype(int)
        drawn = np.abs(view - 28).max(-1) > 30
        skin_tone = drawn & (view[..., 0] - view[..., 2] > 25)  # the figure, not the label's grey letters
        assert drawn.sum() > 3000 and not skin_tone[:LABEL_PX].any()
        assert not drawn[-4:].any() and not drawn[:, :4].any() and not drawn[:, -4:].any()
        x += w


def test_avatar_body_views_at_their_level_of_detail_look_the_same(captures):
    """``avatar.mp4``'s front and 3/4 views draw the character decimated to ``BODY_VIEW_TRIANGLES`` (cluster
    means of the posed mesh and its colours): on a real capture's frames, drawn as the preview draws them, the
    figure's silhouette and its colours agree with the full mesh's (IoU >= 0.97, mean colour within 7 of 255
    where both draw)."""
    from anima.export.avatar import BODY_VIEW_TRIANGLES, character_motion
    from anima.facemodel.character import load_character, skin, vertex_colors
    from anima.render.avatar import _view
    from anima.render.lod import cluster_mean
    from anima.render.raster import draw_shaded

    ch = load_character()
    m = character_motion(captures["oliver1"])
    A, lod_tris = cluster_mean(ch.vertices, ch.faces, BODY_VIEW_TRIANGLES)
    assert len(lod_tris) <= 1.02 * BODY_VIEW_TRIANGLES < 0.5 * len(ch.faces)
    col = vertex_colors()
    centre = np.nanmedian(m["positions"][:, 0], axis=0) + np.array([0.0, 0.05, 0.0])
    for f in (0, 45, 89):
        V = skin(m["vertices"], m["rest"], m["global"][f], m["positions"][f], ch)
        for yaw in (0.0, np.deg2rad(-60)):
            full, dec = (np.full((512, 512, 3), 28, np.uint8) for _ in range(2))
            draw_shaded(full, _view(V, 512, yaw, centre, 512 / 2.1), ch.faces, col, back_faces=False)
            draw_shaded(dec, _view(A @ V, 512, yaw, centre, 512 / 2.1), lod_tris,
                        np.ascontiguousarray(A @ col, np.float32), back_faces=False)  # fmt: skip
            a, b = (np.abs(x.astype(int) - 28).max(-1) > 0 for x in (full, dec))
            assert (a & b).sum() / (a | b).sum() >= 0.97, (f, yaw)
            # <= 7: the host sits, and the thighs' tops face the light (seated 5.9-6.5, standing under 6)
            assert np.abs(full[a & b].astype(int) - dec[a & b]).mean() <= 7, (f, yaw)


def test_draw_smooth_moves_with_an_edge_that_moves_by_less_than_a_pixel():
    """Anti-aliased drawing (supersampled twice a side): a dark square's lower edge lowered by a quarter pixel at
    a time darkens the picture every half pixel, where drawn plain it jumps a whole row at a time; supersampled
    once it is the plain drawing; pixels the square does not reach keep their value exactly."""
    from anima.render.avatar import draw_smooth

    tris = np.array([[0, 3, 2], [0, 2, 1]])  # counter-clockwise seen from the camera: the fronts
    dark = (0.1, 0.1, 0.1)

    def square(bottom):
        return np.array([[5.0, -5.0, 0.0], [35.0, -5.0, 0.0], [35.0, -bottom, 0.0], [5.0, -bottom, 0.0]])

    def darkness(bottom, n):
        img = np.full((40, 40, 3), 200, np.uint8)
        return -int(draw_smooth(img, square(bottom), tris, dark, supersample=n).astype(int).sum())

    bottoms = (20.1, 20.35, 20.6, 20.85, 21.1)  # pixel centres at 20.5 and 21.5; half-pixel ones at 20.25, 20.75
    plain = [darkness(b, 1) for b in bottoms]
    smooth = [darkness(b, 2) for b in bottoms]
    assert len(set(plain)) == 2
    assert all(a <= b for a, b in zip(smooth, smooth[1:])) and len(set(smooth)) == 3

    background = np.random.default_rng(0).integers(0, 255, (40, 40, 3), dtype=np.uint8)
    ref = background.copy()
    raster.draw_shaded(ref, square(20.3), tris, np.array(dark, np.float32), back_faces=False)
    assert (ref != background).any()
    np.testing.assert_array_equal(draw_smooth(background.copy(), square(20.3), tris, dark, supersample=1), ref)
    img = draw_smooth(background.copy(), square(20.3), tris, dark, supersample=2)
    reach = np.zeros((40, 40), bool)
    reach[5:21, 5:35] = True  # the pixels the square covers, in part or whole
    np.testing.assert_array_equal(img[~reach], background[~reach])
    assert (img[reach] != background[reach]).any(-1).all()


def test_the_close_up_draws_its_eyes_anti_aliased_and_the_rest_as_before():
    """The face close-up on the character: the box around each eye (its eyeball and lashes) is the whole
    close-up drawn anti-aliased, there; everywhere else the plain drawing, pixel for pixel."""
    from anima.facemodel.character import eye_vertices, load_character, vertex_colors
    from anima.render.avatar import SMOOTH_MARGIN, draw_close_up, draw_smooth, head_view

    ch = load_character()
    V = ch.vertices.astype(np.float64)
    eyes = eye_vertices()
    assert len(eyes) == 2 and all(len(e) > 50 for e in eyes)
    assert V[eyes[0], 0].min() > V[eyes[1], 0].max()  # one eye each side
    tris = np.asarray(ch.faces, np.int64)
    col = vertex_colors()
    centre = V[np.concatenate(eyes)].mean(0) - [0.0, 0.03, 0.0]
    size = 256
    plain, whole, eyes_only = (np.full((size, size, 3), 28, np.uint8) for _ in range(3))
    draw_close_up(plain, V, np.eye(3), centre, tris, col, smooth=[])
    draw_close_up(whole, V, np.eye(3), centre, tris, col)
    draw_close_up(eyes_only, V, np.eye(3), centre, tris, col, smooth=eyes)
    X = head_view(V, size, np.eye(3), centre, size / 0.30)
    raw = np.full((size, size, 3), 28, np.uint8)
    draw_smooth(raw, X, tris, col, supersample=1)
    np.testing.assert_array_equal(plain, raw)
    inside = np.zeros((size, size), bool)
    for e in eyes:
        x, y = X[e, 0], -X[e, 1]
        m = SMOOTH_MARGIN
        inside[int(np.floor(y.min())) - m : int(np.ceil(y.max())) + m + 1,
               int(np.floor(x.min())) - m : int(np.ceil(x.max())) + m + 1] = True  # fmt: skip
    assert 0.01 < inside.mean() < 0.15
    np.testing.assert_array_equal(eyes_only[~inside], plain[~inside])
    same = (eyes_only[inside] == whole[inside]).all(-1)
    assert same.mean() > 0.999
    assert (whole[inside] != plain[inside]).any(-1).mean() > 0.05  # the eyes' edges are drawn otherwise
