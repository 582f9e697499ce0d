"""``anima eval ...``: every evaluation prints its result (JSON with ``--json``)."""

from __future__ import annotations

import sys
from pathlib import Path

from anima.cli.common import emit, group
from anima.cli.options import number, positive_int, step_grid
from anima.dataset.storage import check_dataset
from anima.dataset.windows import read_clips, read_windows
from anima.errors import InputError
from anima.eval.all import run_all
from anima.eval.annotations import evaluate_annotations
from anima.eval.body import evaluate_body
from anima.eval.landmarks import evaluate_aflw
from anima.eval.pose import evaluate_pose
from anima.eval.reenact import evaluate as evaluate_reenact
from anima.eval.stability import evaluate_stability
from anima.eval.text2face_prompts import evaluate_prompts, load_suite
from anima.io.outdir import check_out_dir, claim_folder


def register(sub) -> None:
    esub = group(sub, "eval", "evaluations that print JSON", "eval_command", "EVAL")
    eall = esub.add_parser(
        "all",
        help="every evaluation in one run: one results file and a markdown summary",
        description="Runs landmarks, stability, body, annotations, pose, reenact, gesture and text2face as their "
        "own commands do, and writes OUT/results.json (per row: command, status, minutes, result; the "
        "commit, the shared data's and the dataset's fingerprints, the machine) and OUT/summary.md. "
        "A row that cannot run (e.g. pose without a trained lifter) is recorded as skipped; exit 3 when "
        "one failed. About 1.9 hours on 2 cores (measured row by row: gesture 52 min, text2face 52 min, the "
        "rest 8 min; pose only with a trained lifter).",
    )
    eall.add_argument("--db", required=True, help="dataset folder from `anima dataset build` (gesture, text2face)")
    eall.add_argument("--out", required=True, help="result folder")
    eall.add_argument("--work", default=None, help="text2face models (reused when there; default OUT/text2face_work)")
    eall.add_argument("--only", nargs="+", default=None, metavar="NAME", help="only these evaluations")
    eall.add_argument("--quick", action="store_true", help="learned models with a few steps: checks that all runs")
    eall.add_argument("--json", action="store_true")
    eall.set_defaults(func=cmd_all)
    el = esub.add_parser(
        "landmarks",
        help="68-point NME on the AFLW2000-3D samples",
        description="68-point NME (3DDFA_V2 protocol) of raw MediaPipe and of the fitted model.",
    )
    el.add_argument("--json", action="store_true")
    el.add_argument("--per-image", action="store_true", help="include per-image rows")
    el.set_defaults(func=cmd_landmarks)

    es = esub.add_parser(
        "stability",
        help="landmark jitter of the smoothed fit vs raw MediaPipe",
        description="Mean landmark acceleration (normalised by inter-ocular distance) of raw "
        "MediaPipe and of the smoothed fit, and the fit's landmark error with and without "
        "smoothing, on talking clips.",
    )
    es.add_argument("clips", nargs="*", help="videos (default: the shared talking clips)")
    es.add_argument("--max-frames", type=positive_int, default=300)
    es.add_argument("--json", action="store_true")
    es.set_defaults(func=cmd_stability)

    eb = esub.add_parser(
        "body",
        help="body/hand tracking and cleaning report on the gesture clips",
        description="Per clip: body and hand tracked %%, after interpolation, bone-length CV "
        "before/after cleaning; hand detector on hand-images/. Default clips: pats-crops, "
        "tango-interviews, LatentSync.",
    )
    eb.add_argument("clips", nargs="*", help="glob patterns under the data root (default: the gesture sets)")
    eb.add_argument("--max-frames", type=positive_int, default=None)
    eb.add_argument("--json", action="store_true")
    eb.set_defaults(func=cmd_body)

    ea = esub.add_parser(
        "annotations",
        help="attribute detectors vs labels made by watching frames",
        description="Precision and recall per attribute (event and frame level) of the automatic "
        "attribute detectors on the labelled clips in anima/eval/labels/attributes/.",
    )
    ea.add_argument("--json", action="store_true")
    ea.set_defaults(func=cmd_annotations)

    ep = esub.add_parser(
        "pose",
        help="3D body pose: lifter vs MediaPipe on Human3.6M S9 images, HumanEva; ablation",
        description="MPJPE, 3D PCK@150 mm and AUC under the unscaled, globally scaled and "
        "Procrustes protocols (seed 004 §3.4.1) for the lifter checkpoint and for MediaPipe's own "
        "world landmarks on the real S9 images; HumanEva-I validation from ground-truth 2D; with "
        "--ablation DIR, trains (resumable) and evaluates the rows of seed table 3.6.",
    )
    ep.add_argument("--model", default=None, help="lifter checkpoint (default: $ANIMA_HOME/models/pose_lifter.pt)")
    ep.add_argument("--ablation", default=None, metavar="DIR", help="train/evaluate the ablation rows into DIR")
    ep.add_argument("--ablation-steps", type=positive_int, default=8000)
    ep.add_argument(
        "--ablation-width",
        type=number(int, 8, 8192),
        default=256,
        help="network width of the ablation rows (256 keeps the five trainings to minutes on 2 cores; "
        "the seed's 1024 is the `train pose` default)",
    )
    ep.add_argument("--ablation-dropout", type=number(float, 0.0, 0.99), default=0.1)
    ep.add_argument("--cache", default=None, help="MediaPipe detection cache (default: $ANIMA_HOME/cache/pose3d)")
    ep.add_argument("--json", action="store_true", help="no progress output (the result is JSON either way)")
    ep.set_defaults(func=cmd_pose)

    er = esub.add_parser(
        "reenact",
        help="self-re-enactment metrics (seed 001 §4.2) on the Obama clips and d11",
        description="SSIM, LPIPS, lip NME, tOF, tLP on the face box; the base loss with the true "
        "vertex colours; SSIM against n; method 1 vs 2; n-best L2 curves with and without the "
        "actor->target expression mapping. --out DIR also writes plots and side-by-side frames.",
    )
    er.add_argument("--out", default=None, help="folder for plots and frames")
    er.add_argument("--json", action="store_true", help="no progress output (the result is JSON either way)")
    er.set_defaults(func=cmd_reenact)

    eg = esub.add_parser(
        "gesture",
        help="gestures from speech: control adherence, L1, FGD, lip error, jerk, beats",
        description="On the dataset's (audio, motion) windows (seed 004 ch. 4-5): k-NN "
        "leave-one-video-out with control adherence as table 5.3; k-NN + cGAN, the §4.4 generator, "
        "direct regression and the LSTM baseline cross-validated by video; L1 to the captured "
        "motion, FGD, lip keypoint error (table 4.3), diversity, jerk, beat consistency; the sync "
        "classifier (table 4.4); lip sync on FaceGood's recordings; minutes per speaker.",
    )
    eg.add_argument("--db", required=True, help="dataset folder from `anima dataset build`")
    eg.add_argument(
        "--refiner-folds",
        type=number(int, 0, 100),
        default=3,
        help="k-NN + cGAN rows: cross-validation folds by video (0 = skip the learned models)",
    )
    eg.add_argument("--refiner-steps", type=positive_int, default=None, help="generator steps per fold (default 600)")
    eg.add_argument(
        "--refiner-ablation",
        action="store_true",
        help="also train the refiner with anima's earlier settings (L1 10, gradient penalty 10, k = 0..4) on the "
        "same folds: knn_cgan_anima_v1 (about 9 minutes more)",
    )
    eg.add_argument(
        "--speaker",
        default=None,
        help="only this speaker's windows (the seed's subject-specific protocol), e.g. oliver",
    )
    eg.add_argument(
        "--generator-steps",
        type=positive_int,
        default=None,
        help="§4.4 generator and baselines: training steps per fold (default 1000)",
    )
    eg.add_argument(
        "--no-blend",
        action="store_true",
        help="k-NN rows with the seed's raw concatenation of windows (no blended joins, no no-repeat rule)",
    )
    eg.add_argument("--json", action="store_true", help="(the result is JSON either way)")
    eg.set_defaults(func=cmd_gesture)

    et = esub.add_parser(
        "text2face",
        help="text -> face: tables 7.1-7.3, attribute recall, R-precision",
        description="Trains (or reuses, in --work) the seed 000 model, its ablations and the MDM- "
        "and StableMoFusion-style baselines on the dataset's training videos (training steps chosen on the "
        "validation videos) and scores them with the retrieval and mean "
        "baselines on 90-frame windows of the held-out videos: MAE/RMSE of mouth and eye vertices "
        "(mm), Diversity, each over --reps repetitions with 95% confidence intervals; attribute "
        "recall with the dataset's detectors; R-precision with a contrastive text-motion evaluator.",
    )
    et.add_argument("dataset", help="dataset folder from `anima dataset build`")
    et.add_argument("--work", default="runs/eval_text2face", help="folder for the trained models (reused)")
    et.add_argument("--reps", type=number(int, 1, 1000), default=20)
    et.add_argument(
        "--steps",
        type=positive_int,
        default=None,
        help="training steps of every model (default: table 7.1's learned models each get the count of "
        "--step-grid with the lowest MAE on the validation videos, the ablation rows ours')",
    )
    et.add_argument(
        "--step-grid",
        type=step_grid,
        default=None,
        metavar="N,N,...",
        help="the step counts tried on the validation videos (default 250,500,1000,2000); one training per "
        "model reaches the largest and keeps a snapshot at each",
    )
    et.add_argument("--no-ablations", action="store_true", help="only the model and the baselines")
    et.add_argument("--seed-preset", action="store_true", help="also train the seed-size model (13.6 M parameters)")
    et.add_argument("--checkpoint", default=None, help="score this checkpoint as 'ours' instead of training it")
    et.add_argument(
        "--prompts",
        nargs="?",
        const="",
        default=None,
        metavar="FILE",
        help="instead of the tables: the prompt suite (default: the 114 prompts shipped in "
        "anima/eval/prompts/text2face.json; the 40 held-out ones are text2face_heldout.json beside it) "
        "scored for the timeline method, the seed model (the "
        "shipped checkpoint or --checkpoint) and retrieval with the dataset's detectors: per-event "
        "recall and false alarms, order, count and side accuracy, emotion checks, distinct motions "
        "(about 1 min on 2 cores)",
    )
    et.add_argument("--seeds", type=number(int, 1, 100), default=3, help="with --prompts: seeds per prompt")
    et.add_argument("--json", action="store_true", help="(the result is JSON either way)")
    et.set_defaults(func=cmd_text2face)


def cmd_all(a) -> int:
    out = check_out_dir(a.out)
    check_dataset(a.db)
    # the dataset read in full before an hour of work: a broken one is refused now, not when its row comes
    if not read_windows(a.db).n or not read_clips(a.db):
        raise InputError(f"{a.db}: the dataset needs (audio, motion) windows and (text, motion) clips")
    say = None if a.json else (lambda line: print(f"anima eval all: {line}", file=sys.stderr, flush=True))
    r = run_all(a.db, out, a.work, a.quick, a.only, say, command=" ".join(["anima", *sys.argv[1:]]))
    summary = {
        "results": str(Path(out) / "results.json"),
        "summary": str(Path(out) / "summary.md"),
        "minutes": round(r["wall_s"] / 60, 1),
        "rows": {n: e["status"] for n, e in r["rows"].items()},
    }
    emit(summary, a.json)
    if r["failed"]:
        print(
            f"anima: error: evaluation(s) failed: {', '.join(r['failed'])} (see {summary['results']})", file=sys.stderr
        )
        return 3
    return 0


def cmd_landmarks(a) -> int:
    r = evaluate_aflw()
    if not a.per_image:
        r.pop("per_image")
    return emit(
        r,
        a.json,
        lambda r: (
            f"AFLW2000-3D samples: {r['detected']}/{r['images']} faces found; 68-pt NME per landmark definition\n"
            + "\n".join(
                f"  {name:<13} raw MediaPipe {100 * v['mediapipe_nme']:.2f} %, fitted ICT model "
                f"{100 * v['fit_nme']:.2f} % (fit - MediaPipe, 95 % over images: "
                f"[{100 * v['fit_minus_mediapipe_ci95_over_images'][0]:+.2f}, "
                f"{100 * v['fit_minus_mediapipe_ci95_over_images'][1]:+.2f}])"
                for name, v in r["by_definition"].items()
            )
        ),
    )


def cmd_stability(a) -> int:
    return emit(evaluate_stability(a.clips or None, max_frames=a.max_frames), a.json, _stability_text)


def cmd_body(a) -> int:
    return emit(evaluate_body(a.clips or None, a.max_frames, progress=not a.json), a.json, _body_text)


def cmd_annotations(a) -> int:
    return emit(evaluate_annotations(), a.json, _annotations_text)


def cmd_pose(a) -> int:
    return emit(
        evaluate_pose(
            a.model, a.cache, a.ablation, a.ablation_steps, a.ablation_width, a.ablation_dropout, progress=not a.json
        ),
        True,
    )


def cmd_reenact(a) -> int:
    out = claim_folder(a.out, "eval_reenact") if a.out else None
    return emit(evaluate_reenact(out, progress=not a.json), True)


def cmd_gesture(a) -> int:
    check_dataset(a.db)  # before torch loads
    from anima.eval.gesture.run import evaluate  # lazy: torch

    return emit(
        evaluate(
            a.db,
            refiner_folds=a.refiner_folds,
            refiner_steps=a.refiner_steps,
            progress=not a.json,
            generator_steps=a.generator_steps,
            speaker=a.speaker,
            blend=not a.no_blend,
            refiner_ablation=a.refiner_ablation,
        ),
        True,
    )


def cmd_text2face(a) -> int:
    check_dataset(a.dataset)  # before torch loads
    if a.prompts is not None:
        load_suite(a.prompts or None)  # a bad suite fails before any model loads
        return emit(evaluate_prompts(a.dataset, a.prompts or None, a.seeds, a.checkpoint, progress=not a.json), True)
    from anima.eval.text2face import evaluate  # lazy: torch

    return emit(
        evaluate(
            a.dataset,
            Path(a.work),
            reps=a.reps,
            ablations=not a.no_ablations,
            steps=a.steps,
            seed_preset=a.seed_preset,
            **({"step_grid": a.step_grid} if a.step_grid else {}),
            checkpoint=a.checkpoint,
            progress=not a.json,
        ),
        True,
    )


def _stability_text(r: dict) -> str:
    lines = [f"{'clip':<28} {'acc raw':>9} {'acc fit':>9} {'reduction':>9} {'err ratio':>9}"]
    for c in r["clips"]:
        lines.append(
            f"{c['clip']:<28} {c['acc_raw']:>9.5f} {c['acc_fit_smoothed']:>9.5f} "
            f"{100 * c['acc_reduction']:>8.1f}% {c['error_ratio_smoothed_vs_unsmoothed']:>9.3f}"
        )
    lines.append(
        f"mean reduction {100 * r['mean_acc_reduction']:.1f}% (target >= 40%), "
        f"mean error ratio {r['mean_error_ratio']:.3f} (target <= 1.10)"
    )
    return "\n".join(lines)


def _body_text(r: dict) -> str:
    lines = [
        f"{'clip':<44} {'body':>6} {'L hand':>7} {'R hand':>7} {'L int':>6} {'R int':>6} {'CV raw':>7} {'CV cln':>7}"
    ]
    for c in r["clips"]:
        lines.append(
            f"{c['clip'][:44]:<44} {100 * c['body_tracked']:>5.1f}% {100 * c['left_hand_tracked']:>6.1f}% "
            f"{100 * c['right_hand_tracked']:>6.1f}% {100 * c['left_hand_after_interpolation']:>5.1f}% "
            f"{100 * c['right_hand_after_interpolation']:>5.1f}% {c['bone_cv_raw']:>7.3f} "
            f"{c['bone_cv_cleaned']:>7.3f}"
        )
    lines.append(f"bone-length CV dropped on {r['bone_cv_dropped_on']}")
    lines += [f"hand image {h['image']}: {h['hands_found']} hand(s) {h['scores']}" for h in r["hand_images"]]
    return "\n".join(lines)


def _annotations_text(r: dict) -> str:
    def f(x):
        return "  -  " if x is None else f"{x:5.2f}"

    lines = [
        f"out of sample ({r['protocol']}, {len(r['clips'])} labelled clips; in-sample figures in --json)",
        f"{'attribute':<16} {'P':>5} {'R':>5} {'frameP':>7} {'frameR':>7} {'events':>7} {'detections':>10}",
    ]
    for k, v in r["per_attribute"].items():
        lines.append(
            f"{k:<16} {f(v['precision'])} {f(v['recall'])} {f(v['frame_precision']):>7} "
            f"{f(v['frame_recall']):>7} {v['labelled_events']:>7} {v['detections']:>10}"
        )
    return "\n".join(lines)
