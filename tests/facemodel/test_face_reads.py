"""A face that reads: the character's head in colour (brows, lips, eyes with irises and pupils, the
inside of the mouth), its weights chosen so that its face moves as the fitted face does
(transfer by geometry), a captured speaker's rest face taken out of every animation, and the face close up in
``avatar.mp4``; read back by MediaPipe's Face Mesh (its own API) on a real clip."""

import numpy as np
import pytest

from anima.core.contract import EXPR_NAMES
from anima.facemodel.character import COLOURS, SKIN_RGB, SOCKET_SHADE, load_character, vertex_colors
from anima.facemodel.ict import load_face_model
from anima.facemodel.neutral import FADE_S, MAX_REST, faded, from_rest, presented, rest_face
from anima.facemodel.transfer import POINTS, Transfer, face_points


def _transfer():
    ict, ch = load_face_model(), load_character()
    nb = ch.n_body
    return Transfer(ict.neutral, ict.expr_deltas, ict.expr_names, ch.vertices[:nb].astype(float),
                    ch.morph_dense()[:, :nb], EXPR_NAMES)  # fmt: skip


def test_the_same_points_are_found_on_both_faces():
    """The twelve points, found by what each model's own morphs do, sit at the same places of the two faces
    (in face sizes, about the upper lids' midpoint): within 0.15 face sizes."""
    ict, ch = load_face_model(), load_character()
    pi, si = face_points(ict.neutral, ict.expr_deltas, list(ict.expr_names))
    nb = ch.n_body  # the skin's own points (the lashes and teeth follow it)
    pc, sc = face_points(ch.vertices[:nb].astype(float), ch.morph_dense()[:, :nb], list(EXPR_NAMES))

    def norm(V, p, s):
        X = V[p] / s
        return X - (X[POINTS.index("upper_lid_L")] + X[POINTS.index("upper_lid_R")]) / 2

    d = np.linalg.norm(norm(ict.neutral, pi, si)[:, :2] - norm(ch.vertices, pc, sc)[:, :2], axis=-1)
    assert d.max() < 0.15, dict(zip(POINTS, d.round(3)))


def test_the_characters_face_moves_as_the_fitted_face_does(d0_capture):
    """d0 (a smile and blinks): the lids, brows, corners and lips of the character follow the fitted face's,
    per frame (r >= 0.95) and at its amplitude (0.75 to 1.3 of it); copied by name, the brows did less well."""
    seq = d0_capture
    W = seq.expression[:, [seq.expr_names.index(n) for n in EXPR_NAMES]]
    t = _transfer()
    want, got, raw = t.targets(W), t.character(t(W)), t.character(W)
    P = {p: i for i, p in enumerate(POINTS)}
    measures = {
        "lip gap": lambda X: X[:, P["upper_lip"], 1] - X[:, P["lower_lip"], 1],
        "lid gap": lambda X: X[:, P["upper_lid_L"], 1] - X[:, P["lower_lid_L"], 1],
        "corners": lambda X: X[:, P["corner_L"], 1] + X[:, P["corner_R"], 1],
        "brows": lambda X: X[:, P["brow_in_L"], 1] + X[:, P["brow_out_R"], 1],
    }
    for name, f in measures.items():
        a, b, c = f(want), f(got), f(raw)
        r = np.corrcoef(a, b)[0, 1]
        assert r >= 0.95 and r >= np.corrcoef(a, c)[0, 1] - 0.02, (name, r)
        if name in ("lid gap", "brows"):  # the matched points: at the fitted face's amplitude
            assert 0.75 <= b.std() / a.std() <= 1.3, (name, b.std() / a.std())


def test_a_speakers_rest_face_is_taken_out_and_a_generated_face_kept():
    rng = np.random.default_rng(0)
    names = list(EXPR_NAMES)
    F = 100
    E = np.clip(rng.normal(0, 0.02, (F, len(names))), 0, 1).astype(np.float32)
    k = names.index("mouthSmile_L")
    E[:, k] += 0.12  # a face shape read as a smile on every frame
    E[60:80, k] = 0.9  # and a real smile
    rest = rest_face(E, names, np.ones(F, bool), 25.0)
    assert 0.09 < rest["mouthSmile_L"] <= MAX_REST
    out = from_rest(E, names, rest)
    assert np.median(out[:50, k]) < 0.1 and out[60:80, k].min() > 0.8  # neutral reads neutral, the smile stays
    assert rest_face(E[:30], names, np.ones(30, bool), 25.0) == {}  # too short to tell a rest from a smile

    class Seq:
        expression, expr_names, tracked, fps = E, names, np.ones(F, bool), 25.0
        meta = {}

    assert presented(Seq)[1] == {} and np.array_equal(presented(Seq)[0], E)  # generated: as it is
    Seq.meta = {"tracker": {"name": "mediapipe.face_mesh"}}
    assert presented(Seq)[1]["mouthSmile_L"] == rest["mouthSmile_L"]


def test_a_lost_face_eases_to_rest_and_back():
    """Two seconds without a face at 25 fps: the last seen face eases to the rest over FADE_S, rests, and the
    next seen face eases in; a two-frame drop-out holds (never reaches the rest); steps stay small."""
    fps, F = 25.0, 150
    W = np.full((F, 3), 0.8, np.float32)
    tracked = np.ones(F, bool)
    tracked[50:100] = False
    tracked[120:122] = False
    out = faded(W, tracked, fps)
    n = int(FADE_S * fps)
    assert np.allclose(out[tracked], 0.8) and np.allclose(out[50 + n : 100 - n], 0.0)
    assert np.abs(np.diff(out[:, 0])).max() <= 0.8 / n + 1e-6  # no pop in or out
    assert out[120:122].min() > 0.6  # a drop-out holds
    assert not faded(W, np.zeros(F, bool), fps).any()


def test_the_head_has_a_face_in_colour():
    col, ch = vertex_colors(), load_character()
    count = {k: int(np.all(np.isclose(col, v, atol=1e-3), 1).sum()) for k, v in COLOURS.items()}
    for k in ("brow", "lip", "sclera", "iris", "pupil"):
        assert count[k] >= 8, count
    skin = np.all(np.isclose(col, SKIN_RGB, atol=1e-3), 1)
    shade = col[:, 0] / SKIN_RGB[0]  # the eye sockets: the skin's colour, darker
    socket = ~skin & np.all(np.isclose(col, shade[:, None] * np.asarray(SKIN_RGB), atol=1e-3), 1) & (shade < 1)
    assert (skin | socket).mean() > 0.9  # the rest of the body keeps its skin
    assert shade[socket].min() == pytest.approx(1.0 - SOCKET_SHADE, abs=0.03)
    V = ch.vertices
    brow, lip = (
        np.all(np.isclose(col, COLOURS["brow"], atol=1e-3), 1),
        np.all(np.isclose(col, COLOURS["lip"], atol=1e-3), 1),
    )
    assert V[brow, 1].min() > V[lip, 1].max() + 0.06  # the brows above the lips, a face's height apart
    assert V[socket, 1].min() > V[lip, 1].max() and V[socket, 1].max() < V[brow, 1].min()  # between them


def _front(V, J, tris, colors, size=240):
    """The head of vertices ``V`` (joints ``J``) drawn from the front by anima's own rasteriser, 22 cm across,
    and the pixel coordinates of ``V``."""
    from anima.core import rig
    from anima.export.avatar import FACE_CENTRE
    from anima.render.avatar import _view
    from anima.render.raster import draw_shaded

    img = np.zeros((size, size, 3), np.uint8)
    X = _view(V, size, 0.0, J[rig.HEAD] + FACE_CENTRE, size / 0.22)
    draw_shaded(img, X, tris, np.ascontiguousarray(colors, np.float32), back_faces=False)
    return img, np.c_[X[:, 0], -X[:, 1]]  # pixels: x right, y down


def test_the_head_has_teeth_and_lashes_that_move_with_it():
    """MakeHuman's helper teeth and lashes on the character (tools/bake_face_parts.py): the upper teeth still,
    the lower teeth a rigid body that drops with the jaw, the lashes closing with their lids; the teeth seen
    only between the lips (never through the lips, cheeks or nose, in any of the 53 expressions, alone or with
    the jaw half open, in the mean shape and at two standard deviations of the first three components)."""
    from anima.export.avatar import head_triangles

    ch = load_character()
    assert set(ch.parts) == {"body", "teeth_upper", "teeth_lower", "lashes"} and ch.n_body == 13718
    sl = {n: slice(*r) for n, r in ch.parts.items()}
    D, ix = ch.morph_dense(), {n: i for i, n in enumerate(EXPR_NAMES)}
    assert np.abs(D[:, sl["teeth_upper"]]).max() == 0.0
    low = ch.vertices[sl["teeth_lower"]]
    opened = low + D[ix["jawOpen"], sl["teeth_lower"]]
    assert (low[:, 1] - opened[:, 1]).mean() > 0.008  # the jaw drops the lower teeth (metres)
    pair = lambda X: np.linalg.norm(X[:, None] - X[None], axis=-1)
    assert np.abs(pair(opened) - pair(low)).max() < 1e-3  # as one rigid body (float16 deltas)
    lashes = ch.vertices[sl["lashes"]]
    for s, sign in (("L", 1.0), ("R", -1.0)):
        own = sign * lashes[:, 0] > 0
        blink = D[ix[f"eyeBlink_{s}"], sl["lashes"]]
        assert -blink[own, 1].min() > 0.004 and np.abs(blink[~own]).max() == 0.0
    tris = head_triangles(ch)
    teeth = np.zeros((len(ch.vertices), 3), np.float32)
    teeth[sl["teeth_upper"]] = teeth[sl["teeth_lower"]] = (1.0, 0.0, 0.0)
    lips = np.all(np.isclose(vertex_colors(), COLOURS["lip"], atol=1e-3), 1)
    shown = []
    shapes = [np.zeros(ch.n_components)]
    shapes += [sgn * 2 * ch.shape_sdev[k] * np.eye(ch.n_components)[k] for k in range(3) for sgn in (-1, 1)]
    for c in shapes:
        V0, J = ch.shaped(c)
        for k in [None, *range(len(EXPR_NAMES))]:
            for jaw in (0.0, 0.5):
                w = np.zeros(len(EXPR_NAMES))
                w[ix["jawOpen"]] = jaw
                if k is not None:
                    w[k] = 1.0
                img, px = _front(V0 + np.einsum("e,evc->vc", w, D), J, tris, teeth)
                seen = (img[..., 0] > 20) & (img[..., 1] < 5)
                if k is None:
                    shown.append(int(seen.sum()))
                if seen.any():
                    ys, xs = np.nonzero(seen)
                    (x0, y0), (x1, y1) = px[lips].min(0), px[lips].max(0)
                    inside = (x0 - 2 <= xs.min()) & (xs.max() <= x1 + 2) & (y0 - 2 <= ys.min()) & (ys.max() <= y1 + 2)
                    assert inside, (EXPR_NAMES[k] if k is not None else "rest", jaw, c.round(2).tolist())
    rest, half_open = shown[0::2], shown[1::2]
    assert all(o > max(40, 2 * r) for r, o in zip(rest, half_open)), shown  # the open jaw shows the teeth


@pytest.mark.slow
def test_the_characters_lids_open_as_the_video_shows(d0_capture):
    """The lids from the landmarks (:meth:`Transfer.follow_lids`): taken as given (no calibration), an eye's
    opening over its open eye scales the character's lid gap (1 keeps the rest gap, 0.5 halves it, 1.2 opens it
    wider by eyeWide; an eye not seen keeps its weights); through the calibration (:data:`EYE_SHOWN`) the gap is
    the one whose close-up reads as that opening (:func:`lid_gap`: shut at or under the least it reads, a
    half-open eye's 0.5 nearer the cliff where the read-back falls, 0.55-0.65; at the frame's eyeSquint, linear
    between the table's, a risen lower lid asking less gap); on d0 (a blink, looks to the
    side) the character's lid gaps follow the landmarks' opening frame by frame (rank r >= 0.99), and its lids
    shut where the video's do."""
    from scipy.stats import spearmanr

    from anima.export.avatar import character_face
    from anima.facemodel.transfer import EYE_SHOWN, LID_KNEE, SHUT_READ, eye_opening, lid_closure, lid_gap

    t = _transfer()
    rest = t.lid_gaps(np.zeros((1, 53)))[0]
    W = np.zeros((4, 53))
    W[:, EXPR_NAMES.index("eyeSquint_L")] = 0.3  # another channel moving the lid is taken into account
    opening = np.array([[1.0, 1.0], [0.5, 0.5], [1.2, 0.0], [np.nan, np.nan]])
    got = t.follow_lids(W, opening, EXPR_NAMES, shown=None)
    gaps = t.lid_gaps(got)
    np.testing.assert_allclose(gaps[:3] / rest, [[1.0, 1.0], [0.5, 0.5], [1.2, 0.0]], atol=0.02)
    np.testing.assert_array_equal(got[3], W[3])
    assert got[2, EXPR_NAMES.index("eyeWide_L")] > 0 and got[2, EXPR_NAMES.index("eyeBlink_L")] == 0

    gap, squints, reads = EYE_SHOWN
    for q, read in zip(squints, reads):  # each squint's row inverted
        np.testing.assert_allclose(lid_gap(np.array(read), q), gap, atol=1e-9)
    between = (squints[0] + squints[1]) / 2  # linear between the squints
    x = np.linspace(0.2, 1.0, 9)
    np.testing.assert_allclose(lid_gap(x, between), (lid_gap(x, squints[0]) + lid_gap(x, squints[1])) / 2, atol=1e-9)
    np.testing.assert_array_equal(lid_gap(x, [np.nan] * 9), lid_gap(x))  # no squint known: none
    assert lid_gap(np.array([0.0, min(reads[0])])).max() == 0.0 and 0.55 < lid_gap(np.array([0.5]))[0] < 0.65
    assert lid_gap(np.array([0.5]), 1.0)[0] < lid_gap(np.array([0.5]))[0] - 0.05  # the lower lid risen: less gap
    assert np.isnan(lid_gap(np.array([np.nan]))[0]) and lid_gap(np.array([9.0]))[0] == 1.5
    calibrated = t.follow_lids(W, opening, EXPR_NAMES, shown=EYE_SHOWN)  # the left eye at eyeSquint 0.3
    asked = np.stack([lid_gap(opening[:3, 0], 0.3), lid_gap(opening[:3, 1], 0.0)], -1)
    np.testing.assert_allclose(t.lid_gaps(calibrated[:3]) / rest, asked, atol=0.02)
    # what every export carries: the opening itself down to the knee, then shut at the shut reading
    closed = t.follow_lids(W, opening, EXPR_NAMES)
    np.testing.assert_allclose(t.lid_gaps(closed[:3]) / rest, lid_closure(opening[:3]), atol=0.02)
    x = np.array([0.0, SHUT_READ, (SHUT_READ + LID_KNEE) / 2, LID_KNEE, 0.8, 1.2, np.nan])
    np.testing.assert_allclose(lid_closure(x), [0.0, 0.0, LID_KNEE / 2, LID_KNEE, 0.8, 1.2, np.nan])

    seq = d0_capture
    seen = eye_opening(seq.landmarks, seq.tracked, seq.width, seq.height)
    char = t.lid_gaps(character_face(seq)) / rest
    for k in range(2):
        ok = np.isfinite(seen[:, k])
        assert spearmanr(seen[ok, k], char[ok, k])[0] >= 0.99, k
        shut = int(np.nanargmin(seen[:, k]))
        assert seen[shut, k] < 0.3 and char[shut, k] < 0.05, (k, seen[shut, k], char[shut, k])


def test_the_characters_lips_part_as_the_video_shows():
    """The lips from the landmarks (:meth:`Transfer.follow_lips`): an opening the character can show becomes its
    lip gap through the calibration (``(opening - offset) / slope`` above rest), less than it can show shuts its
    lips, by jawOpen and mouthClose (each undoing the other first), the other channels kept; a frame not seen
    keeps its weights."""
    from anima.facemodel.transfer import LIP_SHOWN, LIP_SHUT

    t = _transfer()
    ix = {n: i for i, n in enumerate(EXPR_NAMES)}
    offset, slope = LIP_SHOWN
    W = np.zeros((5, 53))
    W[:, ix["mouthFunnel"]] = 0.2  # another channel parting the lips is taken into account
    W[1, ix["mouthClose"]] = 0.3  # opened: mouthClose undone first
    W[2, ix["jawOpen"]] = 0.4  # shut: jawOpen undone first
    opening = np.array([offset + slope * 0.1, offset + slope * 0.2, 0.0, offset + slope * 0.05, np.nan])
    got = t.follow_lips(W, opening, EXPR_NAMES)
    np.testing.assert_allclose(t.lip_gaps(got[:4]), [0.1, 0.2, LIP_SHUT, 0.05], atol=1e-9)
    assert got[1, ix["mouthClose"]] < W[1, ix["mouthClose"]] and got[2, ix["jawOpen"]] < W[2, ix["jawOpen"]]
    others = [k for k in range(53) if k not in (ix["jawOpen"], ix["mouthClose"])]
    np.testing.assert_array_equal(got[:, others], W[:, others])
    np.testing.assert_array_equal(got[4], W[4])


def test_the_characters_brows_rise_as_the_video_shows(d0_capture):
    """The brows from the landmarks (:meth:`Transfer.follow_brows`): a brow raised by x face heights above the
    clip's median lifts the side's brow points by x over the character's brow calibration (:data:`BROW_SHOWN`,
    face sizes) above their level (within a fifth: the pull towards the transferred weights), by browInnerUp and
    browOuterUp alone (browDown and the other channels kept where no brow comes lower; an unseen frame kept);
    on d0 (a smile, brows moving a little) the character's brow rise follows the landmarks' frame by frame, above
    and below their median, and its browDown over the clip averages the transfer's."""
    from anima.export.avatar import character_face
    from anima.facemodel.transfer import BROW_SHOWN, brow_raise

    t = _transfer()
    ix = {n: i for i, n in enumerate(EXPR_NAMES)}
    W = np.zeros((3, 53))
    W[:, ix["browDown_L"]] = 0.1
    raised = np.array([[0.0, 0.0], [0.01, 0.005], [np.nan, np.nan]])
    got = t.follow_brows(W, raised, EXPR_NAMES, level=t.brow_rise(W[:1])[0])
    lift = (t.brow_rise(got) - t.brow_rise(W[:1]))[:2].mean(-1)  # [frame, side], over the inner and outer points
    np.testing.assert_allclose(lift, raised[:2] / BROW_SHOWN, rtol=0.2, atol=1e-4)  # the pull keeps a little
    others = [k for k in range(53) if not EXPR_NAMES[k].startswith(("browInnerUp", "browOuterUp"))]
    np.testing.assert_array_equal(got[:, others], W[:, others])
    np.testing.assert_array_equal(got[2], W[2])

    seq = d0_capture
    seen = brow_raise(seq.landmarks, seq.tracked, seq.width, seq.height)
    W = character_face(seq)
    char = t.brow_rise(W).mean(-1)
    for k in range(2):
        up = seen[:, k] > 0.003  # raised clearly (browInnerUp, browOuterUp): the character follows (browDown,
        # the reader's level and not the landmarks', moves it a little too: r 0.93-0.95 on d0's dozen raised frames)
        assert up.sum() >= 10 and np.corrcoef(seen[up, k], char[up, k])[0, 1] >= 0.9, k
        # d0 holds no frown (tests/labels/d0_labels.json): under the clip's median the brows only jitter, and the
        # frown's level is the solver's (browDown's clip mean, near 0 here): the character does not rise there
        assert char[seen[:, k] < -0.003, k].max() < 0.005, k
    down = [ix["browDown_L"], ix["browDown_R"]]
    by_transfer = character_face(seq, lids=False, lips=False, brows=False)
    np.testing.assert_allclose(W[seq.tracked][:, down].mean(0), by_transfer[seq.tracked][:, down].mean(0), atol=0.01)


def test_a_frown_lowers_the_brows_by_browDown_its_mean_kept():
    """Where the landmarks put a brow lower than the raise channels at zero leave it (a frown), browDown takes it
    there, the lower the more, and the side's browDown over the seen frames keeps its mean (the fit's: a neutral
    speaker reads as before); an unseen frame is kept, and over a single frame (``anima live``'s page) browDown
    is the fit's."""
    from anima.facemodel.transfer import keep_mean

    t = _transfer()
    ix = {n: i for i, n in enumerate(EXPR_NAMES)}
    W = np.zeros((5, 53))
    W[:, [ix["browDown_L"], ix["browDown_R"]]] = 0.2
    raised = np.array([[0.0, 0.0], [0.0, 0.0], [-0.004, -0.004], [-0.008, -0.008], [np.nan] * 2])
    level = t.brow_rise(W[:1])[0]
    got = t.follow_brows(W, raised, EXPR_NAMES, level=level)
    for s in ("L", "R"):
        d = got[:, ix[f"browDown_{s}"]]
        assert d[3] > d[2] > d[0] == pytest.approx(d[1]), d
        assert d[:4].mean() == pytest.approx(0.2, abs=1e-6)
        assert d[4] == 0.2  # unseen
    rise = t.brow_rise(got).mean(-1)
    assert rise[3, 0] < rise[2, 0] < rise[0, 0]
    one = t.follow_brows(W[2:3], raised[2:3], EXPR_NAMES, level=level)
    assert one[0, ix["browDown_L"]] == 0.2

    x = np.array([0.0, 0.1, 0.5, 0.9])
    assert keep_mean(x, 0.2).mean() == pytest.approx(0.2, abs=1e-9)
    assert keep_mean(x, 0.2)[0] == 0.0 and np.all(np.diff(keep_mean(x, 0.2)) > 0)
    np.testing.assert_allclose(keep_mean(x, x.mean()), x, atol=1e-9)
    np.testing.assert_array_equal(keep_mean(np.array([2.0, 0.0]), 0.5), [1.0, 0.0])  # clipped where it cannot


def test_the_characters_lower_lids_rise_as_the_video_shows(d0_capture):
    """The lower lids from the landmarks (:meth:`Transfer.follow_lower_lids`, before :meth:`Transfer.follow_lids`):
    a lower lid risen a share x of the open eye's gap above the clip's median lifts the character's lower lid
    x of its rest gap above its level, by eyeSquint alone (clipped to [0, 1]; an unseen frame kept); the lids'
    gap is then the same, the upper lid closing less by what the lower lid closed. In a blink (the eye shut past
    the close-up's cliff, :data:`LOWER_LID_CLIFF`) the lower lid holds its level and the upper lid closes. The
    lower lid's depth is read across the eye's corners (a tilted head reads the same). On d0 the character's
    lower lids rise as the landmarks' do (outside blinks) wherever eyeSquint is not clipped."""
    from anima.export.avatar import character_face
    from anima.facemodel.transfer import (
        EYE_SHOWN,
        LOWER_LID_CLIFF,
        eye_opening,
        lower_lid_depths,
        lower_lid_rise,
        lower_lid_share,
    )

    t = _transfer()
    ix = {n: i for i, n in enumerate(EXPR_NAMES)}
    W = np.zeros((4, 53))
    W[:, [ix["eyeSquint_L"], ix["eyeSquint_R"]]] = 0.3
    W[:, ix["mouthSmile_L"]] = 0.4  # another channel moving the lower lid is taken into account
    level = t.lower_lids(W[:1])[0]
    rise = np.array([[0.0, 0.0], [0.1, 0.05], [-0.9, 0.0], [np.nan, np.nan]])
    got = t.follow_lower_lids(W, rise, EXPR_NAMES, level)
    gap = t.rest_gap["L"]
    np.testing.assert_allclose(t.lower_lids(got[:2]) - level, rise[:2] * gap, atol=1e-9)
    assert got[2, ix["eyeSquint_L"]] == 0.0  # as low as eyeSquint can take it
    np.testing.assert_array_equal(got[3], W[3])
    moved = [ix[f"eyeSquint_{s}"] for s in ("L", "R")]
    np.testing.assert_array_equal(np.delete(got, moved, 1), np.delete(W, moved, 1))
    opening = np.full((4, 2), 0.8)
    plain, split = (t.follow_lids(w, opening, EXPR_NAMES, shown=None) for w in (W, got))  # the gap as given
    np.testing.assert_allclose(t.lid_gaps(split), t.lid_gaps(plain), atol=1e-9)
    assert split[1, ix["eyeBlink_L"]] < plain[1, ix["eyeBlink_L"]]
    # in a blink (the eye shut past the close-up's cliff) the lower lid holds its level: the upper lid closes
    gaps, _, reads = EYE_SHOWN
    foot, top = (np.interp(g, gaps, reads[0]) for g in LOWER_LID_CLIFF)  # the upper lid's cliff, no squint
    np.testing.assert_allclose(lower_lid_share(np.array([0.0, foot, (foot + top) / 2, top, 1.2])),
                               [0.0, 0.0, 0.5, 1.0, 1.0], atol=1e-9)  # fmt: skip
    blinking = t.follow_lower_lids(W, rise, EXPR_NAMES, level, opening=np.array([[1.0, 1.0], [0.1, 1.0], [1.0] * 2,
                                                                                 [np.nan] * 2]))  # fmt: skip
    np.testing.assert_allclose(t.lower_lids(blinking[1:2]) - level, [[0.0, rise[1, 1] * gap]], atol=1e-9)
    np.testing.assert_array_equal(blinking[[0, 2, 3]], got[[0, 2, 3]])

    seq = d0_capture
    L = np.asarray(seq.landmarks, np.float64)[:, :, :2]
    turn = np.deg2rad(20.0)
    R = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
    c = np.array([0.5, 0.5])
    tilted = ((L - c) * [seq.width, seq.height]) @ R.T / [seq.width, seq.height] + c  # turned in pixels
    np.testing.assert_allclose(
        lower_lid_depths(tilted, seq.width, seq.height), lower_lid_depths(L, seq.width, seq.height), atol=1e-9
    )
    opening = eye_opening(seq.landmarks, seq.tracked, seq.width, seq.height)
    seen = lower_lid_rise(seq.landmarks, seq.tracked, seq.width, seq.height) * lower_lid_share(opening)
    W = character_face(seq)
    lids = t.lower_lids(W)
    for k, s in enumerate(("L", "R")):
        q = W[:, ix[f"eyeSquint_{s}"]]
        free = (q > 0.01) & (q < 0.99) & np.isfinite(seen[:, k])
        assert free.sum() > 20 and np.ptp(seen[free, k]) > 0.05, (s, free.sum())
        slope = np.polyfit(seen[free, k], lids[free, k], 1)[0]
        # within 10 %: cheekSquint (ICT's shape, AU6, which the reader reads with d0's smile) lifts the lower lid too
        assert np.corrcoef(seen[free, k], lids[free, k])[0, 1] > 0.99 and slope == pytest.approx(gap, rel=0.1), s


@pytest.mark.slow
def test_the_lips_calibration_is_what_the_close_up_shows(d0_capture):
    """:data:`LIP_SHOWN` measured again: the character's jaw opened step by step, its close-up read back by Face
    Mesh (``benchmarks/face_readback.py --calibrate``): the mouth's opening is the calibration's line of its lip
    gap (offset within 0.004, slope within 10 %), and its rest lips, shut by :data:`LIP_SHUT`, read as closed."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    from face_readback import calibrate_lips, measures, read_faces, render_character

    from anima.facemodel.transfer import LIP_SHOWN, LIP_SHUT

    cal = calibrate_lips(d0_capture)
    assert abs(cal["offset"] - LIP_SHOWN[0]) < 0.004 and abs(cal["slope"] / LIP_SHOWN[1] - 1) < 0.1, cal
    t = _transfer()
    W = t.follow_lips(np.zeros((3, 53)), np.zeros(3), EXPR_NAMES)
    assert t.lip_gaps(W)[0] == pytest.approx(LIP_SHUT)
    assert measures(read_faces(render_character(d0_capture, W=W)))["mouth"][-1] < LIP_SHOWN[0] / 2


def test_the_eyes_calibration_is_what_the_close_up_shows(d0_capture):
    """:data:`EYE_SHOWN` measured again, on one head pose (d0's first frame; the table took three) and at two of
    its squints (none and eyeSquint 1; the table took seven): the character's lids swept shut and open, its
    close-up read back by Face Mesh (``benchmarks/face_readback.py --calibrate``); at both squints, for every
    opening from a shut eye's to an open one's, the lid gap it asks for is within 0.06 of the table's (of the rest
    gap), and a shut eye reads under a third of an open one."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    from face_readback import calibrate_eyes

    from anima.facemodel.transfer import EYE_SHOWN, lid_gap

    cal = calibrate_eyes([d0_capture], squints=(0.0, 1.0))
    x = np.linspace(0.25, 1.0, 31)
    for q in (0.0, 1.0):
        miss = np.abs(lid_gap(x, q, (cal["gap"], cal["squint"], cal["read"])) - lid_gap(x, q, EYE_SHOWN))
        assert miss.max() <= 0.06, (q, cal["read"], miss.round(3))
    assert cal["read"][0][0] < 1 / 3, cal


def test_the_brows_calibration_is_what_the_close_up_shows(d0_capture):
    """:data:`BROW_SHOWN` measured again, on one head pose (d0's first frame; the constant took three): the
    character's brows swept from browDown to browInnerUp and browOuterUp, its close-up read back by Face Mesh
    (``benchmarks/face_readback.py --calibrate``): the brows' height read per face size their points rise is the
    constant's within a tenth, and it rises as the brows do."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    from face_readback import calibrate_brows

    from anima.facemodel.transfer import BROW_SHOWN

    cal = calibrate_brows([d0_capture])
    assert abs(cal["slope"] / BROW_SHOWN - 1) < 0.1, cal
    read = np.array(cal["points"])[:, 1]
    assert read[0] < 0 < read[-1] and np.corrcoef(np.array(cal["points"])[:, 0], read)[0, 1] > 0.95, cal


def test_the_read_back_counts_blinks_and_finds_them_on_the_same_frames(d0_capture):
    """The read-back's blink measures on d0's blink (its landmarks' eye opening, the reader's measure of it):
    one closing, counted as a blink (two frames or more under the line); a render closing on the same frames,
    or one frame late, shares it; one closing five frames late, or a one-frame closing counted by the two-frame
    rule as none, is told apart."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    from face_readback import blinks, low_runs, shared_blinks

    from anima.facemodel.transfer import eye_ratios

    eye = eye_ratios(d0_capture.landmarks, d0_capture.width, d0_capture.height).mean(1)
    runs = low_runs(eye)
    assert len(runs) == 1 and blinks(eye) == 1 and runs[0, 1] - runs[0, 0] >= 2, runs
    assert shared_blinks(eye, eye) == 1 and shared_blinks(eye, np.roll(eye, 1)) == 1
    assert shared_blinks(eye, np.roll(eye, 5)) == 0
    brief = eye.copy()
    brief[runs[0, 0] + 1 : runs[0, 1]] = np.nanmedian(eye)  # the closing cut to its first frame
    assert blinks(brief) == 0 and len(low_runs(brief)) == 1 and shared_blinks(eye, brief) == 1


def test_a_speaker_talking_with_closed_lips_reads_back_as_the_video():
    """d9's first 10 s (a speaker whose lips part by a pixel or two, closed most of the time): read back by Face
    Mesh, the character's mouth follows the video's (r >= 0.85) with its lips set from the landmarks; by the
    transfer alone its rest lips, parted by a sliver, read as openings the video does not have (r under 0.8)."""
    import itertools
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    from face_readback import compare, measures, read_faces, render_character

    from anima.capture.config import CaptureConfig
    from anima.capture.pipeline import capture_face
    from anima.io.assets import asset
    from anima.io.video import iter_frames, probe_video

    d9, n = str(asset("liveportrait-examples/assets/examples/driving/d9.mp4")), 250
    seq = capture_face(d9, CaptureConfig(max_frames=n), progress=False)
    video = measures(read_faces(itertools.islice(iter_frames(probe_video(d9)), n)))
    assert np.nanpercentile(video["mouth"], 90) < 0.01  # closed lips, nearly throughout
    lips = compare(video, measures(read_faces(render_character(seq))))["mouth_r"]
    alone = compare(video, measures(read_faces(render_character(seq, lips=False))))["mouth_r"]
    assert lips >= 0.85 and alone < 0.8, (lips, alone)


def test_the_live_face_is_the_clips_face_one_frame_at_a_time(d0_capture):
    """``anima live``'s page gets :class:`LiveCharacterFace`: d0 streamed frame by frame (its fit and Face Mesh
    landmarks, at 25 fps): the lids follow the landmarks' opening from the first frames on (r >= 0.95 once
    the running open eye holds ten frames), and at the last frame, the running rest and open eye having seen
    the whole clip, its weights are the clip's own (:func:`character_face`) within 0.05, and the ARKit weights
    the outputs send are the clip's measured from its rest."""
    from anima.export.avatar import LiveCharacterFace, character_face
    from anima.facemodel.transfer import eye_opening

    seq = d0_capture
    X = seq.expression[:, [seq.expr_names.index(n) for n in EXPR_NAMES]]
    live = LiveCharacterFace()
    both = [live(X[f], seq.landmarks[f], (seq.height, seq.width), f / seq.fps) for f in range(seq.n_frames)]
    out, shown = np.stack([b[0] for b in both]), np.stack([b[1] for b in both])
    t = _transfer()
    seen = eye_opening(seq.landmarks, seq.tracked, seq.width, seq.height)
    gaps = t.lid_gaps(out)
    for k in range(2):
        assert np.corrcoef(seen[15:, k], gaps[15:, k])[0, 1] >= 0.95, k
    np.testing.assert_allclose(out[-1], character_face(seq)[-1], atol=0.05)
    # what Live Link and VMC send: the fit measured from the rest face, as a capture's arkit.csv is
    np.testing.assert_allclose(shown[-1], presented(seq)[0][-1][[seq.expr_names.index(n) for n in EXPR_NAMES]],
                               atol=0.05)  # fmt: skip
    np.testing.assert_allclose(shown[:50], np.clip(X[:50], 0, 1), atol=1e-6)  # no rest before 2 s of faces


def test_the_close_up_reads_back_as_the_video():
    """The character's face close up (as ``avatar.mp4``'s face panel draws it) read back by Face Mesh on d3's
    first 6 s (a frown, a squint, talking, four blinks): the mouth's and the eyes' opening follow the video's
    (r >= 0.8), the brows' height too (r >= 0.7), its blinks within one of the video's count; the face is found
    in nearly every frame."""
    import itertools
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    from face_readback import blinks, measures, read_faces, render_character

    from anima.capture.config import CaptureConfig
    from anima.capture.pipeline import capture_face
    from anima.io.assets import asset
    from anima.io.video import iter_frames, probe_video

    d3, n = str(asset("liveportrait-examples/assets/examples/driving/d3.mp4")), 180
    seq = capture_face(d3, CaptureConfig(max_frames=n), progress=False)
    video = measures(read_faces(itertools.islice(iter_frames(probe_video(d3)), n)))
    char = measures(read_faces(render_character(seq)))
    assert np.isfinite(char["mouth"]).mean() > 0.95
    for k, r_min in (("mouth", 0.8), ("eye_L", 0.8), ("eye_R", 0.8), ("brows", 0.7)):
        ok = np.isfinite(video[k]) & np.isfinite(char[k])
        r = np.corrcoef(video[k][ok], char[k][ok])[0, 1]
        assert r >= r_min, (k, r)
    seen, shown = (blinks((m["eye_L"] + m["eye_R"]) / 2) for m in (video, char))
    assert seen >= 3 and abs(shown - seen) <= 1, (seen, shown)


def test_skinning_is_linear_blend_skinning():
    """:func:`anima.facemodel.character.skin` (a numba kernel) against the formula written out in numpy, for one
    pose, a batch of poses, and one vertex set per pose."""
    from anima.core.rotations import rotvec_to_matrix
    from anima.facemodel.character import skin

    ch = load_character()
    rng = np.random.default_rng(0)
    G = rotvec_to_matrix(rng.normal(0, 0.5, (3, len(ch.joints), 3)))
    P = ch.joints + rng.normal(0, 0.05, (3, len(ch.joints), 3))
    Vs = ch.vertices + rng.normal(0, 0.01, (3, *ch.vertices.shape))

    def reference(V, G, P):
        out = 0.0
        for k in range(ch.skin_joints.shape[1]):
            b = ch.skin_joints[:, k]
            local = V - ch.joints[b]
            out = out + ch.skin_weights[:, k, None] * (np.einsum("vij,vj->vi", G[b], local) + P[b])
        return out

    assert np.allclose(skin(ch.vertices, ch.joints, G[0], P[0], ch), reference(ch.vertices, G[0], P[0]), atol=1e-12)
    batch = skin(ch.vertices, ch.joints, G, P, ch)
    assert batch.shape == (3, len(ch.vertices), 3)
    assert np.allclose(batch[2], reference(ch.vertices, G[2], P[2]), atol=1e-12)
    per_pose = skin(Vs, ch.joints, G, P, ch)
    assert np.allclose(per_pose[1], reference(Vs[1], G[1], P[1]), atol=1e-12)
    rest = skin(ch.vertices, ch.joints, np.tile(np.eye(3), (len(ch.joints), 1, 1)), ch.joints, ch)
    assert np.allclose(rest, ch.vertices, atol=1e-12)  # the rest pose leaves the mesh where it is


def test_the_close_up_is_mounted_on_the_head(d0_capture):
    """The close-up's camera rides on the head like a face-capture rig's helmet camera: on d0, where
    the head turns and tilts, the face's still points (the nose's tip, the eyes' corners, the forehead) stay
    within half a pixel of their place in a 384-pixel close-up on every frame, so only the expression moves;
    a camera that followed only the head's yaw let them wander (the brows read against the lids moved)."""
    from anima.core import rig
    from anima.export.avatar import character_motion, face_camera
    from anima.facemodel.character import skin
    from anima.render.avatar import _view, head_view

    ch = load_character()
    m = character_motion(d0_capture)
    centre, head, _ = face_camera(m, ch)
    G = m["global"][:, rig.HEAD]
    turned = np.degrees(np.arccos(np.clip((np.einsum("fij,ij->f", G, G[0]) - 1) / 2, -1, 1)))
    assert turned.max() > 1.5, turned.max()  # the head does turn (2 degrees)
    V = skin(ch.vertices, m["rest"], m["global"], m["positions"], ch)  # no expression: only the pose moves them
    main = ch.skin_joints[np.arange(len(ch.vertices)), np.argmax(ch.skin_weights, 1)]
    still = np.flatnonzero((main == rig.HEAD) & (ch.skin_weights.max(1) > 0.999))
    assert len(still) > 100
    px = np.stack([head_view(V[f, still], 384, head[f], centre[f], 384 / 0.30)[:, :2] for f in range(len(V))])
    assert np.abs(px - px[0]).max() < 0.5, np.abs(px - px[0]).max()
    fwd = np.einsum("fij,j->fi", G, [0.0, 0.0, 1.0])
    yaw = -np.arctan2(fwd[:, 0], fwd[:, 2])
    by_yaw = np.stack([_view(V[f, still], 384, yaw[f], centre[f], 384 / 0.30)[:, :2] for f in range(len(V))])
    assert np.abs(by_yaw - by_yaw[0]).max() > 2  # the yaw-only camera: the same points wander


def test_a_hand_over_the_mouth_eases_the_mouth_to_rest_and_says_so(tmp_path):
    """A real talking clip (d0, 1.2 s) followed by the shared photo of hands over a face (2 s): under the hands
    the fit has no evidence for the mouth, so the character's mouth eases to its rest within 0.25 s (never a
    frozen mid-word mouth) while the eyes and brows keep following; capture's info.json names the covered
    frames."""
    import json
    import subprocess

    import imageio_ffmpeg

    from anima.capture.config import CaptureConfig
    from anima.capture.run import run
    from anima.core.occlusion import hand_over_face
    from anima.export.avatar import MOUTH, character_face
    from anima.io.assets import asset
    from anima.io.sequence import read_sequence

    ff = imageio_ffmpeg.get_ffmpeg_exe()
    talk, hands, both = tmp_path / "talk.mp4", tmp_path / "hands.mp4", tmp_path / "both.mp4"
    scale = ["-vf", "scale=512:512,setsar=1,fps=25,format=yuv420p"]
    subprocess.run([ff, "-v", "error", "-y", "-i", str(asset("liveportrait-examples/assets/examples/driving/d0.mp4")),
                    "-t", "1.2", "-an", *scale, str(talk)], check=True)  # fmt: skip
    subprocess.run([ff, "-v", "error", "-y", "-loop", "1", "-i", str(asset("hand-images/hands_over_face.jpg")),
                    "-t", "2", *scale, str(hands)], check=True)  # fmt: skip
    subprocess.run([ff, "-v", "error", "-y", "-i", str(talk), "-i", str(hands), "-filter_complex",
                    "[0:v][1:v]concat=n=2:v=1[v]", "-map", "[v]", str(both)], check=True)  # fmt: skip
    out = tmp_path / "out"
    run(str(both), out, CaptureConfig(), render=False, progress=False)
    seq = read_sequence(out / "capture.npz")
    covered = hand_over_face(seq) & seq.tracked
    assert covered[40:].mean() > 0.8 and covered[:25].sum() == 0, covered.astype(int).tolist()
    W = character_face(seq)
    start = int(np.flatnonzero(covered)[0])
    settled = [f for f in np.flatnonzero(covered) if f - start > 0.25 * seq.fps]
    assert np.abs(W[settled][:, MOUTH]).max() == 0.0  # at rest under the hands (the fit reads 1.0 there)
    info = json.loads((out / "info.json").read_text())
    assert info["mouth_covered"]["frames"] == int(covered.sum())


def test_a_neutral_reference_keeps_a_clip_long_expression(tmp_path):
    """CREMA-D actor 1001 (development clips, 2 s each): the angry take lowers its brows for the whole clip; with
    the same speaker's neutral take as ``--neutral`` the angry brows stay down against the neutral take's, the
    neutral take reads near zero, and info.json says where the rest came from. The rest clip is given as a video,
    then as a capture."""
    import json

    from anima.capture.config import CaptureConfig
    from anima.capture.run import run
    from anima.core.contract import EXPR_NAMES
    from anima.export.avatar import character_face
    from anima.io.assets import asset
    from anima.io.sequence import read_sequence

    clip = "emotion-clips/crema-d/1001_DFA_{}_XX.flv"
    neu, ang = tmp_path / "neutral", tmp_path / "angry"
    run(str(asset(clip.format("NEU"))), neu, CaptureConfig(), render=False, progress=False,
        neutral=str(asset(clip.format("NEU"))))  # fmt: skip
    run(str(asset(clip.format("ANG"))), ang, CaptureConfig(), render=False, progress=False,
        neutral=str(neu / "capture.npz"))  # fmt: skip

    def mean(seq, base):
        k = [i for i, n in enumerate(EXPR_NAMES) if n.startswith(base + "_")]
        return float(character_face(seq)[seq.tracked][:, k].mean())

    N, A = (read_sequence(d / "capture.npz") for d in (neu, ang))  # as exported: the landmarks set lids, brows
    assert mean(N, "mouthSmile") < 0.1 and mean(N, "browDown") < 0.1
    assert mean(A, "browDown") > mean(N, "browDown") + 0.03  # measured 0.057 against 0.021
    said = {d.name: json.loads((d / "info.json").read_text())["rest_face"] for d in (neu, ang)}
    assert "1001_DFA_NEU_XX.flv (--neutral)" in said["neutral"]["how"]
    assert f"{neu / 'capture.npz'} (--neutral)" in said["angry"]["how"]
    assert said["angry"]["channels"] == pytest.approx(said["neutral"]["channels"])  # the same rest, both ways
