"""``anima gesture``: speech -> 3D upper-body + hands gestures by controllable k-NN search, written as a
sequence file, a BVH and a skeleton video with the speech muxed in."""
from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np

from anima.errors import InputError
from anima.gesture.features import FPS, N_STEP


def synthesize(speech_path: str, db, k: int = 0, controls: list | None = None, init: str = "mean",
               seed: int = 0, refiner=None, keywords: list | None = None,
               keyword_dbs: dict | None = None) -> tuple[np.ndarray, dict]:
    """k-NN search (and, with ``refiner`` from ``anima.gesture.refine.load_refiner``, the cGAN refinement).
    ``keywords`` (``anima.gesture.keywords.Keyword``) switch the search to ``keyword_dbs[word]`` (MatchDB)
    while the word is spoken."""
    from anima.gesture.control import step_masks
    from anima.gesture.features import audio_features
    from anima.gesture.knn import search
    feats, notes = _read_speech(speech_path)
    T = len(feats.features)
    F_in = audio_features(feats.features)
    if init == "mean":
        p0 = db.P.reshape(-1, db.P.shape[-1]).mean(0)
    elif init == "random":
        rng = np.random.default_rng(seed)
        p0 = db.P[rng.integers(db.M), rng.integers(db.P.shape[1])]
    else:
        raise InputError(f"unknown --init {init!r}: mean or random")
    n_steps = -(-T // N_STEP)
    part = None
    if keywords or keyword_dbs:
        from anima.gesture.keywords import keyword_masks, union
        db, part, names = union(db, keyword_dbs or {})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        masks, report = step_masks(db, controls or [], n_steps, N_STEP / FPS,
                                   None if part is None else part == 0)
    notes += [str(w.message) for w in caught]
    used = None
    if part is not None:
        masks, used = keyword_masks(db, part, names, keywords or [], n_steps, N_STEP / FPS,
                                    masks if controls else None)
    if T > db.M * db.P.shape[1]:
        notes.append("the speech is longer than the database: database windows are reused")
    G, picks = search(db, F_in, k, p0, masks)
    J = G.reshape(len(G), -1, 3)
    if refiner is not None:
        J = refiner.refine(feats.features[:len(J)], J)
    info = {"frames": len(G), "fps": FPS, "controls": report, "notes": notes, "refined": refiner is not None,
            "picks": [(int(m), int(r)) for m, r in picks]}
    if used is not None:
        info["database_per_step"] = used
    return J, info


def _read_speech(speech_path: str):
    from anima.audio.features import read_audio, speech_features
    x = read_audio(speech_path)  # any rate -> 16 kHz mono
    feats = speech_features(x, FPS)
    if len(feats.features) < N_STEP:
        raise InputError(f"speech is {len(x) / 16000:.2f} s long: at least {N_STEP / FPS:.2f} s is needed")
    notes = ["the speech is silent (below -60 dBFS): gestures follow the database's quiet moments"] if feats.silent else []
    return feats, notes


def generate(speech_path: str, gen) -> tuple[np.ndarray, np.ndarray, dict]:
    """The §4.4 generator (``anima.gesture.generator.load_generator``): speech -> joints [T, 55, 3] and face
    [T, 56] (53 ICT expression weights + head rotation), one pass for any length."""
    feats, notes = _read_speech(speech_path)
    if feats.silent:
        notes = ["the speech is silent (below -60 dBFS): expect a near-rest pose and a closed mouth"]
    J, face = gen.generate(feats.features)
    return J, face, {"frames": len(J), "fps": FPS, "notes": notes, "model": gen.cfg.kind}


def write_outputs(J: np.ndarray, speech_path: str, out: Path, info: dict, render: bool = True,
                  face: np.ndarray | None = None) -> list[Path]:
    import cv2

    from anima.core.skeleton import JOINT_NAMES, PARENTS
    from anima.io.bvh import write_bvh
    from anima.io.video import VideoWriter
    from anima.render.skeleton import _project_3d, draw_skeleton
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "gesture.npz", out / "gesture.bvh"]
    np.savez(paths[0], joints=J.astype(np.float32), fps=np.float32(FPS), joint_names=np.array(JOINT_NAMES),
             parents=PARENTS, info=np.array(json.dumps({k: v for k, v in info.items() if k != "picks"})))
    write_bvh(paths[1], J, JOINT_NAMES, PARENTS, FPS)
    if face is not None:  # the generator's face: the neutral ICT face animated, as `anima text2face` writes it
        from anima.capture.export import export_arkit_csv
        from anima.io.sequence import write_sequence
        from anima.render.videos import render_videos
        from anima.text2face.generate import motion_to_sequence
        seq = motion_to_sequence(face, fps=FPS, meta={"generated_by": "anima gesture --generator"})
        paths += [write_sequence(seq, out / "face.npz"), export_arkit_csv(seq, out / "arkit.csv")]
        if render:
            render_videos(seq, None, None, out / "face.mp4", progress=False, audio=str(speech_path))
            paths.append(out / "face.mp4")
    if render:
        size = 512
        p = out / "skeleton.mp4"
        with VideoWriter(p, FPS, (2 * size, size), audio_path=str(speech_path)) as vw:
            for f in range(len(J)):
                canvas = np.full((size, 2 * size, 3), 28, np.uint8)
                for i, yaw in enumerate((0.0, np.deg2rad(-60))):
                    canvas[:, i * size:(i + 1) * size] = draw_skeleton(canvas[:, i * size:(i + 1) * size],
                                                                       _project_3d(J[f], size, yaw), 3)
                cv2.putText(canvas, f"{f / FPS:5.2f} s", (10, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (230, 230, 230), 1)
                vw.write(canvas)
        paths.append(p)
    return paths
