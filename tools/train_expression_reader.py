"""Train the expression reader (:mod:`anima.facemodel.reader`) on renders of the ICT face with known weights, and
write ``anima/facemodel/data/expression_reader.npz`` and its provenance ``expression_reader.json``:

    python tools/train_expression_reader.py --work /tmp/reader          # renders cached there (~1 min a clip)
    python tools/train_expression_reader.py --work /tmp/reader --identities 32

**Training identities only.** Identities are drawn from ICT's identity PCA like the round trip's
(``benchmarks/roundtrip_face.py``) but from another random stream (:data:`SEED`): none of them is a round-trip
development or test identity. The round trip's renderer draws them (skin, lips, brows, the mouth's inside, eyes,
lashes), with each clip's key and fill light, background, camera distance (34-70 cm), skin tone and head turns drawn
at random (the round trip's two fixed views are not used).

**Weights.** Each clip is :data:`N_SEGMENTS` expressions, each ramped up, held and released at random speeds: a
third of them one of the round trip's FACS combinations at a random strength (0.5-1.25 of its peak), the rest
0-2 channels of the upper face and 0-2 of the mouth at random strengths (a quarter of the bilateral ones on one
side only), with a few seconds of speech every 11 segments. The gaze (``eyeLook*``) never moves.

**Capture** as a user's: :func:`anima.capture.pipeline.capture_face` with the reader switched off, then the frame's
landmark offsets (:func:`anima.capture.pipeline.landmark_offsets_of`), exactly as the capture reads them.

**Real faces at rest.** A render is not a person: on real faces at rest the renders' reader would read brows down
and a smile (CREMA-D's neutral take: browDown 0.30 with no such prior). So the reader is also told not to respond
to how real faces differ from the renders' rest: the median landmark offsets of :data:`REAL_CLIPS` (talking heads
on the training side of the shared data's split, their first 8 s; none is an emotion clip), less the renders' rest,
enter the prior with weight :data:`SIGMA_REAL`, for every channel but the brows': real faces at rest differ most in
how high their brows sit, which is what browDown reads, so that prior would leave the brows blind to a frown
(CREMA-D's angry take read as its neutral one); a person's brow height is left to the rest face
(:mod:`anima.facemodel.neutral`) instead. And for :data:`QUIET_IN_SPEECH` (the nose's wrinkle, the upper lip's
raise) every frame of those talking heads is a training row whose answer is 0, weighed :data:`W_TALK` against the
renders: Face Mesh on a real mouth that talks with its teeth showing otherwise reads a sneer the renders taught
(an animator reading the development sheets: "a nose sneer on nearly every frame"; with these rows the MEAD and
CREMA-D takes keep it only where disgust shows it; on the development renders a held 0.8 sneer then reads 0.35
instead of 0.39).

**Fit.** :func:`anima.facemodel.reader.fit_reader` with ``lam`` :data:`LAM`, ``sigma`` :data:`SIGMA` (ICT's identity
directions; 0: not used) and :data:`SIGMA_REAL` (the real faces' rest directions), chosen on the round trip's
DEVELOPMENT identities, CREMA-D's neutral take and d0's labelled smile (development data; the round trip's test
identities were not looked at). On the development identities every setting tried read the weights with about the
same error (0.051-0.052, against 0.132 for the fit); they differed in how strongly they read a held expression
(a held 0.8 smile: 0.31 at ``lam`` 3e-3 and ``sigma`` 1, 0.39 here) and in what a neutral face reads (CREMA-D's
neutral take: browDown 0.30 with no real-face prior, 0.025 with it). Four-fold leave-identities-out
cross-validation over the training identities is reported beside it.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

SEED = 20240611 + 7777
"""Not the round trip's seed: no training identity is one of its development or test identities."""
N_SEGMENTS = 44
LAM, SIGMA, SIGMA_REAL = 1e-3, 0.0, 1.0
REAL_CLIPS = (
    "styletalk-samples/samples/source_video/video/KristiNoem.mp4",
    "styletalk-samples/samples/source_video/video/Obama_clip1.mp4",
    "styletalk-samples/samples/source_video/video/andrew_clip_1.mp4",
    "styletalk-samples/samples/source_video/video/feifeili_clip1.mp4",
    "styletalk-samples/samples/source_video/video/reagan_clip1.mp4",
    "talking-heads-extra/RD_Radio10_0_clip_0.mp4",
    "talking-heads-extra/aniportrait_pose_ref.mp4",
    "talking-heads-extra/mouth_source.mp4",
    "talking-heads-extra/pose_source1.mp4",
    "talking-heads-extra/pose_source2.mp4",
    "talking-heads-extra/uncrop_Obama.mp4",
    "talking-heads-misc/Real3DPortrait/data/raw/examples/May_5s.mp4",
    "videoretalking-examples/examples/face/1.mp4",
    "videoretalking-examples/examples/face/2.mp4",
    "videoretalking-examples/examples/face/3.mp4",
    "videoretalking-examples/examples/face/4.mp4",
    "talking-heads-misc/LatentSync/assets/demo1_video.mp4",
    "talking-heads-misc/LatentSync/assets/demo3_video.mp4",
)
"""Talking heads on the training side of the shared data's split (``anima.dataset.splits``)."""
REAL_FRAMES = 240
QUIET_IN_SPEECH = ("noseSneer", "mouthUpperUp")
"""Channels that people talking on the news do not move much: read 0 on the talking heads' frames."""
W_TALK = 1.0
UPPER = ("browDown", "browInnerUp", "browOuterUp", "eyeSquint", "eyeWide", "cheekSquint", "noseSneer", "eyeBlink")
MOUTH = ("mouthSmile", "mouthFrown", "mouthStretch", "mouthDimple", "mouthPress", "mouthUpperUp", "mouthLowerDown",
         "jawOpen", "mouthFunnel", "mouthPucker", "mouthRollLower", "mouthRollUpper", "mouthShrugLower",
         "mouthShrugUpper", "mouthClose", "jawForward", "jawLeft", "jawRight", "mouthLeft", "mouthRight",
         "cheekPuff")  # fmt: skip


def timeline(names: list[str], rng: np.random.Generator) -> np.ndarray:
    """A training clip's weights ``[F, E]`` (see the module docstring)."""
    import roundtrip_face as rt

    fps = rt.FPS
    sec = lambda s: int(round(s * fps))
    chans = lambda b: rt.channels(b, names)
    parts = [np.zeros((sec(0.7), len(names)))]
    protos = list(rt.COMBOS.values())
    for s in range(N_SEGMENTS):
        peak = np.zeros(len(names))
        if rng.random() < 0.35:
            for b, v in protos[rng.integers(len(protos))].items():
                peak[chans(b)] = v * rng.uniform(0.5, 1.25)
        else:
            k_up, k_mo = rng.integers(0, 3), rng.integers(0, 3)
            chosen = list(rng.choice(UPPER, k_up, replace=False)) + list(rng.choice(MOUTH, k_mo, replace=False))
            for b in chosen:
                c = chans(b)
                v = rng.uniform(0.2, 1.0)
                if b == "mouthClose":
                    v = min(v, 0.4)
                if len(c) == 2 and rng.random() < 0.25:
                    peak[c[rng.integers(2)]] = v
                else:
                    peak[c] = v * rng.uniform(0.85, 1.0, len(c))
        if "mouthClose" in names and peak[names.index("mouthClose")] > 0:  # closed lips over an open jaw
            j, m = names.index("jawOpen"), names.index("mouthClose")
            peak[j] = max(peak[j], peak[m] + 0.1)
        up, hold, down = sec(rng.uniform(0.3, 0.8)), sec(rng.uniform(0.3, 1.0)), sec(rng.uniform(0.3, 0.8))
        gap = np.zeros(sec(rng.uniform(0.0, 0.4)))
        curve = np.concatenate([rt.smoothstep(np.arange(up) / up), np.ones(hold),
                                rt.smoothstep(np.arange(down, 0, -1) / down), gap])  # fmt: skip
        parts.append(np.clip(curve[:, None] * peak[None], 0, 1))
        if s % 11 == 5:
            parts.append(rt.speech_curves(sec(3.0), names, rng))
    parts.append(np.zeros((sec(0.7), len(names))))
    return np.concatenate(parts)


def render_and_capture(i: int, coef: np.ndarray, work: Path) -> Path:
    """Training identity ``i``: rendered, captured, its offsets and truth saved as ``work/t{i}.npz``."""
    import roundtrip_face as rt

    from anima.capture.config import CaptureConfig, FitConfig
    from anima.capture.pipeline import capture_face, landmark_offsets_of
    from anima.facemodel.ict import load_face_model

    out = work / f"t{i}.npz"
    if out.is_file():
        return out
    model = load_face_model()
    rng = np.random.default_rng([SEED, i])
    W = timeline(list(model.expr_names), rng)
    ypr = rt.head_path(len(W), rng) * rng.uniform(0.6, 1.3)
    view = dict(rt.VIEWS["near" if i % 2 == 0 else "far"])
    view["distance_cm"] = float(rng.uniform(34, 70))
    view["key"] = (float(rng.uniform(-0.8, 0.8)), float(rng.uniform(0.0, 0.7)), 1.0)
    view["fill"] = (float(-np.sign(view["key"][0]) * rng.uniform(0.3, 0.8)), float(rng.uniform(-0.2, 0.3)), 0.7)
    view["background"] = tuple(float(x) for x in rng.uniform(0.2, 0.75, 3))
    skin = np.clip(np.array(rt.SKIN_TONES[rng.integers(len(rt.SKIN_TONES))]) * rng.uniform(0.9, 1.1), 0, 1)
    video = work / f"t{i}.mp4"
    rt.film(rt.Face(model, coef, skin), W, ypr, view, video, set())
    seq = capture_face(str(video), CaptureConfig(face_only=True, fit=FitConfig(reader=False)), progress=False)
    F = min(len(W), seq.n_frames)
    D = landmark_offsets_of(seq)[:F]
    np.savez_compressed(out, truth=W[:F], fit=np.asarray(seq.expression[:F]), D=D.astype(np.float32),
                        tracked=np.asarray(seq.tracked[:F]), identity=seq.identity, coef=coef)  # fmt: skip
    return out


def real_rest(clip: str, work: Path) -> Path:
    """A real talking head's landmark offsets over its first :data:`REAL_FRAMES` frames (``work/real_*.npz``)."""
    from anima.capture.config import CaptureConfig, FitConfig
    from anima.capture.pipeline import capture_face, landmark_offsets_of
    from anima.io.assets import asset

    out = work / ("real_" + clip.replace("/", "_") + ".npz")
    if not out.is_file():
        cfg = CaptureConfig(face_only=True, max_frames=REAL_FRAMES, fit=FitConfig(reader=False))
        seq = capture_face(str(asset(clip)), cfg, progress=False)
        np.savez_compressed(out, D=landmark_offsets_of(seq).astype(np.float32), tracked=seq.tracked)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", required=True, help="renders and captures are cached here")
    ap.add_argument("--identities", type=int, default=24)
    ap.add_argument("--out", default=str(ROOT / "anima" / "facemodel" / "data" / "expression_reader.npz"))
    a = ap.parse_args()
    from anima.capture.fit import LandmarkBasis
    from anima.facemodel.correspondence import load_correspondence
    from anima.facemodel.ict import load_face_model
    from anima.facemodel.reader import fit_reader
    from anima.io.atomic import atomic_path, write_json

    t0 = time.perf_counter()
    work = Path(a.work)
    work.mkdir(parents=True, exist_ok=True)
    model = load_face_model()
    names = list(model.expr_names)
    coefs = np.clip(np.random.default_rng(SEED).standard_normal((a.identities, model.id_deltas.shape[0])), -2, 2)
    files = []
    for i in range(a.identities):
        files.append(render_and_capture(i, coefs[i], work))
        print(f"identity {i + 1}/{a.identities}", flush=True)

    lms = np.arange(468)  # the iris (468-477) moves with the gaze, which the renders never turn
    channels = np.array([k for k, n in enumerate(names) if not n.startswith("eyeLook")])
    X, Y, G = [], [], []
    for i, f in enumerate(files):
        with np.load(f, allow_pickle=False) as z:
            ok = z["tracked"] & np.isfinite(z["D"][:, lms]).all((1, 2))
            X.append(z["D"][ok][:, lms].reshape(ok.sum(), -1).astype(np.float64))
            Y.append(z["truth"][ok][:, channels])
            G.append(np.full(ok.sum(), i))
    X, Y, G = np.concatenate(X), np.concatenate(Y), np.concatenate(G)
    basis = LandmarkBasis.build(model, load_correspondence(), True)
    pos = {int(v): k for k, v in enumerate(basis.index)}
    J = basis.ident[[pos[int(v)] for v in lms]].reshape(-1, basis.ident.shape[-1])  # identity directions
    rest = Y.max(1) == 0  # the renders at rest
    r0 = X[rest].mean(0)
    B, talk = [], []
    for clip in REAL_CLIPS:
        with np.load(real_rest(clip, work), allow_pickle=False) as z:
            ok = z["tracked"] & np.isfinite(z["D"][:, lms]).all((1, 2))
            talk.append(z["D"][ok][:, lms].reshape(ok.sum(), -1).astype(np.float64))
            B.append(np.median(talk[-1], 0) - r0)
    B, talk = np.array(B, np.float64), np.concatenate(talk)
    prior = SIGMA**2 * (J @ J.T) + SIGMA_REAL**2 * (B.T @ B) / len(B)
    brows = np.array([names[k].startswith("brow") for k in channels])
    plain = SIGMA**2 * (J @ J.T)  # the brows' prior: a person's brow height is their own (the rest face's job)

    quiet = np.array([names[k].startswith(QUIET_IN_SPEECH) for k in channels])

    def fit(rows):
        mx, my, A = fit_reader(X[rows], Y[rows], prior, LAM)
        _, _, Ab = fit_reader(X[rows], Y[rows][:, brows], plain, LAM)
        A[:, brows] = Ab
        # the sneer and the upper lip's raise: the talking heads' frames as rows whose answer is 0, weighed as
        # W_TALK of the renders (the ridge on the renders' mean, its normal equations extended by those rows)
        Xc, Tc = X[rows] - mx, talk - mx
        n, m = len(Xc), len(Tc)
        lhs = Xc.T @ Xc / n + W_TALK * Tc.T @ Tc / m + LAM * np.eye(X.shape[1]) + prior
        zero = np.broadcast_to(my[quiet], (m, quiet.sum()))  # the answer 0, from the renders' mean
        rhs = Xc.T @ (Y[rows][:, quiet] - my[quiet]) / n - W_TALK * Tc.T @ zero / m
        A[:, quiet] = np.linalg.solve(lhs, rhs)
        return mx, my, A

    err = []
    for fo in np.array_split(np.arange(len(files)), 4):
        te = np.isin(G, fo)
        mx, my, A = fit(~te)
        err.append(np.abs(np.clip((X[te] - mx) @ A + my, 0, 1) - Y[te]).mean(0))
    cv = np.mean(err, 0)
    print(f"cross-validated MAE over held-out training identities: {cv.mean():.4f}", flush=True)
    mx, my, A = fit(np.ones(len(X), bool))
    out = Path(a.out)
    with atomic_path(out) as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, landmarks=lms.astype(np.int32), channels=channels.astype(np.int32),
                                mean_in=mx.astype(np.float32), mean_out=my.astype(np.float32),
                                A=A.astype(np.float32))  # fmt: skip
    write_json(out.with_suffix(".json"), {
        "made_by": "tools/train_expression_reader.py (its docstring)", "seed": SEED,
        "identities": len(files), "frames": int(len(X)), "channels": [names[k] for k in channels],
        "landmarks": "Face Mesh 0-467 (no iris)", "lam": LAM, "sigma": SIGMA, "sigma_real": SIGMA_REAL,
        "real_clips": list(REAL_CLIPS), "real_frames": REAL_FRAMES,
        "cross_validated_mae": {"mean": round(float(cv.mean()), 5),
                                "by_channel": {names[k]: round(float(v), 4) for k, v in zip(channels, cv)},
                                "folds": "4, by training identity"},
        "run_s": round(time.perf_counter() - t0, 1),
    })  # fmt: skip
    print(f"wrote {out} ({len(files)} identities, {len(X)} frames)")


if __name__ == "__main__":
    main()
