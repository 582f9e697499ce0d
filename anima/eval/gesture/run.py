"""``anima eval gesture``: seed 004 ch. 4-5 on the dataset's (audio, motion) windows. The k-NN search is
evaluated leave-one-speaker-out (each speaker's windows synthesised from their speech with a database of the
other speakers' windows only) and compared with the captured motion; the learned models (k-NN + cGAN refiner,
the §4.4 generator, direct regression, the LSTM baseline, the sync classifier) are cross-validated by speaker in
3 folds (each speaker's videos in one fold, held out together; the settings chosen inside a fold are chosen on
inner validation speakers of its training speakers) and trained with 3 training seeds per fold (mean and spread
over seeds). With ``--speaker`` (one speaker's windows) the folds hold out videos within that speaker instead.

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

from anima.dataset.windows import read_windows
from anima.errors import InputError
from anima.eval.config import GestureEval
from anima.eval.gesture.learned import generator_rows, refiner_rows, sync_rows
from anima.eval.gesture.metrics import (
    adherence_table,
    audio_onsets,
    beat_consistency,
    bootstrap_over_groups,
    diversity_cm,
    fold_count,
    group_of,
    jerk,
    l1_cm,
    minutes_covered,
    speaker_of,
    wrist_motion,
)
from anima.gesture.config import GestureConfig
from anima.gesture.control import control_features, parse_control, speed_steps, step_masks
from anima.gesture.database import from_dataset
from anima.gesture.features import N_STEP
from anima.gesture.knn import search
from anima.gesture.post import finish_knn
from anima.gesture.refine import RefinerTrainConfig

NO_REPEAT_S = GestureConfig().no_repeat_s
CONTROLS = ["left_wrist_height>=p85", "left_wrist_height<=p15", "left_wrist_speed>=p85", "left_wrist_speed<=p15"]


def knn_rows(db, ks, blend: bool = True, seed_rule: bool = True, by_speaker: bool = True) -> tuple[dict, dict, dict]:
    """Leave-one-speaker-out k-NN synthesis of every window (``by_speaker`` False: leave-one-video-out, for one
    speaker's windows): each speaker's windows are synthesised with a database of the other speakers' windows
    only. Returns (metrics per window, table 5.3 adherence, what the learned rows reuse: per window the k-NN
    outputs, the controlled outputs and the audio onsets, and ``held_out``: each fold's group and its
    database's videos). Table 5.3 is measured with the command's rule (every frame of a step satisfies the
    control) and, with ``seed_rule``, also with the seed's (first and last frame of a step) under
    ``"seed_rule"``."""
    T, fps = db.G.shape[1], db.fps
    no_repeat = round(NO_REPEAT_S * fps / N_STEP) if blend else 0  # the command's defaults (--no-blend: the seed)
    by_group = defaultdict(list)
    for i, (src, _) in enumerate(db.source):
        by_group[group_of(src, by_speaker)].append(i)
    res = defaultdict(list)
    adherence = {c: {"values": []} for c in ["none"] + CONTROLS}
    seed_adherence = {c: {"values": []} for c in CONTROLS}
    rules = [("command", True)] + ([("seed", False)] if seed_rule else [])
    kept = {"outs": {}, "ctrl": defaultdict(dict), "onsets": {}, "videos": [], "no_repeat": no_repeat, "blend": blend}
    kept["held_out"] = []  # per fold: the held-out group and the videos of its database (tests: disjoint)
    distinct = defaultdict(list)  # database windows used per synthesis (variety), uncontrolled and per control
    for group, idx in sorted(by_group.items()):
        own = set(idx)
        sub = db.subset([i for i in range(db.M) if i not in own])
        kept["held_out"].append({"group": group, "database_videos": sorted({s for s, _ in sub.source})})
        p0 = sub.P.reshape(-1, sub.P.shape[-1]).mean(0)
        controlled = {}  # per control: this database's step masks and threshold (the same for all its queries)
        for c in CONTROLS:
            for rule, every in rules:
                masks, rep = step_masks(sub, [parse_control(c)], T // N_STEP, N_STEP / fps, every_frame=every)
                relaxed = rep[0]["relaxed_to"]
                controlled[rule, c] = (masks, relaxed if relaxed is not None else rep[0]["threshold"])
        for i in idx:
            F_in, gt = db.F[i], db.G[i].reshape(T, -1, 3)
            found = [search(sub, F_in, k, p0, no_repeat_steps=no_repeat) for k in ks]
            outs = [finish_knn(G, picks, sub.bone_lengths, N_STEP, blend) for G, picks in found]
            g = outs[0]
            distinct["none"].append(len({m for m, _ in found[0][1]}))
            on = audio_onsets(db.S[i], fps)
            res["l1_cm"].append(l1_cm(g, gt))
            res["diversity_cm"].append(diversity_cm(outs))
            res["jerk"].append(jerk(g, fps))
            res["jerk_captured"].append(jerk(gt, fps))
            res["wrist_motion_cm"].append(wrist_motion(g))
            res["wrist_motion_cm_captured"].append(wrist_motion(gt))
            kept["outs"][i], kept["onsets"][i] = outs, on
            kept["videos"].append(db.source[i][0])  # the video of each row of the metrics, in their order
            res["beat_consistency"].append(beat_consistency(g, on, fps))
            res["beat_consistency_captured"].append(beat_consistency(gt, on, fps))
            adherence["none"]["values"].append(control_features(g.reshape(1, T, -1), fps))
            for (rule, c), (masks, thr) in controlled.items():
                G, picks = search(sub, F_in, 0, p0, masks, no_repeat_steps=no_repeat)
                distinct[rule, c].append(len({m for m, _ in picks}))
                raw = speed_steps([parse_control(c)], T // N_STEP, N_STEP / fps)
                out = finish_knn(G, picks, sub.bone_lengths, N_STEP, blend, raw_steps=raw).reshape(1, T, -1)
                a = adherence if rule == "command" else seed_adherence
                a[c]["values"].append(control_features(out, fps))
                a[c].setdefault("thresholds", []).append(thr)
                a[c].setdefault("videos", []).append(db.source[i][0])
                if rule == "command":
                    kept["ctrl"][c][i] = (out[0].reshape(T, -1, 3), thr)
    table = adherence_table(adherence, T)
    table["none"]["distinct_windows_per_synthesis"] = float(np.mean(distinct["none"]))
    if seed_rule:
        table["seed_rule"] = adherence_table(seed_adherence, T)
        table["seed_rule"]["rule"] = "a control checked on the first and last frame of each step (seed 004 §5.3.2.1)"
    for (rule, c), v in ((k, v) for k, v in distinct.items() if k != "none"):
        (table[c] if rule == "command" else table["seed_rule"][c])["distinct_windows_per_synthesis"] = float(np.mean(v))
    return res, table, kept


def evaluate(
    folder: str,
    ks=(0, 1, 2, 3, 4),
    refiner_folds: int = 3,
    refiner_steps: int | None = None,
    progress: bool = False,
    sync_steps: int = 300,
    generator_steps: int | None = None,
    speaker: str | None = None,
    blend: bool = True,
    refiner_ablation: bool = False,
    fgd_steps: int = 1500,
    facegood_seconds: float | None = None,
    seeds: int = 3,
) -> dict:
    """``refiner_ablation``: also the refiner with anima's earlier loss weights and k (``knn_cgan_anima_v1``).
    ``speaker``: evaluate on that speaker's windows only (databases, training and tests), the seed's
    subject-specific protocol; default: all speakers together. ``seeds``: every learned model is trained with
    training seeds 0 .. seeds - 1 in every fold; its rows are the mean over seeds, with their spread."""
    db = from_dataset(folder, None)
    if speaker is not None:
        keep = [i for i, (s, _) in enumerate(db.source) if speaker_of(s) == speaker]
        if not keep:
            known = sorted({speaker_of(s) for s, _ in db.source})
            raise InputError(f"no (audio, motion) windows of speaker {speaker!r}; speakers: {', '.join(known)}")
        db = db.subset(keep)
    videos = {s for s, _ in db.source}
    speakers = {speaker_of(s) for s in videos}
    by_speaker = len(speakers) > 1  # one speaker (--speaker): the seed's person-specific protocol, by video
    if len(videos) < 2:
        raise InputError("the held-out k-NN rows need windows from at least two videos")
    window_s = db.G.shape[1] / db.fps
    res, table, kept = knn_rows(db, ks, blend, by_speaker=by_speaker)
    seed_table = table.pop("seed_rule")
    starts = defaultdict(list)
    for src, st in db.source:
        starts[src].append(st)
    out = {
        "protocol": __doc__.split("\n\n", 1)[1].strip(),
        "speaker": speaker or "all",
        "joins": "inertialized over one step, one skeleton" if blend else "raw concatenation (--no-blend)",
        "videos": len(videos),
        "windows": db.M,
        "fps": db.fps,
        "minutes_of_audio_motion": minutes_covered(starts.items(), window_s),
        "speakers": len(speakers),
        "knn_protocol": knn_protocol(len(kept["held_out"]), by_speaker),
        "knn_folds": len(kept["held_out"]),
        "knn": {k: float(np.nanmean(v)) for k, v in res.items()},
        "knn_ci95_over_videos": {  # each window's value, whole test videos resampled
            k: bootstrap_over_groups(np.asarray(v, float), np.array(kept["videos"]))
            for k, v in res.items()
            if len(v) == len(kept["videos"]) and np.isfinite(v).all()
        },
        "knn_ci95_over_speakers": {  # the folds' unit: whole held-out speakers resampled (one speaker: none)
            k: bootstrap_over_groups(np.asarray(v, float), np.array([speaker_of(s) for s in kept["videos"]]))
            for k, v in res.items()
            if by_speaker and len(v) == len(kept["videos"]) and np.isfinite(v).all()
        },
        "control_adherence": table,
        "control_adherence_seed_rule": seed_table,
    }
    if refiner_folds:
        out["knn_cgan"] = refiner_rows(db, kept, ks, refiner_folds, refiner_steps, progress, seeds=seeds)
        if refiner_ablation:  # RefinerTrainConfig.anima_v1, on the same folds and windows
            v1 = RefinerTrainConfig.anima_v1()
            out["knn_cgan_anima_v1"] = refiner_rows(
                db, kept, ks, refiner_folds, refiner_steps, progress, v1, seeds=seeds
            )
        body = [db.source[i][0] for i in sorted(kept["outs"])]
        folds = fold_count(body, refiner_folds, len({speaker_of(s) for s in body}) > 1)  # the refiner's folds
        w = read_windows(folder)
        if speaker is not None:
            w = w.select(np.array([speaker_of(s) == speaker for s in w.source]))
        out["generator"] = generator_rows(
            w,
            kept,
            db,
            folds,
            generator_steps,
            progress,
            kept.get("refined"),
            fgd_steps=fgd_steps,
            facegood_seconds=facegood_seconds,
            seeds=seeds,
        )
        out["sync_classifier"] = sync_rows(db, folds, steps=sync_steps, seeds=seeds)
    per = defaultdict(list)
    for src, st in starts.items():
        per[speaker_of(src)].append((src, st))
    out["minutes_per_speaker"] = {k: minutes_covered(v, window_s) for k, v in sorted(per.items())}
    return out


def run(cfg: GestureEval, progress: bool = False) -> dict:
    """``anima eval gesture``."""
    return evaluate(
        cfg.db,
        refiner_folds=cfg.refiner_folds,
        refiner_steps=cfg.refiner_steps,
        progress=progress,
        sync_steps=cfg.sync_steps,
        generator_steps=cfg.generator_steps,
        speaker=cfg.speaker,
        blend=cfg.blend,
        refiner_ablation=cfg.refiner_ablation,
        fgd_steps=cfg.fgd_steps,
        seeds=cfg.seeds,
    )


def knn_protocol(folds: int, by_speaker: bool) -> str:
    """The k-NN rows' protocol line (in the result and the docs' table)."""
    if by_speaker:
        return (
            f"leave-one-speaker-out, {folds} folds (one per speaker): each speaker's windows synthesised with a "
            "database of the other speakers' windows only"
        )
    return (
        f"leave-one-video-out within one speaker, {folds} folds (the seed's person-specific protocol): each "
        "video's windows synthesised with a database of the speaker's other videos"
    )


def _f(x, fmt: str = ".2f") -> str:
    return "-" if x is None or (isinstance(x, float) and not np.isfinite(x)) else format(x, fmt)


def _iv(ci: dict, name: str, fmt: str = ".2f") -> str:
    return f" [{ci[name][0]:{fmt}}, {ci[name][1]:{fmt}}]" if name in ci else ""


def _sd(sd: dict | None, name: str, fmt: str = ".2f") -> str:
    """`` ± spread`` over training seeds where the result has it (results before seeds: nothing)."""
    return f" ± {sd[name]:{fmt}}" if sd and name in sd and np.isfinite(sd[name]) else ""


def _knn_label(r: dict) -> str:
    p = r.get("knn_protocol", "leave-one-video-out")
    return "k-NN, leave one speaker out" if p.startswith("leave-one-speaker-out") else "k-NN, leave one video out"


def summary(r: dict) -> list[str]:
    """The markdown of ``eval all`` and of the docs' generated blocks (tools/doc_tables.py)."""
    by_speaker = bool(r.get("knn_ci95_over_speakers"))  # intervals over the folds' unit where there is one
    unit = "speakers" if by_speaker else "videos"
    k, ci = r["knn"], r.get(f"knn_ci95_over_{unit}", {})
    gen = r.get("generator", {})
    fgd = gen.get("fgd", {})
    out = [
        f"{r['windows']} full-body windows from {r['videos']} videos ({r['minutes_of_audio_motion']:.2f} min of "
        f"(audio, motion), {r['fps']} fps); joins: {r['joins']}. Intervals: 95 % over held-out {unit} "
        f"(whole {unit} resampled"
        + (f", {r['speakers']} speakers: wide)" if by_speaker and "speakers" in r else ")")
        + (
            f"; ± the standard deviation over training seeds {r['knn_cgan']['seeds']}. k-NN: {r['knn_protocol']}."
            if "knn_protocol" in r and "seeds" in r.get("knn_cgan", {})
            else f". k-NN: {r['knn_protocol']}."
            if "knn_protocol" in r
            else "."
        ),
        "",
        "| method | L1 cm | FGD | wrist motion cm | jerk m/s^3 | beat consistency | diversity cm | lip error mm |",
        "|---|---|---|---|---|---|---|---|",
        f"| captured | - | {_f(fgd.get('captured_half_vs_half'))} (random halves) | "
        f"{k['wrist_motion_cm_captured']:.2f} | {k['jerk_captured']:.1f} | {k['beat_consistency_captured']:.3f} | "
        f"- | {_f(gen.get('lip_error_mm_random_other_video'))} (another video's face) |",
        f"| {_knn_label(r)} | {k['l1_cm']:.2f}{_iv(ci, 'l1_cm')} | {_f(fgd.get('knn'))} | "
        f"{k['wrist_motion_cm']:.2f} | {k['jerk']:.1f}{_iv(ci, 'jerk', '.1f')} | "
        f"{k['beat_consistency']:.3f}{_iv(ci, 'beat_consistency', '.3f')} | {k['diversity_cm']:.2f} | - |",
    ]
    if "knn_cgan" in r:
        c = r["knn_cgan"]
        b, m, mci = c.get("knn_fold_inputs", {}), c["metrics"], c.get(f"metrics_ci95_over_{unit}", {})
        sd, fsd = c.get("metrics_sd_over_seeds"), gen.get("fgd_sd_over_seeds")
        if b:
            out.append(
                f"| k-NN searched in the fold's training videos (the refiner's input) | {b['l1_cm']:.2f} | - | "
                f"{b['wrist_motion_cm']:.2f} | {b['jerk']:.1f} | {b['beat_consistency']:.3f} | "
                f"{b['diversity_cm']:.2f} | - |"
            )
        if m:
            out.append(
                f"| k-NN + cGAN refiner (clean folds) | {m['l1_cm']:.2f}{_sd(sd, 'l1_cm')}{_iv(mci, 'l1_cm')} | "
                f"{_f(fgd.get('knn_cgan'))}{_sd(fsd, 'knn_cgan')} | "
                f"{m['wrist_motion_cm']:.2f}{_sd(sd, 'wrist_motion_cm')} | "
                f"{m['jerk']:.1f}{_sd(sd, 'jerk', '.1f')}{_iv(mci, 'jerk', '.1f')} | "
                f"{m['beat_consistency']:.3f}{_sd(sd, 'beat_consistency', '.3f')} | "
                f"{m['diversity_cm']:.2f}{_sd(sd, 'diversity_cm')} | - |"
            )
        else:
            out.append(
                "| k-NN + cGAN refiner (clean folds) | no fold judged (see the folds below) | - | - | - | - | - | - |"
            )
    for name, g in gen.get("rows", {}).items():
        sd, fsd = g.get("sd_over_seeds"), gen.get("fgd_sd_over_seeds")
        out.append(
            f"| {name} | {g['l1_cm']:.2f}{_sd(sd, 'l1_cm')} | {_f(g['fgd'])}{_sd(fsd, name)} | "
            f"{g['wrist_motion_cm']:.2f}{_sd(sd, 'wrist_motion_cm')} | {g['jerk']:.1f}{_sd(sd, 'jerk', '.1f')} | "
            f"{g['beat_consistency']:.3f}{_sd(sd, 'beat_consistency', '.3f')} | "
            f"{g['diversity_cm']:.2f}{_sd(sd, 'diversity_cm') if name == 'moglow' else ''} | "
            f"{g['lip_error_mm']:.2f}{_sd(sd, 'lip_error_mm')} |"
        )
    if "knn_cgan" in r:
        folds, c = r["knn_cgan"]["folds"], r["knn_cgan"]
        judged, skipped = [f for f in folds if "correction_sigma" in f], [f for f in folds if "skipped" in f]
        parts = [f"Refiner: {c['protocol']}."]
        if judged:
            parts.append(
                "Per fold (held-out videos / training pairs / test windows; held-out videos in its inputs; "
                "correction smoothing chosen on the fold's inner validation): "
                + "; ".join(
                    f"{f['held_out_videos']} / {f['train_pairs']} / {f['test_windows']}; "
                    f"{f['held_out_videos_in_inputs']}; sigma {f['correction_sigma']['value']}"
                    + ("" if "validation" in f["correction_sigma"] else " (default)")
                    for f in judged
                )
                + "."
            )
        if skipped:
            parts.append("Skipped: " + "; ".join(f"fold {f['fold']}: {f['skipped']}" for f in skipped) + ".")
        if "l1_to_knn_cm" in c["metrics"]:
            parts.append(f"Moved {c['metrics']['l1_to_knn_cm']:.2f} cm from its k-NN input.")
        out += ["", " ".join(parts)]
    if gen:
        adv = [  # one per fold (the weight is chosen once per fold, for every training seed)
            f.get("adv_weight", {}).get("value")
            for f in gen["rows"].get("adversarial", {}).get("folds", [])
            if f.get("seed", 0) == gen.get("seeds", [0])[0]
        ]
        out += [
            "",
            f"Generators: {gen['protocol']}. Adversarial weight per fold: {', '.join(map(str, adv)) or '-'}. "
            f"Lip error over {gen['lip_windows']} windows; FGD per fold ({gen['fgd_protocol']}): "
            + ", ".join(f"fold {x['fold']} {x['windows']} windows" for x in gen.get("fgd_folds", []))
            + (
                f". The generator rows are the mean ± standard deviation over training seeds {gen['seeds']}, "
                f"with no interval over {unit}: not ranked."
                if "seeds" in gen
                else f". The generator rows have one number per fold, no interval over {unit}: not ranked."
            ),
        ]
        fg = gen.get("facegood_lip_sync")
        if fg and fg.get("rows"):
            out += [
                "",
                f"Lip sync on FaceGood's {fg['recordings']} recordings ({fg['minutes']} min, Mandarin): correlation "
                "of the predicted mouth opening with the jaw curve at lag 0 / best lag (another recording's "
                "speech at lag 0: "
                + ", ".join(
                    f"{n} {v['r_lag0']:.2f} / {v['r_best']:.2f} ({v['r_other_speech']:.2f})"
                    for n, v in fg["rows"].items()
                )
                + ").",
            ]
    if "sync_classifier" in r:
        out += [
            "",
            "Sync classifier (table 4.4), held-out accuracy (chance 0.5"
            + (
                "; ± over training seeds"
                if any("accuracy_sd_over_seeds" in v for v in r["sync_classifier"].values())
                else ""
            )
            + "): "
            + ", ".join(
                f"{n.replace('_', ' ')} {v['accuracy']:.3f}{_sd(v, 'accuracy_sd_over_seeds', '.3f')}"
                for n, v in r["sync_classifier"].items()
            )
            + ".",
        ]
    out += ["", "| control (table 5.3) | mean | threshold | satisfied [95 % over videos] |", "|---|---|---|---|"]
    for c, v in r["control_adherence"].items():
        if "satisfied_fraction" in v:
            lo, hi = v["satisfied_fraction_ci95_over_videos"]
            out.append(
                f"| {c} | {v['mean']:.3f} | {v['threshold']:.3f} | {100 * v['satisfied_fraction']:.1f} % "
                f"[{100 * lo:.1f}, {100 * hi:.1f}] |"
            )
    if r.get("minutes_per_speaker"):
        out += [
            "",
            "Minutes of full-body (audio, motion) per speaker: "
            + ", ".join(f"{s} {m:.2f}" for s, m in r["minutes_per_speaker"].items())
            + ".",
        ]
    return out
