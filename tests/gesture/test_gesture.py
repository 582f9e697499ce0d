"""Motion-matching gestures (seed 004 Algorithm 1) on a dataset built from real gesture clips: the fast
search equals the literal algorithm, controls hold, the command writes its files, bad inputs are clear."""

import json
import subprocess

import numpy as np

from anima.io.assets import asset
from anima.io.video import FFMPEG

SPEECH = "gesture-video/pats-crops/oliver2_gt.mp4"


def test_feature_layout():
    from anima.gesture.features import audio_features, pose_features

    S = np.arange(20 * 28, dtype=np.float32).reshape(20, 28)
    f = audio_features(S)
    assert f.shape == (20, 112)
    np.testing.assert_array_equal(f[0, 14:28], S[2, :14])  # t + 2
    np.testing.assert_array_equal(f[15, -14:], S[19, :14])  # past the end: the last frame
    J = np.random.default_rng(0).random((10, 55, 3)).astype(np.float32)
    assert pose_features(J).shape == (10, 96)


def test_fast_rank_sum_keeps_the_stable_order_of_ties():
    from anima.gesture.knn import _rank_sum, _relrank

    rng = np.random.default_rng(1)
    for n in (1, 2, 5, 300):
        for decimals in (None, 1):  # all distinct, then many ties
            a, b = rng.random(n), rng.random(n)
            if decimals is not None:
                a, b = np.round(a, decimals), np.round(b, decimals)
            out = np.empty(n, np.int64)
            _rank_sum(a, b, out)
            np.testing.assert_array_equal(out, _relrank(a) + _relrank(b))


def test_fast_search_equals_algorithm_1(db):
    from anima.audio.features import features_for_file
    from anima.gesture.control import parse_control, step_masks
    from anima.gesture.features import audio_features
    from anima.gesture.knn import search, search_literal

    assert db.M >= 6
    F_in = audio_features(features_for_file(asset(SPEECH), 15.0).features)[:80]
    p0 = db.P.reshape(-1, 96).mean(0)
    for k in (0, 2):
        a, pa = search_literal(db, F_in, k, p0)
        b, pb = search(db, F_in, k, p0)
        assert pa == pb and np.array_equal(a, b)
    masks, _ = step_masks(db, [parse_control("right_wrist_speed<=p40@0-3s")], 10, 8 / 15)
    a, pa = search_literal(db, F_in, 0, p0, masks)
    b, pb = search(db, F_in, 0, p0, masks)
    assert pa == pb and np.array_equal(a, b)
    for n in (2, 4):  # with the no-repeat rule
        a, pa = search_literal(db, F_in, 0, p0, masks, no_repeat_steps=n)
        b, pb = search(db, F_in, 0, p0, masks, no_repeat_steps=n)
        assert pa == pb and np.array_equal(a, b)


def test_fast_search_equals_algorithm_1_on_a_larger_perturbed_database(db):
    """Many near-duplicate windows (the real ones with noise) make many near-ties in the pose
    pre-selection: the quantised, float32 bounds must still never skip the exact best frame."""
    from anima.audio.features import features_for_file
    from anima.gesture.features import audio_features
    from anima.gesture.knn import MatchDB, search, search_literal

    rng = np.random.default_rng(3)
    pick = rng.integers(0, db.M, 150)
    P = db.P[pick] + rng.normal(0, 0.01, db.P[pick].shape).astype(np.float32)
    F = db.F[pick] * (1 + rng.normal(0, 0.05, db.F[pick].shape)).astype(np.float32)
    big = MatchDB(F, P, db.G[pick])
    F_in = audio_features(features_for_file(asset(SPEECH), 15.0).features)[:64]
    a, pa = search_literal(big, F_in, 1, db.P[0, 5].astype(np.float64))
    b, pb = search(big, F_in, 1, db.P[0, 5].astype(np.float64))
    assert pa == pb and np.array_equal(a, b)


def test_control_holds_on_first_and_last_frame_of_each_window(db):
    from anima.audio.features import features_for_file
    from anima.gesture.control import control_features, parse_control, step_masks
    from anima.gesture.features import audio_features
    from anima.gesture.knn import search

    c = parse_control("left_wrist_height>=p70")
    F_in = audio_features(features_for_file(asset(SPEECH), 15.0).features)[:64]
    masks, rep = step_masks(db, [c], 8, 8 / 15)
    _, picks = search(db, F_in, 0, db.P.reshape(-1, 96).mean(0), masks)
    h = control_features(db.G_rig)["left_wrist_height"]  # measured on the one skeleton every output has
    thr = rep[0]["threshold"]
    for m, r in picks:
        assert h[m, r] >= thr and h[m, r + 7] >= thr


def test_gesture_command_outputs_and_bad_inputs(ds, tmp_path, cli):
    from anima.io.sequence import read_sequence
    from anima.io.video import probe_video

    wav44 = tmp_path / "speech44k.wav"  # a sample rate other than 16 kHz is resampled
    subprocess.run(
        [FFMPEG, "-v", "error", "-y", "-i", str(asset(SPEECH)), "-t", "4", "-vn", "-ar", "44100", str(wav44)],
        check=True,
    )
    out = tmp_path / "g"
    r = cli(
        "gesture",
        str(wav44),
        "--db",
        str(ds),
        "--all-splits",
        "--out",
        str(out),
        "--json",
        "--control",
        "hand_symmetry>=5.0@0-2s",
    )  # impossible: relaxed, with a note
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert info["frames"] == 121 and info["fps"] == 30.0 and info["motion_fps"] == 15.0  # the character's rate
    assert info["controls"][0]["relaxed_to"] is not None
    t = info["time_s"]  # where the command's time went, start-up included
    assert {"start", "load", "speech", "search", "post", "write", "render", "total"} <= set(t)
    assert all(v >= 0 for v in t.values()) and t["total"] >= sum(v for k, v in t.items() if k != "total") - 0.01
    assert "relaxed" in r.stderr
    J = read_sequence(out / "gesture.npz").body_joints
    assert J.shape == (121, 55, 3) and np.isfinite(J).all()
    assert max_bone_turn_deg(read_sequence(out / "gesture.npz")) <= 45.0  # no pop: at most 45 degrees a frame
    assert (out / "body.bvh").read_text().startswith("HIERARCHY")
    assert probe_video(out / "avatar.mp4").has_audio and (out / "speech.wav").is_file()
    # a talking face (speech unseen by the dataset): the jaw follows the speech's loudness
    seq = read_sequence(out / "gesture.npz")
    assert seq.tracked.all() and (out / "arkit.csv").is_file() and (out / "face.glb").is_file()
    jaw = seq.expression[:, seq.expr_names.index("jawOpen")]
    assert r_with_energy(jaw, wav44, seq.fps) >= 0.4

    r = cli("gesture", str(wav44), "--db", str(ds), "--out", str(tmp_path / "x"), "--control", "elbow_twist>=p50")
    assert r.returncode == 2 and "unknown control" in r.stderr and "Traceback" not in r.stderr
    short = tmp_path / "short.wav"
    subprocess.run([FFMPEG, "-v", "error", "-y", "-i", str(wav44), "-t", "0.3", str(short)], check=True)
    r = cli("gesture", str(short), "--db", str(ds), "--out", str(tmp_path / "y"))
    assert r.returncode == 2 and "at least" in r.stderr


def max_bone_turn_deg(seq) -> float:
    """The largest turn of any bone's world direction between two frames of ``seq`` on the character
    (degrees): the pops an animator sees, fingers included."""
    from anima.core import rig
    from anima.export.avatar import character_motion

    m = character_motion(seq)
    P = m["positions"]
    kids = [j for j in range(rig.N_RIG) if rig.PARENTS_RIG[j] >= 0]
    d = P[:, kids] - P[:, rig.PARENTS_RIG[kids]]
    d /= np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-9)
    cos = np.clip((d[1:] * d[:-1]).sum(-1), -1.0, 1.0)
    long = np.linalg.norm(m["rest"][kids] - m["rest"][rig.PARENTS_RIG[kids]], axis=-1) > 1e-4
    return float(np.degrees(np.arccos(cos[:, long])).max())


def r_with_energy(curve: np.ndarray, wav, fps: float, max_lag: int = 3) -> float:
    """Pearson correlation of a per-frame curve with the speech's RMS energy at those frames, at the best lag
    within +-``max_lag`` frames."""
    from anima.audio.features import read_audio

    x = read_audio(wav)
    hop = 16000 / fps
    n = min(len(curve), int(len(x) // hop))  # the frames the audio covers (the last may pass its end)
    curve = curve[:n]
    rms = np.array([np.sqrt(np.mean(x[int(i * hop) : int((i + 1) * hop)] ** 2)) for i in range(n)])
    best = -1.0
    for lag in range(-max_lag, max_lag + 1):
        a, b = (curve[lag:], rms[: len(rms) - lag]) if lag >= 0 else (curve[:lag], rms[-lag:])
        best = max(best, float(np.corrcoef(a, b)[0, 1]))
    return best


def test_the_talking_face_blinks_naturally_and_opens_with_the_speech():
    """Two minutes of real speech (FaceGood's Mandarin recordings, never in a dataset): 4-40 blinks a minute,
    each closing both lids fully for at least two frames at 15 fps, never a wink; the jaw follows the speech's
    energy (r >= 0.4) with the built-in defaults (no dataset) too."""
    import glob

    from anima.audio.features import features_for_file
    from anima.gesture.face import talking_face

    wav = sorted(glob.glob(str(asset("facegood-audio2face/code/train", must_exist=False) / "wav" / "*.wav")))[0]
    S = features_for_file(wav, 15.0).features
    face = talking_face(S, 15.0, None, seed=3)
    L, R = face[:, 10], face[:, 11]  # eyeBlink_L, eyeBlink_R (the contract's order)
    starts = np.flatnonzero((L[1:] >= 0.8) & (L[:-1] < 0.8))
    per_min = len(starts) / (len(S) / 15.0 / 60.0)
    assert 4 <= per_min <= 40, per_min
    assert np.array_equal(L >= 0.8, R >= 0.8)  # both eyes: no wink
    runs = np.diff(np.flatnonzero(np.diff(np.concatenate([[0], (L >= 0.8).astype(int), [0]]))))[::2]
    assert runs.min() >= 1 and np.mean(runs >= 2) > 0.5
    from anima.core.contract import EXPR_NAMES

    assert r_with_energy(face[:, EXPR_NAMES.index("jawOpen")], wav, 15.0) >= 0.4


def test_silent_speech_and_speech_longer_than_the_database(db, tmp_path):
    from anima.gesture.knn import MatchDB
    from anima.gesture.run import synthesize

    silent = tmp_path / "silent.wav"
    subprocess.run(
        [FFMPEG, "-v", "error", "-y", "-f", "lavfi", "-i", "anullsrc=r=16000:cl=mono", "-t", "3", str(silent)],
        check=True,
    )
    J, info = synthesize(str(silent), db)
    assert abs(len(J) - 45) <= 1 and J.shape[1:] == (55, 3) and np.isfinite(J).all()  # 3 s at 15 fps
    assert any("silent" in n for n in info["notes"])
    one = MatchDB(db.F[:1], db.P[:1], db.G[:1])  # 64 frames (4.3 s) of database for 8 s of speech
    speech = tmp_path / "speech.wav"
    subprocess.run([FFMPEG, "-v", "error", "-y", "-i", str(asset(SPEECH)), "-t", "8", "-vn", str(speech)], check=True)
    J, info = synthesize(str(speech), one)
    assert abs(len(J) - 120) <= 1 and np.isfinite(J).all()
    assert any("longer than the database" in n for n in info["notes"])


def test_eval_gesture_leave_one_speaker_out(ds, monkeypatch):
    """The whole evaluation on three PATS videos read as three speakers (oliver1, oliver3, seth3: the test
    dataset has two real ones, and a refiner needs two training speakers to search its pairs without their own),
    with two training seeds."""
    import anima.eval.gesture.learned as learned
    import anima.eval.gesture.metrics as metrics
    import anima.eval.gesture.run as run

    real = metrics.speaker_of

    def by_video(src):
        return src.rsplit("/", 1)[-1].split("_")[0] if "pats-crops" in src else real(src)

    for m in (metrics, learned, run):
        monkeypatch.setattr(m, "speaker_of", by_video)
    r = run.evaluate(
        str(ds),
        refiner_folds=3,
        refiner_steps=15,
        sync_steps=10,
        generator_steps=10,
        fgd_steps=30,
        facegood_seconds=6.0,
        seeds=2,
    )
    assert r["videos"] == 3 and r["speakers"] == 3 and r["minutes_of_audio_motion"] > 0.2
    assert set(r["minutes_per_speaker"]) == {"oliver1", "oliver3", "seth3"}
    assert r["knn_folds"] == 3 and r["knn_protocol"].startswith("leave-one-speaker-out, 3 folds")
    ca = r["control_adherence"]
    assert ca["left_wrist_height>=p85"]["mean"] > ca["none"]["mean"] > ca["left_wrist_height<=p15"]["mean"]
    assert r["knn"]["l1_cm"] > 0 and r["knn"]["diversity_cm"] > 0
    # intervals over the folds' unit (whole speakers resampled) beside those over videos
    assert set(r["knn_ci95_over_speakers"]) == set(r["knn_ci95_over_videos"]) >= {"l1_cm"}
    lo, hi = r["knn_ci95_over_speakers"]["l1_cm"]
    assert lo <= r["knn"]["l1_cm"] <= hi
    cg = r["knn_cgan"]  # the refiner rows judge the same windows, each refined by a model that never saw its speaker
    assert len(cg["folds"]) == 3 and sorted(cg["fold_speakers"]) == [["oliver1"], ["oliver3"], ["seth3"]]
    assert cg["protocol"].startswith("leave-one-speaker-out, 3 folds") and "training seeds [0, 1]" in cg["protocol"]
    assert cg["seeds"] == [0, 1] and len(cg["metrics_per_seed"]) == 2
    assert set(cg["metrics_sd_over_seeds"]) == set(cg["metrics"]) and cg["metrics_sd_over_seeds"]["l1_cm"] >= 0
    assert set(cg["metrics_ci95_over_speakers"]) == set(cg["metrics_ci95_over_videos"]) >= {"l1_cm"}
    judged = [f for f in cg["folds"] if "skipped" not in f]
    assert len(judged) == 3 and sum(f["test_windows"] for f in judged) == cg["windows_judged"] == r["windows"]
    # clean folds: no k-NN synthesis a fold's refiner trains on or refines drew from that fold's speaker, and no
    # training pair's from its own window's speaker
    for f in judged:
        assert f["held_out_videos"] == 1 and f["held_out_videos_in_inputs"] == 0
        assert f["own_group_in_training_pairs"] == 0 and [x["seed"] for x in f["per_seed"]] == [0, 1]
        # two training speakers: one is the inner validation, the other alone can make no pair: the default
        assert f["correction_sigma"]["value"] in f["correction_sigma"]["grid"] and f["correction_sigma"]["chosen_on"]
    assert set(cg["knn_fold_inputs"]) >= {"l1_cm", "jerk"} and "clean folds" in cg["protocol"]
    assert cg["metrics"]["l1_cm"] > 0 and np.isfinite(cg["metrics"]["jerk"])
    assert set(cg["control_adherence"]) == set(ca)
    gen = r["generator"]  # the §4.4 generator and its baselines on the same windows, with FGD and lip error
    assert set(gen["rows"]) == {"adversarial", "regression", "lstm", "velocity_adversarial", "moglow"}
    assert gen["windows_judged"] == r["windows"] and gen["seeds"] == [0, 1]
    assert gen["lip_windows"] > r["windows"]  # the talking head's face-only windows are judged too
    assert gen["face_only_windows_per_speaker"] == {"feifeili": gen["lip_windows"] - r["windows"]}
    for row in gen["rows"].values():
        assert row["l1_cm"] > 0 and row["lip_error_mm"] > 0 and np.isfinite(row["fgd"])
        assert [x["seed"] for x in row["per_seed"]] == [0, 1] and row["l1_cm"] == np.mean(
            [x["l1_cm"] for x in row["per_seed"]]
        )
        assert set(row["sd_over_seeds"]) >= {"l1_cm", "fgd", "lip_error_mm"}
        assert sorted((x["fold"], x["seed"]) for x in row["folds"]) == [(f, s) for f in range(3) for s in (0, 1)]
    chosen = [f["adv_weight"] for f in gen["rows"]["adversarial"]["folds"] if "validation" in f["adv_weight"]]
    assert len(chosen) == 6  # every fold: two training speakers, one the inner validation (the same for both seeds)
    for choice, f in zip(chosen, gen["rows"]["adversarial"]["folds"]):  # chosen on the fold's own training speakers
        assert set(choice["validation"]) == {"0.1", "0.01", "1.0"} and choice["validation_windows"] > 0
        assert choice["value"] == min(choice["grid"], key=lambda a: choice["validation"][str(a)]["fgd_frames"])
        assert len(choice["validation_speakers"]) == 1
        assert choice["validation_speakers"][0] not in cg["fold_speakers"][f["fold"]]
    assert "chosen per fold" in gen["protocol"] and gen["protocol"].startswith("leave-one-speaker-out, 3 folds")
    assert set(gen["fgd"]) >= {"knn", "knn_cgan", "adversarial", "captured_half_vs_half"}
    assert set(gen["fgd_sd_over_seeds"]) >= {"knn_cgan", "adversarial"}
    # FGD per fold: each fold's feature network saw only the other folds' windows
    assert len(gen["fgd_folds"]) == 3
    assert all(x["train_windows"] + x["windows"] == r["windows"] for x in gen["fgd_folds"])
    fg = gen["facegood_lip_sync"]
    assert fg["recordings"] == 7 and set(fg["rows"]) == set(gen["rows"]) and fg["seeds"] == [0, 1]
    assert all(len(v["best_lag_frames"]) == 14 and "r_lag0_sd_over_seeds" in v for v in fg["rows"].values())
    sync = r["sync_classifier"]
    assert set(sync) == {"16_frames", "32_frames", "64_frames"}
    assert all(0 <= v["accuracy"] <= 1 and sum(v["test_windows"]) == r["windows"] for v in sync.values())
    assert all(len(v["accuracy_per_seed"]) == 2 for v in sync.values())
    text = "\n".join(run.summary(r))  # the docs' generated tables render from this result
    assert "| k-NN + cGAN refiner (clean folds) |" in text and "| moglow |" in text and "Sync classifier" in text
    assert "| k-NN, leave one speaker out |" in text and "k-NN: leave-one-speaker-out, 3 folds" in text
    assert " ± " in text and "training seeds [0, 1]" in text
    assert "Intervals: 95 % over held-out speakers (whole speakers resampled, 3 speakers" in text


def test_correction_smoothing_rule_is_closest_jerk_ties_to_smaller():
    from anima.eval.gesture.learned import pick_sigma

    scores = {0.0: {"jerk": 30.0}, 0.75: {"jerk": 21.0}, 1.5: {"jerk": 19.0}, 3.0: {"jerk": 9.0}}
    assert pick_sigma(scores, 20.0) == 0.75  # 1 away each: the smaller sigma
    assert pick_sigma(scores, 10.0) == 3.0 and pick_sigma(scores, 40.0) == 0.0


def test_parent_relative_representation_roundtrips(db):
    from anima.gesture.refine import from_parent_relative, to_parent_relative

    J = db.G[0].reshape(64, 55, 3)
    R = to_parent_relative(J)
    np.testing.assert_allclose(from_parent_relative(R), J, atol=1e-6)
    # a hand's finger tip is a short offset from its parent joint (centimetres, not the arm's length)
    assert np.linalg.norm(R[:, 20], axis=-1).max() < 0.08


def test_refiner_trains_with_wgan_gp_and_the_command_uses_it(ds, db, tmp_path, cli):
    import torch

    from anima.gesture.refine import RefinerTrainConfig, knn_pairs, load_refiner, save_refiner, train_refiner

    pairs = knn_pairs(db, RefinerTrainConfig(pairs_per_window=2))  # the seed's draws: k = 1 and k in 2..15
    S, K, R, W = pairs
    assert S.shape[1:] == (64, 28) and K.shape[1:] == (64, 55, 3) and len(S) == 2 * db.M
    assert not np.allclose(K[0], K[1])  # two different syntheses of one window
    old = knn_pairs(db, RefinerTrainConfig.anima_v1(ks=(0, 1)))  # the ablation: k = 0 and 1 from the mean pose
    assert len(old[0]) == 2 * db.M and np.array_equal(old[2], R)
    ref, info = train_refiner(db, RefinerTrainConfig(steps=12, batch=4), pairs=pairs)
    assert len(info["log"]["critic"]) == 12 and np.isfinite(info["log"]["critic"]).all()
    out = ref.refine(S[0][:50], K[0][:50])  # any length (padded to a multiple of 8 inside)
    assert out.shape == (50, 55, 3) and np.isfinite(out).all()
    assert 0 < np.abs(out - K[0][:50]).mean() < 0.05  # trained: moves the k-NN output, but not far
    path = save_refiner(tmp_path / "ref.pt", ref, info)
    again = load_refiner(path)
    np.testing.assert_allclose(again.refine(S[0], K[0]), ref.refine(S[0], K[0]), atol=1e-6)
    wav = tmp_path / "s.wav"
    subprocess.run(
        [FFMPEG, "-v", "error", "-y", "-i", str(asset(SPEECH)), "-t", "3", "-vn", "-ar", "16000", str(wav)], check=True
    )
    r = cli(
        "gesture",
        str(wav),
        "--db",
        str(ds),
        "--all-splits",
        "--out",
        str(tmp_path / "g"),
        "--refiner",
        str(path),
        "--no-render",
        "--json",
    )
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["refined"] is True
    bad = tmp_path / "bad.pt"
    torch.save({"format": "anima.gesture_refiner", "version": 7}, bad)
    r = cli("gesture", str(wav), "--db", str(ds), "--out", str(tmp_path / "h"), "--refiner", str(bad), "--no-render")
    assert r.returncode == 4 and "version 7" in r.stderr and "Traceback" not in r.stderr


def test_sync_pairs_take_off_sync_gestures_from_other_windows():
    from anima.gesture.sync import SyncClassifier, make_pairs

    M, T = 5, 64
    S = np.repeat(np.arange(M, dtype=np.float32)[:, None, None], T, 1).repeat(28, 2)
    G = np.repeat(np.arange(M, dtype=np.float32)[:, None, None], T, 1).repeat(165, 2)
    s, g, y = make_pairs(S, G, 16, 50, np.random.default_rng(0))
    assert s.shape == (100, 16, 28) and g.shape == (100, 16, 165) and y.sum() == 50
    same = s[:, 0, 0] == g[:, 0, 0]
    assert same[y == 1].all() and not same[y == 0].any()
    import torch

    assert SyncClassifier()(torch.from_numpy(s[:4]), torch.from_numpy(g[:4])).shape == (4,)


def test_joins_continue_without_repeating_and_blend(db, tmp_path):
    """On real windows and unseen speech: the search continues from r + 8 (no join repeats the last frame), the
    output keeps one skeleton, and blended joins move the wrists no more than the frames inside windows do."""
    from dataclasses import replace

    from anima.core.skeleton import JOINT_NAMES, PARENTS
    from anima.gesture.post import joins_of
    from anima.gesture.run import SEED_SEARCH, synthesize

    speech = tmp_path / "s.wav"
    subprocess.run([FFMPEG, "-v", "error", "-y", "-i", str(asset(SPEECH)), "-t", "8", "-vn", str(speech)], check=True)
    raw, info_raw = synthesize(str(speech), db, replace(SEED_SEARCH, blend=False))
    J, info = synthesize(str(speech), db)
    picks = info["picks"]
    steps = np.arange(len(picks)) * 8
    assert not any((raw[t] == raw[t - 1]).all() for t in steps[1:])  # no repeated frame at any step
    L = np.linalg.norm(J - J[:, np.maximum(PARENTS, 0)], axis=-1)
    assert np.allclose(L, L[:1], atol=1e-6)  # one skeleton over the whole output
    w = [JOINT_NAMES.index("left_wrist"), JOINT_NAMES.index("right_wrist")]
    joins = joins_of(picks, 8)
    assert joins and info["joins_s"] == [round(t / 15.0, 3) for t in joins]

    def step(X):
        d = np.linalg.norm(np.diff(X[:, w], axis=0), axis=-1).mean(-1)  # per-frame wrist displacement
        at = np.array(joins) - 1
        inside = np.setdiff1d(np.arange(len(d)), at)
        return d[at].mean(), d[inside].mean()

    j_raw, in_raw = step(raw)
    j_bl, in_bl = step(J)
    assert j_bl < j_raw and j_bl < 1.5 * in_bl, (j_raw, in_raw, j_bl, in_bl)


def test_speed_controlled_joins_are_not_blended(db, tmp_path):
    """A wrist-speed control asks for stillness (or motion) that the join blend's decaying offset would change:
    joins inside its time range stay as searched, the others are still blended."""
    from dataclasses import replace

    from anima.gesture.control import parse_control, speed_steps
    from anima.gesture.post import finish_knn, joins_of, one_skeleton
    from anima.gesture.run import SEED_SEARCH, synthesize

    speech = tmp_path / "s.wav"
    subprocess.run([FFMPEG, "-v", "error", "-y", "-i", str(asset(SPEECH)), "-t", "8", "-vn", str(speech)], check=True)
    c = parse_control("left_wrist_speed<=p15@0-4s")
    raw_steps = speed_steps([c], 15, 8 / 15)
    assert raw_steps == set(range(8))  # steps starting before 4 s
    assert not speed_steps([parse_control("left_wrist_height>=p85")], 15, 8 / 15)
    J, info = synthesize(str(speech), db, replace(SEED_SEARCH, control=["left_wrist_speed<=p15@0-4s"]))
    G = np.concatenate([db.G[m, r : r + 8] for m, r in info["picks"]])[: len(J)]
    joins = joins_of(info["picks"], 8)
    plain = one_skeleton(G.reshape(len(G), -1, 3), db.bone_lengths)
    blended = finish_knn(G, info["picks"], db.bone_lengths, 8)
    assert np.allclose(J, finish_knn(G, info["picks"], db.bone_lengths, 8, raw_steps=raw_steps))
    early = [t for t in joins if t < 64]
    late = [t for t in joins if t >= 64]
    assert early and late
    for t in early:  # left as searched
        assert np.allclose(J[t : t + 8], plain[t : t + 8], atol=1e-6)
    assert any(not np.allclose(J[t : t + 8], plain[t : t + 8], atol=1e-4) for t in late)  # blended
    assert not np.allclose(J, blended)  # and it differs from blending every join


def test_no_repeat_keeps_variety_under_a_control(db):
    """A control narrows the database; without the no-repeat rule the output loops over a few windows. With it,
    a controlled output uses at least half as many distinct database windows as an uncontrolled one."""
    from anima.audio.features import features_for_file
    from anima.gesture.control import parse_control, step_masks
    from anima.gesture.features import audio_features
    from anima.gesture.knn import search

    F_in = audio_features(features_for_file(asset(SPEECH), 15.0).features)
    steps = -(-len(F_in) // 8)
    p0 = db.P.reshape(-1, 96).mean(0)
    masks, _ = step_masks(db, [parse_control("left_wrist_height>=p70")], steps, 8 / 15)

    def distinct(masks, n):
        return len({(m, r // 8) for m, r in search(db, F_in, 0, p0, masks, no_repeat_steps=n)[1]})

    free, looped, varied = distinct(None, 8), distinct(masks, 0), distinct(masks, 8)
    assert varied > looped and varied >= free / 2, (free, looped, varied)


def test_control_holds_on_every_frame_of_a_step(db):
    """A control allows a start only where all eight frames it gives satisfy it (the seed checks the first and
    last frame, which let a wrist-speed control hold on about half of the frames): every frame of the search
    output satisfies it, where under the seed's rule frames in between break it."""
    from anima.audio.features import features_for_file
    from anima.gesture.control import control_features, parse_control, step_masks
    from anima.gesture.features import audio_features
    from anima.gesture.knn import search

    F_in = audio_features(features_for_file(asset(SPEECH), 15.0).features)[:120]
    steps = len(F_in) // 8
    p0 = db.P.reshape(-1, 96).mean(0)
    c = parse_control("left_wrist_speed<=p30")
    feats = control_features(db.G_rig)
    fm = c.frame_mask(feats)
    every, ends = db.start_mask(fm), db.start_mask(fm, every_frame=False)
    assert every.any() and (every <= ends).all() and every.sum() < ends.sum()
    for m, s in zip(*np.nonzero(every)):
        assert fm[m, s : s + 8].all()
    sat = {}
    for rule in (True, False):
        masks, rep = step_masks(db, [c], steps, 8 / 15, every_frame=rule)
        _, picks = search(db, F_in, 0, p0, masks)
        thr = rep[0]["relaxed_to"] or rep[0]["threshold"]
        sat[rule] = np.mean([(feats[c.name][m, r : r + 8] <= thr).mean() for m, r in picks])
    assert sat[True] == 1.0 and sat[False] < 1.0, sat


def test_refiner_defaults_are_the_seeds():
    """§5.3.4: w1 = 0.1 (L1), w2 = 1 (adversarial), w3 = 100 (gradient penalty); half the pairs from k = 1,
    the rest uniform over 2..15. anima's earlier setting stays as the named ablation."""
    from anima.gesture.refine import RefinerTrainConfig, seed_draws

    c = RefinerTrainConfig()
    assert (c.l1, c.adv, c.gp, c.k_sampling) == (0.1, 1.0, 100.0, "seed")
    ks = seed_draws(np.random.default_rng(0), 2000)
    assert ks.count(1) == 1000 and set(ks) - {1} == set(range(2, 16))
    v1 = RefinerTrainConfig.anima_v1()
    assert (v1.l1, v1.gp, v1.k_sampling, v1.ks) == (10.0, 10.0, "ks", (0, 1, 2, 3, 4))


def test_database_cache_maps_the_same_windows_and_follows_a_rebuild(ds, tmp_path, monkeypatch):
    """``from_dataset`` makes its memory-mapped cache once, maps the same arrays the next time, and a dataset
    whose manifest changed (a rebuild) gets a new cache instead of the old arrays."""
    import os
    from pathlib import Path

    from anima.gesture.database import _from_windows, from_dataset

    monkeypatch.setenv("ANIMA_HOME", str(tmp_path / "home"))
    ref = _from_windows(ds, None)
    made, mapped = from_dataset(ds, None), from_dataset(ds, None)
    assert isinstance(mapped.F, np.memmap) and not mapped.F.flags.writeable
    for db in (made, mapped):
        for k in ("F", "P", "G", "S"):
            np.testing.assert_array_equal(np.asarray(getattr(db, k)), getattr(ref, k))
        assert db.source == ref.source and db.fps == ref.fps
    caches = tmp_path / "home" / "cache" / "gesture_db"
    assert len(list(caches.iterdir())) == 1
    manifest = Path(ds) / "manifest.json"
    st = manifest.stat()
    try:
        os.utime(manifest, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
        from_dataset(ds, None)
        assert len([p for p in caches.iterdir() if not p.name.startswith(".")]) == 2
    finally:
        os.utime(manifest, ns=(st.st_atime_ns, st.st_mtime_ns))


def test_gesture_folds_keep_each_speaker_in_one_fold():
    """The learned models' folds are by speaker (PATS oliver's three videos in one fold), the
    speakers balanced by windows (GroupKFold's rule), a speaker already placed (body windows) keeps its fold for
    its face-only videos; with one speaker (--speaker) the folds are by video, the seed's person-specific rule."""
    from anima.eval.gesture.metrics import fold_count, speaker_folds

    pats = "gesture-video/pats-crops/"
    src = [pats + "oliver1_gt.mp4"] * 5 + [pats + "oliver3_gt.mp4"] * 4 + [pats + "oliver2_gt.mp4"] * 3
    src += [pats + "seth3_gt.mp4"] * 6 + [pats + "noah1_gt.mp4"] * 5 + [pats + "chem1_gt.mp4"] * 2
    assert fold_count(src, 3) == 3 and fold_count(src[:12], 3) == 2 and fold_count(src[:12], 3, False) == 3
    f = speaker_folds(src, 3)
    assert len({f[pats + n] for n in ("oliver1_gt.mp4", "oliver2_gt.mp4", "oliver3_gt.mp4")}) == 1
    assert f[pats + "oliver1_gt.mp4"] == 0 and f[pats + "seth3_gt.mp4"] == 1 and f[pats + "noah1_gt.mp4"] == 2
    assert f[pats + "chem1_gt.mp4"] == 2  # the lightest fold then (5 windows against 12 and 6)
    face = ["styletalk-samples/samples/source_video/video/Obama_clip1.mp4", pats + "oliver4_gt.mp4"]
    g = speaker_folds(face, 3, True, {"oliver": 0, "seth": 1, "noah": 2, "chem": 2})
    assert g[pats + "oliver4_gt.mp4"] == 0 and g[face[0]] in (0, 1, 2)
    one = speaker_folds(src[:12], 3, by_speaker=False)  # one speaker: by video
    assert sorted(one.values()) == [0, 1, 2]
