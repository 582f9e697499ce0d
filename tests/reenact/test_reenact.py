"""Re-enactment (seed 001): the maths of texture synthesis and blending, the database artifact on a real
clip, the command end to end (audio, bad inputs) and the live loop on a file paced at its frame rate."""

import json
from types import SimpleNamespace

import numpy as np
import pytest

from anima.io.assets import asset
from anima.reenact.config import ReenactConfig
from anima.reenact.pipeline import Smoother, actor_expressions
from anima.reenact.render import laplacian_blend
from anima.reenact.run import pingpong
from anima.reenact.synth import adaptive_sigma, nearest, weighted_median, weighted_median_listing1

OBAMA1 = "styletalk-samples/samples/source_video/video/Obama_clip1.mp4"
ACTOR = "videoretalking-examples/examples/face/1.mp4"


def test_adaptive_sigma_gives_the_weight_fraction():
    rng = np.random.default_rng(0)
    X = rng.random((800, 53)).astype(np.float32)
    idx, d2 = nearest(X, X[3] + 0.02, 100)
    assert idx[0] == 3 and np.all(np.diff(d2[idx]) >= 0)
    s = adaptive_sigma(d2, idx, 0.9)
    w = np.exp(-(d2 - d2.min()) / (2 * s * s))
    assert abs(w[idx].sum() / w.sum() - 0.9) < 1e-3
    # a database smaller than n / a: every frame counts, sigma is large
    idx2, d22 = nearest(X[:105], X[0], 100)
    assert adaptive_sigma(d22, idx2, 0.9) > np.sqrt(d22.max())


def test_weighted_median_fast_matches_listing1():
    rng = np.random.default_rng(1)
    N, V = 300, 500
    base = rng.integers(30, 220, (1, V, 3))
    db = np.clip(base + rng.normal(0, 15, (N, V, 3)), 0, 255).astype(np.uint8)
    idx = rng.choice(N, 100, replace=False)
    w = rng.random(100) + 0.05
    fast = weighted_median(db, idx, w)
    ref = weighted_median_listing1(db[idx].astype(np.float32), w)
    # the same definition; equal colours are merged into one rank here, ordered arbitrarily in the listing
    assert np.abs(fast - ref).max() <= 1.5 and np.abs(fast - ref).mean() < 0.5
    # one overwhelming weight: that frame's colours; equal weights: the ordinary median (odd n)
    w1 = np.full(100, 1e-6)
    w1[7] = 1.0
    np.testing.assert_allclose(weighted_median(db, idx, w1), db[idx[7]], atol=0.01)
    idx3 = idx[:99]
    eq = weighted_median(db, idx3, np.ones(99))
    lo, hi = np.percentile(db[idx3], 40, 0), np.percentile(db[idx3], 60, 0)
    assert ((eq >= lo - 1e-3) & (eq <= hi + 1e-3)).all()


def test_laplacian_blend_limits_and_smoother():
    rng = np.random.default_rng(2)
    a = rng.random((64, 48, 3)).astype(np.float32) * 255
    b = rng.random((64, 48, 3)).astype(np.float32) * 255
    np.testing.assert_allclose(laplacian_blend(a, b, np.ones((64, 48), np.float32), 4), a, atol=1e-3)
    np.testing.assert_allclose(laplacian_blend(a, b, np.zeros((64, 48), np.float32), 4), b, atol=1e-3)
    sm, out = Smoother(5), []
    for i in range(6):
        out += sm.push(np.array([float(i)]), np.array([float(i)]), i)
    out += sm.flush()
    assert [o[2] for o in out] == list(range(6))
    np.testing.assert_allclose([o[0][0] for o in out], [1.0, 1.5, 2.0, 3.0, 3.5, 4.0])
    np.testing.assert_array_equal(pingpong(np.arange(8), 4), [0, 1, 2, 3, 2, 1, 0, 1])


def test_one_pyramid_blend_equals_the_two_pyramid_blend_on_real_frames():
    """Burt & Adelson's blend, L(a) G(m) + L(b) (1 - G(m)) collapsed, written out here, against the one-pyramid
    form anima runs (b + collapse(L(a - b) G(m))) on two real frames of a clip and a feathered mask."""
    import cv2

    from anima.io.video import read_video

    frames, _ = read_video(asset(OBAMA1), max_frames=31)
    a, b = frames[0].astype(np.float32), frames[30].astype(np.float32)
    h, w = (a.shape[0] // 16) * 16, (a.shape[1] // 16) * 16
    a, b = a[:h, :w], b[:h, :w]
    m = np.zeros((h, w), np.float32)
    m[h // 3 : 2 * h // 3, w // 4 : 3 * w // 4] = 1
    m = cv2.GaussianBlur(m, (21, 21), 6)

    def two_pyramids(a, b, m, levels):
        ga, gb, gm = [a], [b], [m[..., None]]
        for _ in range(levels):
            ga.append(cv2.pyrDown(ga[-1]))
            gb.append(cv2.pyrDown(gb[-1]))
            gm.append(cv2.pyrDown(gm[-1])[..., None])
        out = ga[-1] * gm[-1] + gb[-1] * (1 - gm[-1])
        for i in range(levels - 1, -1, -1):
            size = (ga[i].shape[1], ga[i].shape[0])
            la = ga[i] - cv2.pyrUp(ga[i + 1], dstsize=size)
            lb = gb[i] - cv2.pyrUp(gb[i + 1], dstsize=size)
            out = cv2.pyrUp(out, dstsize=size) + la * gm[i] + lb * (1 - gm[i])
        return out

    ref = two_pyramids(a, b, m, 4)
    assert np.abs(a - b).max() > 50  # the frames differ
    np.testing.assert_allclose(laplacian_blend(a, b, m, 4), ref, atol=1e-2)


def test_lost_actor_face_holds_then_fades():
    F = 30
    flags = np.zeros(F, np.uint8)
    flags[10:] = 1  # face lost from frame 10 on
    expr = np.tile(np.linspace(0, 1, F)[:, None], (1, 53)).astype(np.float32)
    db = SimpleNamespace(expression=np.random.default_rng(0).random((200, 53)).astype(np.float32))
    x, alpha = actor_expressions(
        SimpleNamespace(expression=expr, flags=flags),
        db,
        ReenactConfig(map_expressions=False, hold_frames=4, fade_frames=4),
    )
    np.testing.assert_allclose(x[10:], np.repeat(expr[9:10], F - 10, 0))
    assert (alpha[:14] == 1).all() and 0 < alpha[14] < 1 and (alpha[17:] == 0).all()  # 4 held, 4 fading


@pytest.fixture(scope="module")
def obama_db(tmp_path_factory):
    from anima.reenact.database import build_database, write_database

    db, seqs = build_database([str(asset(OBAMA1))], max_frames=160, progress=False)
    path = write_database(db, tmp_path_factory.mktemp("db") / "obama.npz")
    return db, seqs[0], path


def test_database_on_a_real_clip(obama_db, tmp_path):
    from anima.errors import SchemaError
    from anima.io.video import read_video
    from anima.reenact.database import read_database
    from anima.reenact.pipeline import Reenactor

    db, seq, path = obama_db
    assert db.n >= 150 and db.colors.shape == (db.n, len(db.vertex_ids), 3) and db.colors.dtype == np.uint8
    # the mouth interior the z-buffer never showed is dropped; all skin stays
    rv = db.meta["region_vertices"]
    assert rv["all"] == 11421 and 2000 < rv["kept"] < rv["all"] and rv["kept"] == len(db.vertex_ids)
    db2 = read_database(path)
    np.testing.assert_array_equal(db2.colors, db.colors)
    np.testing.assert_array_equal(db2.expression, db.expression)
    # synthesis from the database reproduces a frame's own lower face closely (it is among the candidates)
    frames, _ = read_video(asset(OBAMA1), max_frames=60)
    rx = Reenactor(db2, ReenactConfig(n=20))
    f = 50
    col = rx.texture(seq.expression[f], skin=rx.target_skin(frames, seq, f, db.identity[0]))
    row = int(np.flatnonzero(db.frame == f)[0])
    assert np.abs(col - db.colors[row]).mean() < 12
    uvz = rx.geometry(seq.expression[f], db.identity[0], seq.scale[f], seq.rotation[f], seq.translation[f])
    out = rx.blend(frames[f], uvz, col)
    assert out.shape == frames[f].shape and np.abs(out.astype(int) - frames[f]).mean() < 6
    # newer version: refused
    d = dict(np.load(path))
    meta = json.loads(str(d["meta"]))
    meta["version"] = 9
    d["meta"] = np.array(json.dumps(meta))
    np.savez(tmp_path / "v9.npz", **d)
    with pytest.raises(SchemaError, match="version 9"):
        read_database(tmp_path / "v9.npz")


def test_self_reenactment_colours_never_read_the_truth_frames(obama_db):
    """Seed 001 §4.2.1: in self-re-enactment the truth frames are kept out of the database, and the
    colour target (the target video's skin) is computed from the database's frames alone."""
    from anima.eval.reenact.run import video_skin
    from anima.reenact.database import build_database
    from anima.reenact.pipeline import Reenactor
    from anima.reenact.synth import skin_stats

    full, seq, _ = obama_db
    db, _ = build_database([str(asset(OBAMA1))], seqs=[seq], exclude={0: (0, 60)}, progress=False)
    assert db.n < full.n and db.frame.min() >= 60  # no truth frame in the database
    rx = Reenactor(db, ReenactConfig())
    mu, sd = video_skin(rx, db)
    # the full database's colours of the same vertices: its frames from 60 on are exactly this database's
    where = {v: k for k, v in enumerate(full.vertex_ids.tolist())}
    cols = full.colors[:, [where[v] for v in db.vertex_ids.tolist()]]
    np.testing.assert_array_equal(cols[full.frame >= 60], db.colors)
    want_mu, want_sd = skin_stats(cols[full.frame >= 60], rx.skin)
    np.testing.assert_allclose(mu, want_mu.mean(0), atol=1e-4)
    np.testing.assert_allclose(sd, want_sd.mean(0), atol=1e-4)
    with_truth, _ = skin_stats(cols, rx.skin)  # what reading the truth frames too would have given
    assert not np.allclose(mu, with_truth.mean(0), atol=1e-4)


def test_colour_transfer_maths():
    from anima.reenact.synth import color_transfer, normalized_colors, skin_stats

    rng = np.random.default_rng(3)
    c = rng.normal(120, 20, (4, 300, 3)).astype(np.float32)
    skin = np.zeros(300, bool)
    skin[:200] = True
    mu, sd = skin_stats(c, skin)
    assert mu.shape == (4, 3) and np.allclose(mu, c[:, :200].mean(1), atol=1e-3)
    lit = c * np.float32([1.3, 1.1, 0.8]) + np.float32([10, 0, -5])  # another camera's white balance
    mu2, sd2 = skin_stats(lit, skin)
    back = color_transfer(lit, mu2, sd2, mu, sd)  # to the first lighting and back again
    np.testing.assert_allclose(back, c, atol=1e-3)
    np.testing.assert_allclose(color_transfer(back, mu, sd, mu2, sd2), lit, atol=1e-3)
    # the gain is bounded: a flat frame cannot blow the contrast up
    flat = np.full((300, 3), 100, np.float32)
    assert np.abs(color_transfer(flat + rng.normal(0, 50, (300, 3)), 100, 1, 100, 50) - 100).max() < 400
    norm = normalized_colors(np.clip(lit, 0, 255).astype(np.uint8), mu2, sd2, mu.mean(0), sd.mean(0), chunk=3)
    assert norm.shape == (4, 300, 3) and norm.dtype == np.uint8


def test_visible_vertices_zbuffer():
    from anima.reenact.render import visible_vertices

    # a small far triangle (depth 0) behind a large near one (depth 10): only the near one's corners show
    uvz = np.array([[5, 5, 0], [9, 5, 0], [5, 9, 0], [0, 0, 10], [30, 0, 10], [0, 30, 10], [40, 40, 0.0]])
    tris = np.array([[0, 1, 2], [3, 4, 5]])
    vis = visible_vertices(uvz.astype(np.float64), tris)
    assert not vis[:3].any() and vis[3:6].sum() >= 2 and not vis[6]  # vertex 6 is on no triangle
    vis_front = visible_vertices((uvz * [1, 1, -1]).astype(np.float64), tris)  # swap the depths
    assert vis_front[:3].all()


def test_lighting_change_between_target_videos(obama_db):
    """A target database whose second half was filmed under other light (the real clip with a camera's
    gain and white balance changed): with colour transfer the texture of a frame from the first half keeps
    that frame's own colours; without it the other light leaks in."""
    import dataclasses

    from anima.io.video import read_video
    from anima.reenact.pipeline import Reenactor

    db, seq, _ = obama_db
    half = db.n // 2
    lit = db.colors.astype(np.float32)
    lit[half:] = lit[half:] * np.float32([1.25, 1.15, 0.75]) + np.float32([25, 15, 0])  # brighter, cooler
    db2 = dataclasses.replace(db, colors=np.clip(lit, 0, 255).astype(np.uint8))
    frames, _ = read_video(asset(OBAMA1), max_frames=60)
    errs = {}
    for on in (False, True):
        rx = Reenactor(db2, ReenactConfig(color_transfer=on, n=100))  # the seed's n: neighbours from both halves
        assert rx.skin.sum() > 300
        e = []
        for f in range(5, 60, 9):
            col = rx.texture(seq.expression[f], skin=rx.target_skin(frames, seq, f, db.identity[0]))
            row = int(np.flatnonzero(db.frame == f)[0])
            e.append(np.abs(col[rx.skin].mean(0) - db.colors[row][rx.skin].mean(0)).max())
        errs[on] = float(np.max(e))
    assert errs[False] > 8 and errs[True] < 3, errs


def test_reenact_command_end_to_end(obama_db, tmp_path, cli):
    from anima.io.video import probe_video

    path = obama_db[2]
    out = tmp_path / "re.mp4"
    r = cli(
        "reenact",
        "--actor",
        str(asset(ACTOR)),
        "--target",
        str(asset(OBAMA1)),
        "--db",
        str(path),
        "--out",
        str(out),
        "--side-by-side",
        "--json",
        "--quiet",
    )
    assert r.returncode == 0, r.stderr
    info = probe_video(out)
    assert info.has_audio and info.n_frames == probe_video(asset(ACTOR)).n_frames
    assert info.width > info.height  # actor | output
    assert "frame rates differ" in r.stderr  # 22 fps actor on a 30 fps target is handled and said
    # the run's record beside the video, which `anima view` reads (the video or its folder)
    rec = json.loads(out.with_suffix(".json").read_text())
    assert rec["schema"] == "anima.reenact_run" and rec["result"]["frames"] == info.n_frames
    assert rec["side_by_side"] and rec["config"]["n"] == ReenactConfig().n
    from anima.io import owned

    # the record names the video's sha256: a later run may replace this video, only while it is anima's
    assert owned.video(out)
    mine = tmp_path / "mine.mp4"
    mine.write_bytes(out.read_bytes() + b"\0")
    (tmp_path / "mine.json").write_text(out.with_suffix(".json").read_text())
    assert not owned.video(mine)
    r = cli("view", out, "--static", tmp_path / "page")
    assert r.returncode == 0, r.stderr
    assert "reenact page written" in r.stdout and (tmp_path / "page" / "reenact.mp4").is_file()
    data = json.loads((tmp_path / "page" / "view-data.js").read_text().split("=", 1)[1].rstrip().rstrip(";"))
    assert data["kind"] == "reenact" and data["videos"] == [
        {"file": "reenact.mp4", "role": "re-enactment (actor | output)"}
    ]


def test_reenact_bad_inputs(tmp_path, cli):
    r = cli(
        "reenact",
        "--actor",
        str(asset(ACTOR)),
        "--target",
        str(asset("liveportrait-examples/assets/examples/driving/d0.mp4")),
        "--out",
        str(tmp_path / "o.mp4"),
    )
    assert r.returncode == 2 and "at least 100" in r.stderr and "Traceback" not in r.stderr
    r = cli(
        "reenact",
        "--actor",
        str(tmp_path / "missing.mp4"),
        "--target",
        str(asset(OBAMA1)),
        "--out",
        str(tmp_path / "o.mp4"),
    )
    assert r.returncode == 2 and "not found" in r.stderr


def test_live_loop_on_a_paced_file(obama_db):
    from anima.live.reenact import reenact_live

    r = reenact_live(
        str(asset(ACTOR)),
        [str(asset(OBAMA1))],
        None,
        ReenactConfig(smooth=0),
        db_path=str(obama_db[2]),
        max_seconds=8,
        progress=False,
    )
    assert r["frames_processed"] > 20
    assert r["frames_received"] >= r["frames_processed"]
    assert r["latency_ms"]["median"] < 1000


def test_ahead_keeps_order_raises_worker_errors_and_stops_when_closed():
    import threading

    from anima.live.reenact import ahead

    assert [(i, r) for i, r in ahead(range(50), lambda i: i * i)] == [(i, i * i) for i in range(50)]

    def bad(i):
        if i == 3:
            raise ValueError("frame 3")
        return i

    got = []
    with pytest.raises(ValueError, match="frame 3"):
        for i, _ in ahead(range(10), bad):
            got.append(i)
    assert got == [0, 1, 2]
    calls = []
    gen = ahead(iter(range(10_000)), lambda i: calls.append(i) or i, depth=2)
    assert next(gen) == (0, 0)
    gen.close()  # the worker stops instead of tracking the rest of the source
    before = threading.active_count()
    n = len(calls)
    assert n < 10 and threading.active_count() <= before


def test_mouth_detail_adds_only_the_best_frames_high_frequencies_inside_the_mask():
    """The one-ring smoother keeps a constant colour field (rows sum to 1); the detail term is then zero, and
    otherwise it changes only the masked vertices, by ``amount`` times (best - smoothed best)."""
    from anima.facemodel.ict import load_face_model
    from anima.reenact.synth import add_detail, mesh_smoother

    sub = load_face_model().subset(np.arange(2000))
    tris = sub.triangles()
    S = mesh_smoother(tris, 2000)
    np.testing.assert_allclose(np.asarray(S.sum(1)).ravel(), 1.0)
    rng = np.random.default_rng(0)
    median = rng.uniform(50, 200, (2000, 3)).astype(np.float32)
    mask = np.zeros(2000, bool)
    mask[:500] = True
    flat = np.full((2000, 3), 120.0)
    np.testing.assert_allclose(add_detail(median, flat, S, mask, 1.0), median, atol=1e-4)
    best = rng.uniform(0, 255, (2000, 3))
    out = add_detail(median, best, S, mask, 0.5)
    np.testing.assert_array_equal(out[~mask], median[~mask])
    want = np.clip(median[mask] + 0.5 * (best - S @ (S @ best))[mask], 0, 255)
    np.testing.assert_allclose(out[mask], want, rtol=1e-5, atol=1e-3)
    assert add_detail(median, best, S, mask, 0.0) is median
