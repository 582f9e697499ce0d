"""``anima eval gesture``: seed 004 ch. 4-5 on the dataset's (audio, motion) windows. The k-NN search is
evaluated leave-one-video-out (each video's windows synthesised from its speech with a database of the other
videos' windows) and compared with the captured motion; the learned models (k-NN + cGAN refiner, the §4.4
generator, direct regression, the LSTM baseline, the sync classifier) are cross-validated by video in 3 folds.

* control adherence (table 5.3): for each control (high / low left-wrist height, high / low left-wrist speed
  at the database's 85th / 15th percentile), the mean and standard deviation of the controlled feature over
  the synthesised frames, beside the threshold and the uncontrolled synthesis;
* L1 to the ground truth (cm, mean over joints and frames, pelvis-relative);
* diversity: mean L1 (cm) between syntheses of the same speech with k = 0..4;
* jerk: mean magnitude of the third time derivative of the wrists (m/s^3), synthesised vs captured;
* beat consistency (Li et al. 2021): mean over motion beats (local minima of the wrists' speed) of
  exp(-d^2 / (2 * 0.1^2)), d the distance in seconds to the nearest audio onset (librosa);
* FGD (Yoon et al. 2020): Fréchet distance in the feature space of a motion autoencoder trained on the
  training split's captured windows;
* lip keypoint error (table 4.3): mm between the 20 lip landmarks of the ICT face with the predicted and the
  captured expression, neutral head pose; the sanity row pairs each window with a random other video's face;
* lip sync on FaceGood's (Mandarin speech, blendshape) recordings: correlation of the predicted mouth opening
  with FaceGood's jaw-open curve, at lag 0 and at the best lag.
"""
from __future__ import annotations

from collections import defaultdict

import numpy as np

from anima.core.skeleton import JOINT_NAMES
from anima.errors import InputError
from anima.gesture.features import FPS, T_MATCH

_W = [JOINT_NAMES.index("left_wrist"), JOINT_NAMES.index("right_wrist")]


def _jerk(J: np.ndarray) -> float:
    w = J[:, _W]
    return float(np.linalg.norm(np.diff(w, 3, axis=0) * FPS ** 3, axis=-1).mean()) if len(w) > 3 else float("nan")


def _wrist_motion(J: np.ndarray) -> float:
    """Expressiveness: the wrists' temporal standard deviation (cm, mean over wrists and axes); a model that
    regresses to the mean pose scores near 0."""
    return float(J[:, _W].std(0).mean() * 100)


def _beat_consistency(J: np.ndarray, onsets_s: np.ndarray) -> float:
    from scipy.signal import argrelmin
    v = np.linalg.norm(np.diff(J[:, _W], axis=0), axis=-1).sum(-1)
    beats = argrelmin(v, order=2)[0] / FPS
    if len(beats) == 0 or len(onsets_s) == 0:
        return float("nan")
    d = np.abs(beats[:, None] - onsets_s[None]).min(1)
    return float(np.exp(-d ** 2 / (2 * 0.1 ** 2)).mean())


def _speaker(source: str) -> str:
    """The speaker of a clip, from the naming of the shared sets: PATS (oliver3_gt.mp4 -> oliver), StyleTalk
    (Obama_clip2.mp4 -> obama), TANGO (speaker7_....mp4 -> speaker7); other clips by their folder."""
    p = source.replace("\\", "/").split("/")
    stem = p[-1].rsplit(".", 1)[0]
    if "pats-crops" in p:
        return stem.split("_")[0].rstrip("0123456789")
    if "styletalk-samples" in p:
        return stem.split("_")[0].lower()
    if "tango-interviews" in p and stem.startswith("speaker"):
        return stem.split("_")[0]
    generic = {"assets", "examples", "video", "videos", "source", "face", "driving", "source_video", "samples"}
    for part in reversed(p[:-1]):
        if part and part not in generic:
            return part
    return p[-1]


def evaluate(folder: str, ks=(0, 1, 2, 3, 4), refiner_folds: int = 3, refiner_steps: int | None = None,
             progress: bool = False, sync_steps: int = 300, generator_steps: int | None = None,
             speaker: str | None = None) -> dict:
    """``speaker``: evaluate on that speaker's windows only (databases, training and tests), the seed's
    subject-specific protocol; default: all speakers together."""
    import librosa

    from anima.gesture.control import control_features, parse_control, step_masks
    from anima.gesture.database import from_dataset
    from anima.gesture.knn import MatchDB, search
    db = from_dataset(folder, None)
    if speaker is not None:
        keep = [i for i, (s, _) in enumerate(db.source) if _speaker(s) == speaker]
        if not keep:
            known = sorted({_speaker(s) for s, _ in db.source})
            raise InputError(f"no (audio, motion) windows of speaker {speaker!r}; speakers: {', '.join(known)}")
        db = MatchDB(db.F[keep], db.P[keep], db.G[keep], [db.source[i] for i in keep], db.S[keep])
    by_video = defaultdict(list)
    for i, (src, _) in enumerate(db.source):
        by_video[src].append(i)
    if len(by_video) < 2:
        raise InputError("leave-one-video-out needs windows from at least two videos")
    ctrl_text = ["left_wrist_height>=p85", "left_wrist_height<=p15", "left_wrist_speed>=p85", "left_wrist_speed<=p15"]
    res = defaultdict(list)
    adherence = {c: {"values": []} for c in ["none"] + ctrl_text}
    kept = {"outs": {}, "ctrl": defaultdict(dict), "onsets": {}}  # per window, for the refiner rows
    for src, idx in by_video.items():
        own = set(idx)
        rest = np.array([i for i in range(db.M) if i not in own])
        sub = MatchDB(db.F[rest], db.P[rest], db.G[rest])
        p0 = sub.P.reshape(-1, sub.P.shape[-1]).mean(0)
        controlled = {}  # per control: this database's step masks and threshold (the same for all its queries)
        for c in ctrl_text:
            masks, rep = step_masks(sub, [parse_control(c)], T_MATCH // 8, 8 / FPS)
            controlled[c] = (masks, rep[0]["relaxed_to"] if rep[0]["relaxed_to"] is not None else rep[0]["threshold"])
        for i in idx:
            F_in, gt = db.F[i], db.G[i].reshape(T_MATCH, -1, 3)
            outs = [search(sub, F_in, k, p0)[0].reshape(T_MATCH, -1, 3) for k in ks]
            g = outs[0]
            res["l1_cm"].append(float(np.abs(g - gt).mean() * 100))
            res["diversity_cm"].append(float(np.mean([np.abs(a - b).mean() * 100 for j, a in enumerate(outs)
                                                      for b in outs[j + 1:]])))
            res["jerk"].append(_jerk(g))
            res["jerk_captured"].append(_jerk(gt))
            res["wrist_motion_cm"].append(_wrist_motion(g))
            res["wrist_motion_cm_captured"].append(_wrist_motion(gt))
            # audio onsets: peaks of the rise of the log energy (speech feature 13) at 15 fps
            env = np.maximum(np.diff(db.F[i][:, 13], prepend=db.F[i][0, 13]), 0)
            on = librosa.onset.onset_detect(onset_envelope=env, sr=int(FPS), hop_length=1, units="time")
            kept["outs"][i], kept["onsets"][i] = outs, on
            res["beat_consistency"].append(_beat_consistency(g, on))
            res["beat_consistency_captured"].append(_beat_consistency(gt, on))
            adherence["none"]["values"].append(control_features(g.reshape(1, T_MATCH, -1)))
            for c, (masks, thr) in controlled.items():
                out = search(sub, F_in, 0, p0, masks)[0].reshape(1, T_MATCH, -1)
                adherence[c]["values"].append(control_features(out))
                adherence[c].setdefault("thresholds", []).append(thr)
                kept["ctrl"][c][i] = (out[0].reshape(T_MATCH, -1, 3), thr)
    table = _adherence_table(adherence)
    refined = _refiner_rows(db, kept, ks, refiner_folds, refiner_steps, progress) if refiner_folds else None


    starts = defaultdict(list)
    for src, st in db.source:
        starts[src].append(st)
    out = {"protocol": __doc__.split("\n\n", 1)[1].strip(), "speaker": speaker or "all",
           "videos": len(by_video), "windows": db.M,
           "minutes_of_audio_motion": _minutes(starts.items()),
           "knn": {k: float(np.nanmean(v)) for k, v in res.items()}, "control_adherence": table}
    if refined is not None:
        out["knn_cgan"] = refined
    if refiner_folds:
        out["generator"] = _generator_rows(folder, kept, db, max(2, min(refiner_folds, len(by_video))),
                                           generator_steps, progress, kept.get("refined"), speaker)
    if refiner_folds:
        out["sync_classifier"] = _sync_rows(db, max(2, min(refiner_folds, len(by_video))), steps=sync_steps)
    per = defaultdict(list)
    for src, st in starts.items():
        per[_speaker(src)].append((src, st))
    out["minutes_per_speaker"] = {k: _minutes(v) for k, v in sorted(per.items())}
    return out


def _minutes(items) -> float:
    """Minutes covered by (source, [window start s]) items: the union of the (overlapping) windows' ranges."""
    total = 0.0
    for _, starts in items:
        end = -1.0
        for a in sorted(starts):
            b = a + T_MATCH / FPS
            total += b - max(a, end) if b > end else 0.0
            end = max(end, b)
    return round(total / 60, 2)


def _adherence_table(adherence: dict) -> dict:
    table = {}
    for c, a in adherence.items():
        name = "left_wrist_height" if c == "none" else c.split(">")[0].split("<")[0]
        vals = np.concatenate([v[name].ravel() for v in a["values"]])
        row = {"mean": float(vals.mean()), "deviation": float(vals.std())}
        if c != "none":  # each query against the threshold of its own (leave-one-out) database
            thr = np.repeat(a["thresholds"], T_MATCH)
            row["threshold"] = float(np.mean(a["thresholds"]))
            row["satisfied_fraction"] = float((vals >= thr).mean() if ">" in c else (vals <= thr).mean())
        table[c] = row
    return table


def _refiner_rows(db, kept: dict, ks, folds: int, steps: int | None, progress: bool) -> dict:
    """k-NN + cGAN (seed 004 §5.3.3), cross-validated by video: the videos are split into ``folds`` groups;
    each group's windows are refined by a refiner trained on the other groups' (k-NN, captured) pairs. The
    k-NN outputs are those of the leave-one-video-out search above, so both rows judge the same windows."""
    from tqdm import tqdm

    from anima.gesture.control import control_features
    from anima.gesture.refine import RefinerTrainConfig, train_refiner
    windows = sorted(kept["outs"])
    videos = sorted({db.source[i][0] for i in windows})
    folds = max(2, min(folds, len(videos)))
    fold_of = {v: n % folds for n, v in enumerate(videos)}
    S = np.stack([db.S[i] for i in windows for _ in ks])
    K = np.stack([kept["outs"][i][n] for i in windows for n in range(len(ks))])
    R = np.stack([db.G[i].reshape(T_MATCH, -1, 3) for i in windows for _ in ks])
    W = np.array([i for i in windows for _ in ks])
    cfg = RefinerTrainConfig() if steps is None else RefinerTrainConfig(steps=steps)
    res = defaultdict(list)
    adherence = {c: {"values": []} for c in ["none"] + list(kept["ctrl"])}
    logs = []
    for f in range(folds):
        test = [i for i in windows if fold_of[db.source[i][0]] == f]
        tr = np.array([fold_of[db.source[w][0]] != f for w in W])
        if not test or not tr.any():
            continue
        bar = tqdm(total=cfg.steps, desc=f"refiner fold {f + 1}/{folds}", disable=not progress, leave=False)
        ref, info = train_refiner(None, cfg, progress=lambda s: bar.update(1), pairs=(S[tr], K[tr], R[tr], W[tr]))
        bar.close()
        logs.append({"fold": f, "train_pairs": int(tr.sum()), "test_windows": len(test), "wall_s": info["wall_s"],
                     "critic_last": float(np.mean(info["log"]["critic"][-50:]))})
        for i in test:
            gt = db.G[i].reshape(T_MATCH, -1, 3)
            outs = [ref.refine(db.S[i], o) for o in kept["outs"][i]]
            g = outs[0]
            kept.setdefault("refined", {})[i] = g
            res["l1_cm"].append(float(np.abs(g - gt).mean() * 100))
            res["l1_to_knn_cm"].append(float(np.abs(g - kept["outs"][i][0]).mean() * 100))
            res["diversity_cm"].append(float(np.mean([np.abs(a - b).mean() * 100 for j, a in enumerate(outs)
                                                      for b in outs[j + 1:]])))
            res["jerk"].append(_jerk(g))
            res["jerk_knn"].append(_jerk(kept["outs"][i][0]))
            res["wrist_motion_cm"].append(_wrist_motion(g))
            res["jerk_captured"].append(_jerk(gt))
            res["beat_consistency"].append(_beat_consistency(g, kept["onsets"][i]))
            adherence["none"]["values"].append(control_features(g.reshape(1, T_MATCH, -1)))
            for c, per in kept["ctrl"].items():
                out, thr = per[i]
                adherence[c]["values"].append(control_features(ref.refine(db.S[i], out).reshape(1, T_MATCH, -1)))
                adherence[c].setdefault("thresholds", []).append(thr)
    return {"protocol": f"{folds}-fold cross-validation by video; WGAN-GP, {cfg.critic_steps} critic steps per "
                        f"generator step, {cfg.steps} generator steps, L1 weight {cfg.l1}",
            "metrics": {k: float(np.nanmean(v)) for k, v in res.items()},
            "control_adherence": _adherence_table(adherence), "folds": logs}


def _sync_rows(db, folds: int, lengths=(16, 32, 64), steps: int = 300) -> dict:
    """Table 4.4: the discriminator trained as an in-sync / off-sync classifier, cross-validated by video
    (the same folds as the refiner); accuracy on 2 x 200 held-out crops per fold and length (chance 0.5)."""
    from anima.gesture.sync import accuracy, train_sync
    videos = sorted({v for v, _ in db.source})
    fold = np.array([videos.index(v) % folds for v, _ in db.source])
    rows = {}
    for L in lengths:
        accs, ns = [], []
        for f in range(folds):
            tr, te = fold != f, fold == f
            if tr.sum() < 2 or te.sum() < 2:
                continue
            S_mean, S_std = db.S[tr].reshape(-1, 28).mean(0), db.S[tr].reshape(-1, 28).std(0) + 1e-4
            G_mean, G_std = db.G[tr].reshape(-1, 165).mean(0), db.G[tr].reshape(-1, 165).std(0) + 1e-4

            def norm(m):
                return ((db.S[m] - S_mean) / S_std).astype(np.float32), ((db.G[m] - G_mean) / G_std).astype(np.float32)
            net, _ = train_sync(*norm(tr), L, steps=steps, seed=f)
            accs.append(accuracy(net, *norm(te), L))
            ns.append(int(te.sum()))
        rows[f"{L}_frames"] = {"accuracy": float(np.average(accs, weights=ns)) if accs else float("nan"),
                               "per_fold": [round(a, 3) for a in accs], "test_windows": ns}
    return rows


# ---- §4.4 generator, its baselines, FGD and the lip error ------------------------------------------------

def load_windows(folder: str) -> dict:
    """All (audio, motion) windows of a dataset, face-only ones included: speech [N, T, 28], body [N, T, 165]
    (NaN rows for face-only windows), face [N, T, 56], source video, start, split."""
    from anima.dataset.storage import read_table
    t = read_table(folder, "audio_motion", None)
    n = t["n_frames"].to_pylist()
    out = {"speech": np.stack([np.asarray(x, np.float32).reshape(k, 28) for x, k in zip(t["speech"].to_pylist(), n)]),
           "body": np.stack([np.asarray(x, np.float32).reshape(k, 165) for x, k in zip(t["body"].to_pylist(), n)]),
           "face": np.stack([np.asarray(x, np.float32).reshape(k, 56) for x, k in zip(t["face"].to_pylist(), n)]),
           "source": t["source"].to_pylist(), "start_s": t["start_s"].to_pylist(), "split": t["split"].to_pylist()}
    out["has_body"] = np.isfinite(out["body"]).all((1, 2))
    return out


def lip_keypoints(face56: np.ndarray, model=None) -> np.ndarray:
    """``[..., 56]`` -> the 20 lip landmarks (iBUG 48-67) of the ICT mean face in a neutral head pose, mm."""
    from anima.facemodel.ict import load_face_model
    from anima.facemodel.landmarks68 import ibug68_vertices
    model = model or load_face_model()
    lip = ibug68_vertices(model)[48:68]
    sub = model.neutral[lip].astype(np.float64)
    d = model.expr_deltas[:, lip].astype(np.float64)
    return (sub + np.tensordot(face56[..., :53].astype(np.float64), d, axes=([-1], [0]))) * 10.0


def lip_error_mm(pred56: np.ndarray, gt56: np.ndarray, model=None) -> float:
    """Table 4.3: mean distance (mm) between predicted and captured 3D lip keypoints, neutral head pose."""
    return float(np.linalg.norm(lip_keypoints(pred56, model) - lip_keypoints(gt56, model), axis=-1).mean())


def mouth_opening_mm(face56: np.ndarray, model=None) -> np.ndarray:
    """Inner-lip opening (iBUG 62 to 66, mm) per frame."""
    k = lip_keypoints(face56, model)
    return np.linalg.norm(k[..., 14, :] - k[..., 18, :], axis=-1)


def _load_py2_npy(path) -> np.ndarray:
    """FaceGood's arrays were saved by Python 2 (latin-1 pickles): numpy reads them but warns each time."""
    import warnings
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Reading `.npy` or `.npz` file required additional header")
        return np.load(path, allow_pickle=True, encoding="latin1")


def _facegood_sync(generators: dict, max_lag: int = 8) -> dict | None:
    """Lip sync on FaceGood's real (Mandarin speech, blendshape) recordings, never seen in training: the
    Pearson correlation between the predicted mouth opening and FaceGood's ``mouth_stretch_c`` curve (its
    jaw-open channel, the largest mouth motion of its rig), at lag 0 and at the best lag within +-``max_lag``
    frames (15 fps); the "other speech" row correlates each recording with the prediction for another one."""
    import glob

    from anima.audio.features import read_audio, speech_features
    from anima.io.assets import asset
    root = asset("facegood-audio2face/code/train", must_exist=False)
    if not root.is_dir():
        return None
    names_p = root / "shirley_1015_bs_name.npy"  # the name list whose symmetric pairs line up with the values
    wavs = sorted(glob.glob(str(root / "wav" / "*.wav")))
    if not wavs or not names_p.is_file():
        return None
    names = list(_load_py2_npy(names_p))
    ch = names.index("mouth_stretch_c")
    recs = []
    for w in wavs:
        stem = w.rsplit("/", 1)[-1][:-4]
        bs = _load_py2_npy(root / "bs_value" / f"bs_value_{stem}.npy")[:, ch]
        x = read_audio(w)
        T = min(int(len(bs) / 30 * FPS), int(len(x) / 16000 * FPS))
        ref = np.interp(np.arange(T) / FPS, np.arange(len(bs)) / 30.0, bs)
        recs.append((stem, speech_features(x, FPS, T).features, ref))

    def corr(a, b, lag):
        if lag > 0:
            a, b = a[lag:], b[:-lag]
        elif lag < 0:
            a, b = a[:lag], b[-lag:]
        n = min(len(a), len(b))
        return float(np.corrcoef(a[:n], b[:n])[0, 1])
    rows = {}
    for kind, gens in generators.items():
        r0, best, lags, other = [], [], [], []
        preds = []
        for _, S, ref in recs:
            m = np.mean([mouth_opening_mm(g.generate(S)[1]) for g in gens], 0)
            preds.append(m)
        for n, (_, S, ref) in enumerate(recs):
            m = preds[n]
            cs = [corr(m, ref, lag) for lag in range(-max_lag, max_lag + 1)]
            r0.append(cs[max_lag])
            best.append(max(cs))
            lags.append(int(np.argmax(cs)) - max_lag)
            other.append(corr(preds[(n + 1) % len(recs)], ref, 0))
        rows[kind] = {"r_lag0": float(np.mean(r0)), "r_best": float(np.mean(best)),
                      "best_lag_frames": lags, "r_other_speech": float(np.mean(other))}
    return {"recordings": len(recs), "minutes": round(sum(len(r[2]) for r in recs) / FPS / 60, 2),
            "channel": "mouth_stretch_c", "rows": rows}


def _generator_rows(folder: str, kept: dict, knn_db, folds: int, steps: int | None, progress: bool,
                    refined_outs: dict | None, speaker: str | None = None) -> dict:
    """The §4.4 generator (adversarial), direct regression (no adversarial term) and the LSTM baseline,
    cross-validated by video with the refiner's folds; FGD for every method; lip error (table 4.3)."""
    from tqdm import tqdm

    from anima.facemodel.ict import load_face_model
    from anima.gesture.fgd import train_fgd
    from anima.gesture.generator import KINDS, GeneratorConfig, GeneratorTrainConfig, train_generator
    w = load_windows(folder)
    if speaker is not None:
        keep = np.array([_speaker(s) == speaker for s in w["source"]])
        w = {k: (v[keep] if isinstance(v, np.ndarray) else [x for x, y in zip(v, keep) if y]) for k, v in w.items()}
    model = load_face_model()
    key = {(s, round(st, 3)): n for n, (s, st) in enumerate(zip(w["source"], w["start_s"]))}
    # the refiner's folds over the body videos, then the face-only videos
    body_videos = sorted({knn_db.source[i][0] for i in kept["outs"]})
    other = sorted(set(w["source"]) - set(body_videos))
    fold_of = {v: n % folds for n, v in enumerate(body_videos)}
    fold_of.update({v: n % folds for n, v in enumerate(other)})
    fold = np.array([fold_of[s] for s in w["source"]])
    cfg = GeneratorTrainConfig() if steps is None else GeneratorTrainConfig(steps=steps)
    res = {k: defaultdict(list) for k in KINDS}
    gen_windows = {k: {} for k in KINDS}
    lip = {k: [] for k in KINDS}
    lip_random = []
    rng = np.random.default_rng(0)
    gens = {k: [] for k in KINDS}
    info = {k: [] for k in KINDS}
    for f in range(folds):
        tr, te = fold != f, np.flatnonzero(fold == f)
        if not tr.any() or not len(te) or not w["has_body"][tr].any():
            continue
        for kind in KINDS:
            bar = tqdm(total=cfg.steps, desc=f"{kind} fold {f + 1}/{folds}", disable=not progress, leave=False)
            gen, inf = train_generator(w["speech"][tr], w["body"][tr], w["face"][tr], GeneratorConfig(kind=kind), cfg,
                                       progress=lambda s: bar.update(1))
            bar.close()
            gens[kind].append(gen)
            info[kind].append({"fold": f, "train_windows": inf["windows"], "train_body_windows": inf["body_windows"],
                               "wall_s": inf["wall_s"], "loss_weights": inf["loss_weights"]})
            for n in te:
                J, face = gen.generate(w["speech"][n])
                lip[kind].append(lip_error_mm(face, w["face"][n], model))
                if w["has_body"][n]:
                    gen_windows[kind][n] = J
        for n in te:  # sanity row of table 4.3: the captured face of a random window of another video
            cand = np.flatnonzero(np.array(w["source"]) != w["source"][n])
            lip_random.append(lip_error_mm(w["face"][rng.choice(cand)], w["face"][n], model))
    # body metrics on the windows the k-NN rows judged (the same windows, the same captured motion)
    judged = []
    for i in sorted(kept["outs"]):
        n = key.get((knn_db.source[i][0], round(knn_db.source[i][1], 3)))
        if n is not None and all(n in gen_windows[k] for k in KINDS):
            judged.append((i, n))
    for kind in KINDS:
        for i, n in judged:
            g, gt = gen_windows[kind][n], knn_db.G[i].reshape(T_MATCH, -1, 3)
            res[kind]["l1_cm"].append(float(np.abs(g - gt).mean() * 100))
            res[kind]["jerk"].append(_jerk(g))
            res[kind]["wrist_motion_cm"].append(_wrist_motion(g))
            res[kind]["beat_consistency"].append(_beat_consistency(g, kept["onsets"][i]))
    train_rows = [i for i, (s, _) in enumerate(knn_db.source) if w["split"][key[(s, round(knn_db.source[i][1], 3))]] == "train"]
    fgd = train_fgd(knn_db.G[train_rows].reshape(len(train_rows), T_MATCH, -1))
    real = np.stack([knn_db.G[i].reshape(T_MATCH, -1) for i, _ in judged])
    fgd_rows = {kind: fgd.distance(real, np.stack([gen_windows[kind][n].reshape(T_MATCH, -1) for _, n in judged]))
                for kind in KINDS}
    fgd_rows["knn"] = fgd.distance(real, np.stack([kept["outs"][i][0].reshape(T_MATCH, -1) for i, _ in judged]))
    if refined_outs:
        fgd_rows["knn_cgan"] = fgd.distance(real, np.stack([refined_outs[i].reshape(T_MATCH, -1) for i, _ in judged]))
    # two random halves of the captured windows against each other: what sampling noise alone gives
    half = len(real) // 2
    perm = np.random.default_rng(0).permutation(len(real))
    fgd_rows["captured_half_vs_half"] = (fgd.distance(real[perm[:half]], real[perm[half:2 * half]]) if half >= 2
                                         else float("nan"))
    rows = {kind: {**{k: float(np.nanmean(v)) for k, v in res[kind].items()}, "diversity_cm": 0.0,
                   "lip_error_mm": float(np.mean(lip[kind])), "fgd": fgd_rows[kind], "folds": info[kind]}
            for kind in KINDS}
    face_only = defaultdict(lambda: defaultdict(list))
    for s_, st, h in zip(w["source"], w["start_s"], w["has_body"]):
        if not h:
            face_only[_speaker(s_)][s_].append(st)
    return {"protocol": f"{folds}-fold cross-validation by video (the refiner's folds; face-only windows from "
                        f"talking-head clips train the face decoder); {cfg.steps} steps, batch {cfg.batch}, Adam "
                        f"{cfg.lr}, adversarial weight {cfg.adv_weight}; deterministic, so diversity is 0",
            "windows_judged": len(judged), "lip_windows": len(lip["adversarial"]), "rows": rows,
            "lip_error_mm_random_other_video": float(np.mean(lip_random)),
            "face_only_windows_per_speaker": {k: sum(len(x) for x in v.values()) for k, v in sorted(face_only.items())},
            "face_only_minutes_per_speaker": {k: _minutes(v.items()) for k, v in sorted(face_only.items())},
            "fgd": fgd_rows, "fgd_autoencoder": fgd.info, "facegood_lip_sync": _facegood_sync(gens)}
