"""Rows of the learned gesture models, cross-validated by speaker (by video for one speaker): the
k-NN + cGAN refiner (§5.3.3), the §4.4 generator with its baselines (direct regression, LSTM), FGD, the lip
error (table 4.3) and the sync classifier (table 4.4). Every model is trained by its feature package
(``anima.gesture``) on the training folds' videos and judged on the held-out fold's windows; a held-out speaker's
videos are all held out together, and a setting chosen inside a fold is chosen on inner validation speakers
(:func:`anima.eval.gesture.metrics.inner_validation`) of that fold's training speakers. Every model is trained with
several training seeds per fold; a row is the mean over seeds, beside its standard deviation over seeds."""

from __future__ import annotations

import dataclasses
from collections import defaultdict

import numpy as np
from tqdm import tqdm

from anima.core.contract import BODY_DIM, SPEECH_DIM
from anima.dataset.windows import Windows
from anima.eval.gesture.facegood import facegood_sync
from anima.eval.gesture.fgd import train_fgd
from anima.eval.gesture.metrics import (
    adherence_table,
    beat_consistency,
    bootstrap_over_groups,
    diversity_cm,
    fold_count,
    group_of,
    inner_validation,
    jerk,
    l1_cm,
    lip_error_mm,
    minutes_covered,
    speaker_folds,
    speaker_of,
    wrist_motion,
)
from anima.facemodel.ict import load_face_model
from anima.gesture.control import control_features, parse_control, speed_steps, step_masks
from anima.gesture.features import N_STEP
from anima.gesture.generator import KINDS, GeneratorConfig, GeneratorTrainConfig, train_generator
from anima.gesture.knn import search
from anima.gesture.post import finish_knn, one_skeleton
from anima.gesture.refine import CORRECTION_SIGMA, RefinerTrainConfig, pair_draws, train_refiner
from anima.gesture.sync import accuracy, train_sync


def fold_inputs(db, test_videos: set, ks, controls, cfg: RefinerTrainConfig, rng, no_repeat: int, blend: bool,
                by_speaker: bool = True) -> dict:  # fmt: skip
    """Everything one refiner fold reads, from databases without that fold's videos: the training
    pairs (each training window's k-NN syntheses searched in the fold's training videos less the window's own
    speaker's, as the held-out windows' are; less its own video with ``by_speaker`` False), the judged inputs
    (each held-out window's k = ``ks`` outputs and controlled outputs searched in the fold's training videos) and
    the bone lengths every output is re-posed on (measured on the training videos)."""
    T, fps = db.G.shape[1], db.fps
    train = [i for i, (s, _) in enumerate(db.source) if s not in test_videos]
    tr_db = db.subset(train)
    lengths = tr_db.bone_lengths
    by_group = defaultdict(list)
    for i in train:
        by_group[group_of(db.source[i][0], by_speaker)].append(i)
    S, K, R, W = [], [], [], []
    used = set()  # the videos every synthesis drew its windows from
    own_in_pairs = 0  # training syntheses that drew from their own window's speaker (video): 0
    for g, idx in by_group.items():
        sub = db.subset([i for i in train if group_of(db.source[i][0], by_speaker) != g])
        if not sub.M:
            continue
        for i in idx:
            if cfg.k_sampling == "ks":
                p0 = sub.P.reshape(-1, sub.P.shape[-1]).mean(0)
                draws = [(min(k, sub.M - 1), p0) for k in ks]
            else:
                draws = [(min(k, sub.M - 1), p) for k, p in pair_draws(sub, cfg, rng)]
            for k, p in draws:
                G, picks = search(sub, db.F[i], k, p, no_repeat_steps=no_repeat)
                used |= {sub.source[m][0] for m, _ in picks}
                own_in_pairs += any(group_of(sub.source[m][0], by_speaker) == g for m, _ in picks)
                S.append(db.S[i])
                K.append(finish_knn(G, picks, lengths, N_STEP))
                R.append(db.G[i].reshape(T, -1, 3))
                W.append(i)
    p0 = tr_db.P.reshape(-1, tr_db.P.shape[-1]).mean(0)
    test = [i for i, (s, _) in enumerate(db.source) if s in test_videos]
    outs, ctrl = {}, defaultdict(dict)
    masks = {}
    for c in controls:
        m, rep = step_masks(tr_db, [parse_control(c)], T // N_STEP, N_STEP / fps, every_frame=True)
        masks[c] = (m, rep[0]["relaxed_to"] if rep[0]["relaxed_to"] is not None else rep[0]["threshold"])
    for i in test:
        found = [search(tr_db, db.F[i], min(k, tr_db.M - 1), p0, no_repeat_steps=no_repeat) for k in ks]
        outs[i] = [finish_knn(G, picks, lengths, N_STEP, blend) for G, picks in found]
        used |= {tr_db.source[m][0] for _, picks in found for m, _ in picks}
        for c, (m, thr) in masks.items():
            G, picks = search(tr_db, db.F[i], 0, p0, m, no_repeat_steps=no_repeat)
            used |= {tr_db.source[m][0] for m, _ in picks}
            raw = speed_steps([parse_control(c)], T // N_STEP, N_STEP / fps)
            ctrl[c][i] = (finish_knn(G, picks, lengths, N_STEP, blend, raw_steps=raw), thr)
    pairs = (np.stack(S), np.stack(K), np.stack(R), np.array(W)) if S else None
    return {
        "pairs": pairs,
        "outs": outs,
        "ctrl": ctrl,
        "lengths": lengths,
        "test": test,
        "used_videos": used,
        "own_group_in_pairs": own_in_pairs,
    }


SIGMA_GRID = (0.0, 0.75, 1.5, 3.0)  # frames: the refiner's correction smoothing tried on inner validation


def pick_sigma(scores: dict, captured_jerk: float) -> float:
    """The rule fixed before any run: the correction smoothing whose refined wrist jerk is closest
    to the captured jerk of the same validation windows; a tie goes to the smaller sigma."""
    return min(sorted(scores), key=lambda s: abs(scores[s]["jerk"] - captured_jerk))


def choose_correction_sigma(db, held: set, videos: list, cfg: RefinerTrainConfig, no_repeat: int, blend: bool,
                            by_speaker: bool = True) -> dict:  # fmt: skip
    """The refiner's correction smoothing chosen on one outer fold's training videos only: every third of their
    speakers (:func:`inner_validation`; every third video for one speaker) is the inner validation; a refiner
    trained on the other training speakers (clean inputs, :func:`fold_inputs`) refines the validation windows'
    k-NN outputs with each sigma of :data:`SIGMA_GRID`, and :func:`pick_sigma` chooses."""
    train_videos = sorted(v for v in videos if v not in held)
    val = inner_validation(train_videos, by_speaker)
    T, fps = db.G.shape[1], db.fps
    inp = fold_inputs(db, held | val, (0,), [], cfg, np.random.default_rng(cfg.seed + 1), no_repeat, blend, by_speaker)
    val_windows = [i for i in inp["test"] if db.source[i][0] in val]
    if not val_windows or inp["pairs"] is None or len(val) == len(train_videos):
        default = "no inner validation split: the default"
        return {"value": CORRECTION_SIGMA, "grid": list(SIGMA_GRID), "chosen_on": default}
    ref, _ = train_refiner(None, cfg, pairs=inp["pairs"])
    captured = float(np.mean([jerk(db.G[i].reshape(T, -1, 3), fps) for i in val_windows]))
    scores = {}
    for s in SIGMA_GRID:
        ref.correction_sigma = s
        outs = [(i, one_skeleton(ref.refine(db.S[i], inp["outs"][i][0]), inp["lengths"])) for i in val_windows]
        scores[s] = {
            "jerk": round(float(np.mean([jerk(g, fps) for _, g in outs])), 4),
            "l1_cm": round(float(np.mean([l1_cm(g, db.G[i].reshape(T, -1, 3)) for i, g in outs])), 4),
        }
    return {
        "value": pick_sigma(scores, captured),
        "grid": list(SIGMA_GRID),
        "validation": {str(s): v for s, v in scores.items()},
        "validation_captured_jerk": round(captured, 4),
        "validation_videos": len(val),
        "validation_speakers": sorted({speaker_of(v) for v in val}),
        "validation_windows": len(val_windows),
        "chosen_on": f"the inner validation {_unit(by_speaker)} of this fold's training videos (every third, by "
        "name), a refiner trained on the other training "
        f"{_unit(by_speaker)}; the refined wrist jerk closest to the captured jerk of those windows, ties to the "
        "smaller sigma",
    }


def _unit(by_speaker: bool) -> str:
    return "speakers" if by_speaker else "videos"


def _over_seeds(per_seed: list[dict]) -> tuple[dict, dict]:
    """(mean, sample standard deviation) over seeds of each key of the per-seed dicts (0 for one seed)."""
    keys = [k for k in per_seed[0] if all(k in m for m in per_seed)] if per_seed else []
    mean = {k: float(np.mean([m[k] for m in per_seed])) for k in keys}
    sd = {k: float(np.std([m[k] for m in per_seed], ddof=1)) if len(per_seed) > 1 else 0.0 for k in keys}
    return mean, sd


def refiner_rows(
    db,
    kept: dict,
    ks,
    folds: int,
    steps: int | None,
    progress: bool,
    cfg: RefinerTrainConfig | None = None,
    seeds: int = 1,
) -> dict:
    """k-NN + cGAN, cross-validated by speaker (:func:`speaker_folds`; by video for one speaker): the videos are
    split into ``folds`` groups; each group's windows are refined by refiners trained on the other groups' (k-NN,
    captured) pairs, one per training seed (``cfg.seed`` .. ``cfg.seed + seeds - 1``; the fold's inputs and its
    correction smoothing are the same for every seed). Clean folds (:func:`fold_inputs`): no window, bone length
    or k-NN synthesis of a held-out video enters the refiner's training or its inputs; the judged inputs are k-NN
    outputs searched in the fold's training videos (their own row, ``knn_fold_inputs``, beside the refined one).
    Training pairs follow ``cfg.k_sampling`` (default the seed's draws; ``"ks"``: the k = ``ks`` outputs from the
    mean pose). ``metrics``: the mean over seeds of each seed's mean over the judged windows;
    ``metrics_sd_over_seeds`` their standard deviation; ``metrics_ci95_over_videos`` over the test videos of the
    windows' seed means, ``metrics_ci95_over_speakers`` over their speakers (empty for one speaker); the control
    adherence pools every seed's syntheses."""
    T = db.G.shape[1]
    cfg = cfg or RefinerTrainConfig()
    if steps is not None:
        cfg = dataclasses.replace(cfg, steps=steps)
    seed_list = [cfg.seed + n for n in range(max(1, seeds))]
    windows = sorted(kept["outs"])
    videos = sorted({db.source[i][0] for i in windows})
    srcs = [db.source[i][0] for i in windows]
    by_speaker = len({speaker_of(s) for s in srcs}) > 1  # one speaker (--speaker): the seed's protocol, by video
    folds = fold_count(srcs, folds, by_speaker)
    fold_of = speaker_folds(srcs, folds, by_speaker)
    res, base = {s: defaultdict(list) for s in seed_list}, defaultdict(list)
    adherence = {c: {"values": []} for c in ["none"] + list(kept["ctrl"])}
    judged_videos = []
    logs = []
    rng = np.random.default_rng(0)
    for f in range(folds):
        held = {v for v in videos if fold_of[v] == f}
        inp = fold_inputs(db, held, ks, list(kept["ctrl"]), cfg, rng, kept["no_repeat"], kept["blend"], by_speaker)
        test = [i for i in inp["test"] if i in kept["outs"]]
        if not test or inp["pairs"] is None:  # e.g. one training speaker left: no k-NN pair without its own
            why = (
                "no test window"
                if not test
                else f"no training pair (a training window's k-NN input is searched in the other training "
                f"{_unit(by_speaker)}: one is left)"
            )
            logs.append({"fold": f, "held_out_videos": len(held), "skipped": why, "test_windows": 0})
            continue
        sigma = choose_correction_sigma(db, held, videos, cfg, kept["no_repeat"], kept["blend"], by_speaker)
        per_seed = []
        for seed in seed_list:
            scfg = dataclasses.replace(cfg, seed=seed)
            bar = tqdm(total=cfg.steps, desc=f"refiner fold {f + 1}/{folds} seed {seed}", disable=not progress,
                       leave=False)  # fmt: skip
            ref, info = train_refiner(None, scfg, progress=lambda s: bar.update(1), pairs=inp["pairs"])
            bar.close()
            ref.correction_sigma = sigma["value"]
            per_seed.append(
                {"seed": seed, "wall_s": info["wall_s"], "critic_last": float(np.mean(info["log"]["critic"][-50:]))}
            )
            for i in test:
                _judge_refined(db, i, ref, inp, kept, scfg, res[seed], base if seed == seed_list[0] else None,
                               adherence, seed)  # fmt: skip
        judged_videos += [db.source[i][0] for i in test]
        logs.append(
            {
                "fold": f,
                "held_out_videos": len(held),
                "held_out_speakers": sorted({speaker_of(v) for v in held}),
                "held_out_videos_in_inputs": len(held & inp["used_videos"]),  # 0: clean
                "own_group_in_training_pairs": inp["own_group_in_pairs"],  # 0: pairs searched as the tests are
                "train_pairs": int(len(inp["pairs"][0])),
                "test_windows": len(test),
                "wall_s": round(sum(x["wall_s"] for x in per_seed), 1),  # every seed's training
                "per_seed": per_seed,
                "correction_sigma": sigma,
            }
        )
    seed_means = [{k: float(np.nanmean(v)) for k, v in res[s].items()} for s in seed_list if res[s]]
    metrics, sd = _over_seeds(seed_means)
    window_means = {k: np.mean([np.asarray(res[s][k], float) for s in seed_list], 0) for k in metrics}
    return {
        "protocol": _refiner_protocol(
            cfg, folds, by_speaker, seed_list, len({group_of(v, by_speaker) for v in videos})
        ),
        "seeds": seed_list,
        "train_config": {k: v for k, v in dataclasses.asdict(cfg).items() if k != "model"},
        "metrics": metrics,
        "metrics_sd_over_seeds": sd,
        "metrics_per_seed": [{"seed": s, **m} for s, m in zip(seed_list, seed_means)],
        "knn_fold_inputs": {k: float(np.nanmean(v)) for k, v in base.items()},
        "metrics_ci95_over_videos": {
            k: bootstrap_over_groups(v, np.array(judged_videos))
            for k, v in window_means.items()
            if np.isfinite(v).all()
        },
        "metrics_ci95_over_speakers": {  # the folds' unit: whole held-out speakers resampled
            k: bootstrap_over_groups(v, np.array([speaker_of(s) for s in judged_videos]))
            for k, v in window_means.items()
            if by_speaker and np.isfinite(v).all()
        },
        "control_adherence": adherence_table(adherence, T) if judged_videos else {},
        "folds": logs,
        "windows_judged": len(judged_videos),
        "fold_speakers": fold_speakers(fold_of, folds),
    }


def _judge_refined(db, i: int, ref, inp: dict, kept: dict, cfg: RefinerTrainConfig, res, base, adherence,
                   seed: int = 0) -> None:  # fmt: skip
    """Window ``i`` of a fold's test windows refined by ``ref`` from its k-NN inputs (``inp``): its metrics
    appended to ``res`` (and the k-NN inputs' to ``base``, unless None), and its control features, plain and
    under each control, to ``adherence``; with the seed's k sampling its refined output is kept (per ``seed``)
    for FGD."""
    T, fps = db.G.shape[1], db.fps
    gt = db.G[i].reshape(T, -1, 3)
    knn = inp["outs"][i]
    outs = [one_skeleton(ref.refine(db.S[i], o), inp["lengths"]) for o in knn]
    g = outs[0]
    if cfg.k_sampling == "seed":
        kept.setdefault("refined", {}).setdefault(seed, {})[i] = g
    res["l1_cm"].append(l1_cm(g, gt))
    res["l1_to_knn_cm"].append(l1_cm(g, knn[0]))
    res["diversity_cm"].append(diversity_cm(outs))
    res["jerk"].append(jerk(g, fps))
    res["jerk_knn"].append(jerk(knn[0], fps))
    res["wrist_motion_cm"].append(wrist_motion(g))
    res["jerk_captured"].append(jerk(gt, fps))
    res["beat_consistency"].append(beat_consistency(g, kept["onsets"][i], fps))
    if base is not None:
        base["l1_cm"].append(l1_cm(knn[0], gt))
        base["diversity_cm"].append(diversity_cm(knn))
        base["jerk"].append(jerk(knn[0], fps))
        base["wrist_motion_cm"].append(wrist_motion(knn[0]))
        base["beat_consistency"].append(beat_consistency(knn[0], kept["onsets"][i], fps))
    adherence["none"]["values"].append(control_features(g.reshape(1, T, -1), fps))
    for c, per in inp["ctrl"].items():
        out, thr = per[i]
        refined = one_skeleton(ref.refine(db.S[i], out), inp["lengths"])
        adherence[c]["values"].append(control_features(refined.reshape(1, T, -1), fps))
        adherence[c].setdefault("thresholds", []).append(thr)
        adherence[c].setdefault("videos", []).append(db.source[i][0])


def _refiner_protocol(cfg: RefinerTrainConfig, folds: int, by_speaker: bool, seeds: list, groups: int) -> str:
    return (
        f"{fold_protocol(folds, groups, by_speaker)}; {seeds_words(seeds)}; WGAN-GP, {cfg.critic_steps} critic "
        f"steps per generator step, {cfg.steps} generator steps, loss weights L1 {cfg.l1} / adversarial {cfg.adv} / "
        f"gradient penalty {cfg.gp}, training pairs: "
        + (
            "the seed's k (1 for half, 2..15) from random initial poses"
            if cfg.k_sampling == "seed"
            else f"k in {list(cfg.ks)} from the mean pose"
        )
        + f", each searched in the fold's other training {_unit(by_speaker)}; clean folds: training pairs, judged "
        "k-NN inputs and bone lengths from the other folds' videos only; the correction smoothing chosen per fold "
        f"on inner validation {_unit(by_speaker)} of its own training videos (each fold's 'correction_sigma')"
    )


def fold_protocol(folds: int, groups: int, by_speaker: bool) -> str:
    """The learned rows' folds in words: leave-one-speaker-out where there is one fold per speaker, else
    ``folds``-fold cross-validation with each speaker's videos held out together (by video for one speaker)."""
    if by_speaker:
        if folds == groups:
            return f"leave-one-speaker-out, {folds} folds (one per speaker)"
        return (
            f"{folds}-fold cross-validation by speaker ({groups} speakers; each speaker's videos in one fold, held "
            "out together)"
        )
    if folds == groups:
        return f"leave-one-video-out within one speaker, {folds} folds (the seed's person-specific protocol)"
    return f"{folds}-fold cross-validation by video within one speaker (the seed's person-specific protocol)"


def seeds_words(seeds: list) -> str:
    return f"training seeds {list(seeds)} per fold (rows: mean over seeds; spread: standard deviation over seeds)"


def fold_speakers(fold_of: dict, folds: int) -> list[list[str]]:
    """Each fold's speakers (the results say who was judged by models that never saw them)."""
    return [sorted({speaker_of(v) for v, f in fold_of.items() if f == k}) for k in range(folds)]


def sync_rows(db, folds: int, lengths=(16, 32, 64), steps: int = 300, seeds: int = 1) -> dict:
    """Table 4.4: the discriminator trained as an in-sync / off-sync classifier, cross-validated by speaker
    (the same folds as the refiner), one classifier per fold and training seed (seed ``n * folds + fold`` for
    n = 0 .. seeds - 1); accuracy on 2 x 200 held-out crops per fold and length (chance 0.5), window-weighted
    over folds, then the mean over seeds (``accuracy_sd_over_seeds``: its spread)."""
    srcs = [v for v, _ in db.source]
    by_speaker = len({speaker_of(s) for s in srcs}) > 1
    fold_of = speaker_folds(srcs, folds, by_speaker)
    fold = np.array([fold_of[v] for v in srcs])
    rows = {}
    for L in lengths:
        per_seed = []
        for n in range(max(1, seeds)):
            accs, ns = [], []
            for f in range(folds):
                tr, te = fold != f, fold == f
                if tr.sum() < 2 or te.sum() < 2:
                    continue
                S_mean = db.S[tr].reshape(-1, SPEECH_DIM).mean(0)
                S_std = db.S[tr].reshape(-1, SPEECH_DIM).std(0) + 1e-4
                G_mean, G_std = db.G[tr].reshape(-1, BODY_DIM).mean(0), db.G[tr].reshape(-1, BODY_DIM).std(0) + 1e-4

                def norm(m):
                    return ((db.S[m] - S_mean) / S_std).astype(np.float32), ((db.G[m] - G_mean) / G_std).astype(
                        np.float32
                    )

                net, _ = train_sync(*norm(tr), L, steps=steps, seed=n * folds + f)
                accs.append(accuracy(net, *norm(te), L))
                ns.append(int(te.sum()))
            per_seed.append((float(np.average(accs, weights=ns)) if accs else float("nan"), accs, ns))
        acc = [a for a, _, _ in per_seed]
        rows[f"{L}_frames"] = {
            "accuracy": float(np.mean(acc)),
            "accuracy_sd_over_seeds": float(np.std(acc, ddof=1)) if len(acc) > 1 else 0.0,
            "accuracy_per_seed": [round(a, 4) for a in acc],
            "per_fold": [round(float(np.mean([p[1][k] for p in per_seed])), 3) for k in range(len(per_seed[0][1]))],
            "test_windows": per_seed[0][2],
            "seeds": list(range(len(per_seed))),  # seed n: fold f's classifier trained with n * folds + f
        }
    return rows


ADV_WEIGHTS = (0.01, 0.1, 1.0)  # the adversarial weights tried on each fold's inner validation videos


def choose_adv_weight(
    w: Windows,
    tr: np.ndarray,
    n_to_i: dict,
    knn_db,
    cfg,
    grid,
    progress,
    fold: int,
    fgd_steps: int = 1500,
    by_speaker: bool = True,
) -> dict:
    """Nested choice of the §4.4 generator's adversarial weight, on one outer fold's training videos only:
    every third of the speakers with body windows among them (:func:`inner_validation`; every third video for
    one speaker) is the inner validation, with all of those speakers' windows; the other training speakers train
    one generator per weight of ``grid``; the weight whose validation motion is closest to the captured (FGD of
    the code's time steps, with an autoencoder trained on the inner training windows) wins. Every weight's FGD
    and L1 are kept."""
    T = knn_db.G.shape[1]
    groups = np.array([group_of(s, by_speaker) for s in w.source])
    body_videos = sorted({s for s, h, t in zip(w.source, w.has_body, tr) if h and t})
    val_groups = sorted({group_of(v, by_speaker) for v in inner_validation(body_videos, by_speaker)})
    val = tr & np.isin(groups, val_groups)
    itr = tr & ~val
    val_n = [n for n in np.flatnonzero(val & w.has_body) if n in n_to_i]
    fit_n = [n for n in np.flatnonzero(itr & w.has_body) if n in n_to_i]
    if not val_n or not fit_n:
        return {"value": cfg.adv_weight, "grid": list(grid), "chosen_on": "no inner validation split: the default"}
    fgd = train_fgd(np.stack([knn_db.G[n_to_i[n]] for n in fit_n]).reshape(len(fit_n), T, -1), steps=fgd_steps)
    real = np.stack([knn_db.G[n_to_i[n]].reshape(T, -1) for n in val_n])
    scores = {}
    for a in grid:
        bar = tqdm(total=cfg.steps, desc=f"adv weight {a} fold {fold + 1}", disable=not progress, leave=False)
        gen, _ = train_generator(
            w.speech[itr],
            w.body[itr],
            w.face[itr],
            GeneratorConfig(kind="adversarial", fps=w.fps),
            dataclasses.replace(cfg, adv_weight=a),
            progress=lambda s: bar.update(1),
        )
        bar.close()
        J = [gen.generate(w.speech[n])[0] for n in val_n]
        scores[a] = {
            "fgd_frames": round(fgd.frame_distance(real, np.stack([j.reshape(T, -1) for j in J])), 4),
            "l1_cm": round(
                float(np.mean([l1_cm(j, knn_db.G[n_to_i[n]].reshape(T, -1, 3)) for j, n in zip(J, val_n)])), 4
            ),
        }
    best = min(grid, key=lambda a: scores[a]["fgd_frames"])
    return {
        "value": best,
        "grid": list(grid),
        "validation": {str(a): v for a, v in scores.items()},
        "validation_videos": len({w.source[n] for n in val_n}),
        "validation_speakers": sorted({speaker_of(w.source[n]) for n in val_n}),
        "validation_windows": len(val_n),
        "chosen_on": f"the inner validation {_unit(by_speaker)} of this fold's training videos (every third with "
        f"body windows, by name), generators trained on the other training {_unit(by_speaker)}; lowest FGD of the "
        "code's time steps",
    }


def _generator_folds(w: Windows, knn_db, kept: dict, folds: int) -> tuple[dict, bool]:
    """``({video: fold}, by speaker)``: the refiner's folds over the body videos' speakers, then the face-only
    videos' other speakers (a speaker's face-only videos in that speaker's fold; by video for one speaker)."""
    body = [knn_db.source[i][0] for i in sorted(kept["outs"])]
    by_speaker = len({speaker_of(s) for s in body}) > 1
    fold_of = speaker_folds(body, folds, by_speaker)
    if by_speaker:
        placed = {speaker_of(v): f for v, f in fold_of.items()}
        fold_of |= speaker_folds([s for s in w.source if s not in fold_of], folds, True, placed)
    else:
        other = sorted(set(w.source) - set(fold_of))
        fold_of |= {v: n % folds for n, v in enumerate(other)}
    return fold_of, by_speaker


def _body_metrics(res, kind: str, judged: list, outs: dict, gens: list, info: list, fold, w: Windows, knn_db,
                  kept: dict) -> None:  # fmt: skip
    """One method's body metrics on the judged windows (``(k-NN row, window)`` pairs) appended to ``res``: L1,
    jerk, wrist motion, beat consistency, and for the stochastic MoGlow-style row the diversity over five
    sampling seeds of the fold's model that judged the window."""
    T, fps = knn_db.G.shape[1], knn_db.fps
    for i, n in judged:
        g, gt = outs[n], knn_db.G[i].reshape(T, -1, 3)
        if kind == "moglow":  # stochastic: five sampling seeds of the model that judged this window
            fold_gen = gens[[x["fold"] for x in info].index(fold[n])]
            res["diversity_cm"].append(diversity_cm([g] + [fold_gen.generate(w.speech[n], s)[0] for s in range(1, 5)]))
        res["l1_cm"].append(l1_cm(g, gt))
        res["jerk"].append(jerk(g, fps))
        res["wrist_motion_cm"].append(wrist_motion(g))
        res["beat_consistency"].append(beat_consistency(g, kept["onsets"][i], fps))


def _fgd_per_fold(knn_db, kept: dict, judged: list, fold, fold_of: dict, gen_windows: dict, kinds, refined_outs,
                  fgd_steps: int):  # fmt: skip
    """FGD per fold: each fold's feature network is trained on the other folds' videos only and measures that
    fold's judged windows, for every training seed's outputs (``gen_windows``: ``{seed: {kind: {window: J}}}``;
    ``refined_outs``: ``{seed: {row: J}}``); a row is the window-weighted mean over folds, per seed, then the mean
    over seeds. Returns (rows, their standard deviation over seeds, per seed, per fold, the last fold's network)."""
    T = knn_db.G.shape[1]
    fgd_folds = []
    perm_rng = np.random.default_rng(0)
    seeds = list(gen_windows)
    net = None
    for f in sorted({int(fold[n]) for _, n in judged}):
        jf = [(i, n) for i, n in judged if fold[n] == f]
        tr_rows = [i for i, (s, _) in enumerate(knn_db.source) if fold_of[s] != f]
        net = train_fgd(knn_db.G[tr_rows].reshape(len(tr_rows), T, -1), steps=fgd_steps)
        real = np.stack([knn_db.G[i].reshape(T, -1) for i, _ in jf])
        per_seed = {
            k: [net.distance(real, np.stack([gen_windows[s][k][n].reshape(T, -1) for _, n in jf])) for s in seeds]
            for k in kinds
        }
        if refined_outs:  # a fold the refiner skipped: not in its mean
            r = [
                net.distance(real, np.stack([outs[i].reshape(T, -1) for i, _ in jf]))
                for _, outs in sorted(refined_outs.items())
                if all(i in outs for i, _ in jf)
            ]
            if r:
                per_seed["knn_cgan"] = r
        one = {k: float(np.mean(v)) for k, v in per_seed.items()}
        one["knn"] = net.distance(real, np.stack([kept["outs"][i][0].reshape(T, -1) for i, _ in jf]))
        # two random halves of the fold's captured windows against each other: what sampling noise alone gives
        half = len(real) // 2
        perm = perm_rng.permutation(len(real))
        one["captured_half_vs_half"] = (
            net.distance(real[perm[:half]], real[perm[half : 2 * half]]) if half >= 2 else float("nan")
        )
        fgd_folds.append({"fold": f, "windows": len(jf), "train_windows": len(tr_rows), **one, "per_seed": per_seed})
    fgd_rows, fgd_sd, fgd_seeds = {}, {}, {}
    for k in {k for x in fgd_folds for k in x} - {"fold", "windows", "train_windows", "per_seed"}:
        has = [x for x in fgd_folds if k in x]  # the refined row: only the folds the refiner judged
        total = sum(x["windows"] for x in has)
        fgd_rows[k] = sum(x[k] * x["windows"] / total for x in has)
        n = {len(x["per_seed"].get(k, [])) for x in has}
        if len(n) == 1 and min(n) > 0:  # the same seeds in every fold: each seed's window-weighted mean
            fgd_seeds[k] = [sum(x["per_seed"][k][j] * x["windows"] / total for x in has) for j in range(min(n))]
            fgd_sd[k] = float(np.std(fgd_seeds[k], ddof=1)) if len(fgd_seeds[k]) > 1 else 0.0
    return fgd_rows, fgd_sd, fgd_seeds, fgd_folds, net


def _generator_protocol(cfg: GeneratorTrainConfig, folds: int, by_speaker: bool, adv_weights, kinds, seeds: list,
                        groups: int) -> str:  # fmt: skip
    return (
        f"{fold_protocol(folds, groups, by_speaker)}, the refiner's folds (face-only windows from talking-head clips "
        f"train the face decoder); {seeds_words(seeds)}; {cfg.steps} steps, batch {cfg.batch}, Adam "
        f"{cfg.lr}, adversarial weight "
        + (
            f"chosen per fold among {list(adv_weights)} on inner validation {_unit(by_speaker)} of that fold's own "
            "training videos (training seed 0; each fold's 'adv_weight')"
            if adv_weights and "adversarial" in kinds
            else f"{cfg.adv_weight} (not chosen on data)"
        )
        + f" (velocity-adversarial baseline: {cfg.velocity_adv_weight}, Ginosar et al.'s); "
        "the U-Net and LSTM rows are deterministic (diversity 0); the MoGlow-style row is judged on sampling seed "
        "0, its diversity over sampling seeds 0-4"
    )


def _fold_generator(w: Windows, tr, kind: str, cfg: GeneratorTrainConfig, choice: dict | None, progress: bool,
                    desc: str) -> tuple:  # fmt: skip
    """A ``kind`` generator trained on the windows ``tr`` (the adversarial weight ``choice["value"]`` where one
    was chosen) and what its fold's log says of it."""
    bar = tqdm(total=cfg.steps, desc=desc, disable=not progress, leave=False)
    kcfg = dataclasses.replace(cfg, adv_weight=choice["value"]) if choice else cfg
    gen, inf = train_generator(
        w.speech[tr], w.body[tr], w.face[tr], GeneratorConfig(kind=kind, fps=w.fps), kcfg,
        progress=lambda s: bar.update(1),
    )  # fmt: skip
    bar.close()
    log = {
        "train_windows": inf["windows"],
        "train_body_windows": inf["body_windows"],
        "wall_s": inf["wall_s"],
        "loss_weights": inf["loss_weights"],
        **({"adv_weight": choice} if choice else {}),
    }
    return gen, log


def generator_rows(
    w: Windows,
    kept: dict,
    knn_db,
    folds: int,
    steps: int | None,
    progress: bool,
    refined_outs: dict | None,
    kinds: tuple = KINDS,
    adv_weights: tuple | None = ADV_WEIGHTS,
    fgd_steps: int = 1500,
    facegood_seconds: float | None = None,
    seeds: int = 1,
) -> dict:
    """The §4.4 generator (adversarial), direct regression (no adversarial term), the LSTM baseline, the
    velocity-adversarial baseline (Ginosar et al.) and the MoGlow-style flow,
    cross-validated with the refiner's folds (by speaker); FGD for every method; lip error (table 4.3).
    ``w``: every window of the dataset (face-only ones train the face decoder). ``adv_weights``: the §4.4
    generator's adversarial weight is chosen among these in each fold on its own training videos
    (:func:`choose_adv_weight`); ``None``: the config's (0.1) for every fold. ``seeds``: every model of every
    fold is trained with training seeds ``cfg.seed`` .. ``cfg.seed + seeds - 1`` (the adversarial weight is chosen
    once per fold); a row is the mean over seeds of each seed's value, ``sd_over_seeds`` its spread.
    ``refined_outs``: the refiner's outputs per seed (``{seed: {row: J}}``), for its FGD."""
    T, fps = knn_db.G.shape[1], knn_db.fps
    model = load_face_model()
    key = {(s, round(st, 3)): n for n, (s, st) in enumerate(zip(w.source, w.start_s))}
    fold_of, by_speaker = _generator_folds(w, knn_db, kept, folds)
    fold = np.array([fold_of[s] for s in w.source])
    has_body = w.has_body
    cfg = GeneratorTrainConfig() if steps is None else GeneratorTrainConfig(steps=steps)
    seed_list = [cfg.seed + n for n in range(max(1, seeds))]
    res = {s: {k: defaultdict(list) for k in kinds} for s in seed_list}
    gen_windows = {s: {k: {} for k in kinds} for s in seed_list}
    lip = {s: {k: [] for k in kinds} for s in seed_list}
    lip_random = []
    rng = np.random.default_rng(0)
    gens = {s: {k: [] for k in kinds} for s in seed_list}
    info = {k: [] for k in kinds}
    n_to_i = {key[(s, round(st, 3))]: i for i, (s, st) in enumerate(knn_db.source) if (s, round(st, 3)) in key}
    for f in range(folds):
        tr, te = fold != f, np.flatnonzero(fold == f)
        if not tr.any() or not len(te) or not has_body[tr].any():
            continue
        choice = None
        if adv_weights and "adversarial" in kinds:
            choice = choose_adv_weight(w, tr, n_to_i, knn_db, cfg, adv_weights, progress, f, fgd_steps, by_speaker)
        for seed in seed_list:
            scfg = dataclasses.replace(cfg, seed=seed)
            for kind in kinds:
                gen, inf = _fold_generator(w, tr, kind, scfg, choice if kind == "adversarial" else None, progress,
                                           f"{kind} fold {f + 1}/{folds} seed {seed}")  # fmt: skip
                gens[seed][kind].append(gen)
                info[kind].append({"fold": f, "seed": seed, **inf})
                for n in te:
                    J, face = gen.generate(w.speech[n])
                    lip[seed][kind].append(lip_error_mm(face, w.face[n], model))
                    if has_body[n]:
                        gen_windows[seed][kind][n] = J
        for n in te:  # sanity row of table 4.3: the captured face of a random window of another video
            cand = np.flatnonzero(np.array(w.source) != w.source[n])
            lip_random.append(lip_error_mm(w.face[rng.choice(cand)], w.face[n], model))
    # body metrics on the windows the k-NN rows judged (the same windows, the same captured motion)
    judged = []
    for i in sorted(kept["outs"]):
        n = key.get((knn_db.source[i][0], round(knn_db.source[i][1], 3)))
        if n is not None and all(n in gen_windows[s][k] for s in seed_list for k in kinds):
            judged.append((i, n))
    for seed in seed_list:
        for kind in kinds:
            seed_info = [x for x in info[kind] if x["seed"] == seed]
            _body_metrics(res[seed][kind], kind, judged, gen_windows[seed][kind], gens[seed][kind], seed_info, fold,
                          w, knn_db, kept)  # fmt: skip
    fgd_rows, fgd_sd, fgd_seeds, fgd_folds, net = _fgd_per_fold(
        knn_db, kept, judged, fold, fold_of, gen_windows, kinds, refined_outs, fgd_steps
    )
    rows = {}
    for kind in kinds:
        per_seed = [
            {
                "diversity_cm": 0.0,
                **{k: float(np.nanmean(v)) for k, v in res[seed][kind].items()},
                "lip_error_mm": float(np.mean(lip[seed][kind])),
                **({"fgd": fgd_seeds[kind][j]} if kind in fgd_seeds else {}),
            }
            for j, seed in enumerate(seed_list)
        ]
        mean, sd = _over_seeds(per_seed)
        rows[kind] = {
            **mean,
            "fgd": fgd_rows.get(kind, float("nan")),
            "sd_over_seeds": sd,
            "per_seed": [{"seed": seed, **m} for seed, m in zip(seed_list, per_seed)],
            "folds": info[kind],
        }
    face_only = defaultdict(lambda: defaultdict(list))
    for s_, st, h in zip(w.source, w.start_s, has_body):
        if not h:
            face_only[speaker_of(s_)][s_].append(st)
    groups = len({group_of(v, by_speaker) for v in {knn_db.source[i][0] for i in kept["outs"]}})
    return {
        "protocol": _generator_protocol(cfg, folds, by_speaker, adv_weights, kinds, seed_list, groups),
        "seeds": seed_list,
        "windows_judged": len(judged),
        "lip_windows": len(lip[seed_list[0]][kinds[0]]),
        "rows": rows,
        "lip_error_mm_random_other_video": float(np.mean(lip_random)),
        "face_only_windows_per_speaker": {k: sum(len(x) for x in v.values()) for k, v in sorted(face_only.items())},
        "face_only_minutes_per_speaker": {k: minutes_covered(v.items(), T / fps) for k, v in sorted(face_only.items())},
        "fgd": dict(fgd_rows),
        "fgd_sd_over_seeds": fgd_sd,
        "fgd_protocol": "per fold: the feature network trained on the other folds' videos, distances on the "
        "fold's judged windows; window-weighted mean over folds, per training seed, then the mean over seeds",
        "fgd_folds": fgd_folds,
        "fgd_autoencoder": net.info if net is not None else None,
        "facegood_lip_sync": _facegood_over_seeds(gens, fps, facegood_seconds),
    }


def _facegood_over_seeds(gens: dict, fps: float, seconds: float | None) -> dict | None:
    """:func:`facegood_sync` for each training seed's models (``{seed: {kind: [one per fold]}}``): each row's
    correlations are the mean over seeds (``*_sd_over_seeds``: their spread), its best lags every seed's."""
    per = {seed: facegood_sync(g, fps, seconds=seconds) for seed, g in gens.items()}
    first = next(iter(per.values()), None)
    if first is None:
        return None
    rows = {}
    for kind in first["rows"]:
        vals = [x["rows"][kind] for x in per.values()]
        mean, sd = _over_seeds([{k: v for k, v in x.items() if k != "best_lag_frames"} for x in vals])
        rows[kind] = {
            **mean,
            "best_lag_frames": [lag for x in vals for lag in x["best_lag_frames"]],  # seed by seed
            **{f"{k}_sd_over_seeds": v for k, v in sd.items()},
            "per_seed": [{"seed": seed, **x["rows"][kind]} for seed, x in per.items()],
        }
    return {**first, "rows": rows, "seeds": list(per)}
