"""Does the character's mouth move like the person's, as a landmark reader that shares nothing with anima sees it?
(The target: the inner-lip gap over the face's height, frame by frame, r >= 0.7 on every talking or emoting clip.)

    python benchmarks/mouth_independent.py   # writes benchmarks/results/mouth_independent.json (4-7 min, 2 cores)
    python benchmarks/mouth_independent.py --clips CLIP... --out FILE   # other clips (under the shared data)
    python benchmarks/mouth_independent.py --fresh   # capture again (after a change to the face), then read

**A development check on shared clips, not a held-out test**: every clip here has been looked at while building
the face (CREMA-D actor 1001's six takes, EAMM's six MEAD crops, three talking heads: :data:`CLIPS`, 15 clips,
about 1,900 frames). The numbers are the face code's as it stood when each clip was captured (each row's
``code``: the commit, the files changed under ``anima/`` and a hash of their diff); rerun it after a change
(``--fresh``).

**Capture** as a user does: ``anima capture CLIP --out WORK/NAME --face-only`` (the shipped defaults), cached
under ``--work`` (a folder with its ``manifest.json``, written last, is reused unless ``--fresh``). The check
reads ``avatar.mp4``'s face close-up, the square at its right (the character's head seen from in front of the
face, the panel a user sees; its side is the video's height), frame by frame; and, as a ceiling, the fitted
ICT face (the clip's identity and the fit's 53 expressions from ``capture.npz``, no head turn) drawn alone in one
colour the way ``benchmarks/face_readback.py`` draws it (``--no-ict`` skips it).

**The reader** shares nothing with anima (whose tracker is MediaPipe Face Mesh): dlib's HOG face detector and its
68-point shape predictor (an ensemble of regression trees, Kazemi & Sullivan 2014; ``dlib-bin``, Boost licence),
with the model file ``shape_predictor_68_face_landmarks.dat`` that ``face_recognition_models`` ships in its
package (MIT package; the model was trained on iBUG 300-W, whose images are licensed for research only: fine for
this development check, not for anything anima ships; both are in requirements.txt only, never imported by
anima/). Never tuned to, never used inside the method. Per frame (RGB, the largest face the detector finds; if
none, once more with the image upsampled): the inner-lip gap, the mean of the distances 61-67, 62-66, 63-65
(0-based iBUG points), over the face's height, nose bridge (27) to chin (8); and, as a second reading, over the
outer eye corners' distance (36-45: a normaliser that does not grow as the jaw drops); and the outer lips' height
(the mean of 50-58, 51-57, 52-56) over the face's height. Where teeth show, dlib tends to put the inner-lip points
on the teeth's edges, not the lips' (lips parted over clenched teeth read nearly shut: MEAD's surprised take; the
character's wide-open mouth reads at its teeth's edges), so the inner-lip gap reads the teeth's opening as much as
the lips'; ``r_outer`` does not depend on those points.

**Reported** per clip: Pearson's r between the person's (source video) and the character's gap over the frames
where the reader found both faces (``r``; ``r_eyes``, ``r_outer`` the other readings), the best r within
+-:data:`MAX_LAG` frames and its lag (a timing slip would show as a lag other than 0), the reader's detection rate
on each, the frames counted, and the gap's spread (standard deviation, face heights) on each side: a clip whose
mouth hardly moves gives a noisy r. The same for the fitted ICT face (``ict``).
"""

from __future__ import annotations

import argparse
import hashlib
import importlib.util
import json
import subprocess
import sys
import time
from pathlib import Path

import cv2
import dlib
import numpy as np

from anima.io.assets import asset
from anima.io.atomic import write_json

CREMA = "emotion-clips/crema-d/1001_DFA_{}_XX.flv"
MEAD = "emotion-clips/eamm-mead/{}.mp4"
CLIPS = (
    [("crema-d", c, CREMA.format(c)) for c in ("ANG", "DIS", "FEA", "HAP", "NEU", "SAD")]
    + [("eamm-mead", n, MEAD.format(n)) for n in ("contempt", "disgusted", "fear", "happy", "sad", "surprised")]
    + [
        ("talking", "RD_Radio10_0_clip_0", "talking-heads-extra/RD_Radio10_0_clip_0.mp4"),
        ("talking", "May_5s", "talking-heads-misc/Real3DPortrait/data/raw/examples/May_5s.mp4"),
        ("talking", "mouth_source", "talking-heads-extra/mouth_source.mp4"),
    ]
)
"""(set, name, clip under the shared data): CREMA-D 1001's six takes, the six MEAD crops, three talking heads."""
MAX_LAG = 3
ICT_SIZE = 384
TARGET_R = 0.7
INNER = ((61, 67), (62, 66), (63, 65))
OUTER = ((50, 58), (51, 57), (52, 56))
HEIGHT = (27, 8)
EYES = (36, 45)


def model_path() -> Path:
    """``shape_predictor_68_face_landmarks.dat`` inside ``face_recognition_models`` (found without importing the
    package: its ``__init__`` needs ``pkg_resources``, which a setuptools-free venv lacks)."""
    spec = importlib.util.find_spec("face_recognition_models")
    if spec is None or not spec.submodule_search_locations:
        sys.exit("mouth_independent: pip install face_recognition_models (requirements.txt)")
    return Path(next(iter(spec.submodule_search_locations))) / "models" / "shape_predictor_68_face_landmarks.dat"


class Reader:
    """dlib's 68 points on an RGB frame: ``[68, 2]`` pixels, or None where no face is found. ``detect_scale``:
    the detector runs on the frame scaled by it (a large face: faster), the points on the frame itself."""

    def __init__(self):
        self.path = model_path()
        self.detector = dlib.get_frontal_face_detector()
        self.predictor = dlib.shape_predictor(str(self.path))

    def __call__(self, rgb: np.ndarray, detect_scale: float = 1.0) -> np.ndarray | None:
        rgb = np.ascontiguousarray(rgb)
        small = rgb if detect_scale == 1.0 else cv2.resize(rgb, None, fx=detect_scale, fy=detect_scale,
                                                           interpolation=cv2.INTER_AREA)  # fmt: skip
        boxes = self.detector(small, 0)
        if len(boxes) == 0:
            boxes = self.detector(small, 1)
        if len(boxes) == 0:
            return None
        b = max(boxes, key=lambda r: r.width() * r.height())
        s = 1.0 / detect_scale
        rect = dlib.rectangle(int(b.left() * s), int(b.top() * s), int(b.right() * s), int(b.bottom() * s))
        shape = self.predictor(rgb, rect)
        return np.array([(shape.part(i).x, shape.part(i).y) for i in range(68)], np.float64)


def read_points(reader: Reader, frames, detect_scale: float = 1.0) -> np.ndarray:
    """``[F, 68, 2]``, NaN where no face was found."""
    out = []
    for rgb in frames:
        p = reader(rgb, detect_scale)
        out.append(np.full((68, 2), np.nan) if p is None else p)
    return np.array(out).reshape(-1, 68, 2)


def video_frames(path: str | Path, crop_right_square: bool = False):
    """RGB frames decoded by OpenCV (not anima's reader); ``crop_right_square``: the square at the right edge
    (``avatar.mp4``'s face close-up)."""
    cap = cv2.VideoCapture(str(path))
    try:
        while True:
            ok, bgr = cap.read()
            if not ok:
                return
            if crop_right_square:
                h, w = bgr.shape[:2]
                if w <= h:  # the front and 3/4 views, then the face: no room for them, no close-up at the right
                    sys.exit(f"mouth_independent: {path} is {w} x {h}: where is the face close-up?")
                bgr = bgr[:, w - h :]
            yield cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
    finally:
        cap.release()


def gaps(P: np.ndarray) -> dict[str, np.ndarray]:
    """The inner-lip gap per frame over the face's height (27-8) and over the outer eye corners (36-45); the outer
    lips' height over the face's height."""
    d = lambda a, b: np.linalg.norm(P[:, a] - P[:, b], axis=-1)
    gap = np.mean([d(a, b) for a, b in INNER], axis=0)
    outer = np.mean([d(a, b) for a, b in OUTER], axis=0)
    return {"height": gap / d(*HEIGHT), "eyes": gap / d(*EYES), "outer": outer / d(*HEIGHT)}


def pearson(a: np.ndarray, b: np.ndarray) -> float | None:
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 5 or np.std(a[ok]) == 0 or np.std(b[ok]) == 0:
        return None
    return float(np.corrcoef(a[ok], b[ok])[0, 1])


def best_lag(a: np.ndarray, b: np.ndarray, max_lag: int = MAX_LAG) -> tuple[float | None, int]:
    """The largest r of ``a[t]`` against ``b[t + lag]`` for ``|lag| <= max_lag``."""
    best = (None, 0)
    for lag in range(-max_lag, max_lag + 1):
        x, y = (a[: len(a) - lag], b[lag:]) if lag >= 0 else (a[-lag:], b[: len(b) + lag])
        n = min(len(x), len(y))
        r = pearson(x[:n], y[:n])
        if r is not None and (best[0] is None or r > best[0]):
            best = (r, lag)
    return best


def compare(person: dict[str, np.ndarray], P: np.ndarray) -> dict:
    """One render's points ``P`` against the person's gaps."""
    n = min(len(person["height"]), len(P))
    g = gaps(P[:n])
    a, b = person["height"][:n], g["height"]
    both = np.isfinite(a) & np.isfinite(b)
    r_lag, lag = best_lag(a, b)
    rd = lambda x: None if x is None else round(x, 3)
    return {
        "r": rd(pearson(a, b)),
        "r_eyes": rd(pearson(person["eyes"][:n], g["eyes"])),
        "r_outer": rd(pearson(person["outer"][:n], g["outer"])),
        "r_best_lag": rd(r_lag),
        "lag": lag,
        "frames_counted": int(both.sum()),
        "detected": round(float(np.isfinite(b).mean()), 3) if n else 0.0,
        "gap_sd": round(float(np.std(b[both])), 4) if both.any() else None,
        "person_gap_sd": round(float(np.std(a[both])), 4) if both.any() else None,
    }


def code_state() -> dict:
    """The face code a capture ran with: the commit, and the uncommitted changes under ``anima/`` (their files and
    a hash of their diff; others may be editing the tree while this runs)."""
    changed = git("diff", "HEAD", "--name-only", "--", "anima").splitlines()
    diff = git("diff", "HEAD", "--", "anima")
    return {
        "commit": git("rev-parse", "--short", "HEAD"),
        "anima_changed": changed,
        "anima_diff_sha1": hashlib.sha1(diff.encode()).hexdigest()[:12] if changed else None,
    }


def capture(clip: str, out: Path, fresh: bool) -> dict:
    """``anima capture CLIP --out OUT --face-only`` (cached on its ``manifest.json``, written last), and the code
    state it ran with (``OUT.code.json`` beside it)."""
    state = out.with_name(out.name + ".code.json")
    if (out / "manifest.json").exists() and (out / "avatar.mp4").exists() and not fresh:
        return json.loads(state.read_text()) if state.exists() else {"commit": None}
    if out.exists():
        subprocess.run(["rm", "-rf", str(out)], check=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    code = code_state() | {"captured": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    exe = Path(sys.executable).parent / "anima"
    cmd = [str(exe), "capture", str(asset(clip)), "--out", str(out), "--face-only", "--quiet"]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    write_json(state, code)
    return code


def render_ict(npz: Path):
    """The fitted ICT face (the clip's identity, the fit's expressions, no head turn), one colour, frame by frame
    (as ``benchmarks/face_readback.py``'s ``render_ict``)."""
    from anima.facemodel.ict import load_face_model
    from anima.io.sequence import read_sequence
    from anima.render.avatar import draw_smooth
    from anima.render.face import SKIN

    seq = read_sequence(npz, landmarks=False)
    model = load_face_model()
    tris = np.ascontiguousarray(model.triangles(), np.int64)
    base = model.neutral + np.einsum("k,kvc->vc", seq.identity, model.id_deltas[: len(seq.identity)])
    D = model.expr_deltas[[list(model.expr_names).index(n) for n in seq.expr_names]]
    c = base.mean(0)
    scale = ICT_SIZE / (np.ptp(base[:, 0]) * 1.1)
    for f in range(seq.n_frames):
        V = (base + np.einsum("e,evc->vc", seq.expression[f], D) - c) * scale
        img = np.full((ICT_SIZE, ICT_SIZE, 3), 28, np.uint8)
        draw_smooth(img, V + [ICT_SIZE / 2, -ICT_SIZE / 2, 0.0], tris, SKIN)
        yield img


def source_points(reader: Reader, clip: str, cache: Path) -> np.ndarray:
    """The person's points on the source video, cached by the file's size and time and the model's hash (they do
    not depend on anima)."""
    path = asset(clip)
    st = path.stat()
    key = hashlib.sha1(f"{path}|{st.st_size}|{st.st_mtime_ns}|{model_hash(reader.path)}".encode()).hexdigest()[:16]
    f = cache / f"{Path(clip).stem}.{key}.npy"
    if f.exists():
        return np.load(f)
    P = read_points(reader, video_frames(path))
    cache.mkdir(parents=True, exist_ok=True)
    tmp = f.with_suffix(".tmp.npy")
    np.save(tmp, P)
    tmp.replace(f)
    return P


_HASHES: dict[Path, str] = {}


def model_hash(path: Path) -> str:
    if path not in _HASHES:
        _HASHES[path] = hashlib.sha256(path.read_bytes()).hexdigest()
    return _HASHES[path]


def git(*args: str) -> str:
    root = Path(__file__).resolve().parents[1]
    return subprocess.run(["git", *args], capture_output=True, text=True, cwd=root).stdout.strip()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", default="/tmp/anima_mouth_independent", help="capture cache (one folder per clip)")
    ap.add_argument("--fresh", action="store_true", help="capture again even where a capture is cached")
    ap.add_argument("--no-ict", action="store_true", help="skip the fitted ICT face (the ceiling)")
    ap.add_argument("--only", nargs="*", help="only these of the clips' names (e.g. ANG surprised)")
    ap.add_argument("--clips", nargs="*", help="other clips (paths under the shared data) instead of the list")
    ap.add_argument("--out", help="the result file (default: benchmarks/results/mouth_independent.json, written "
                    "only for the whole default list; with --only or --clips, only where --out is given)")  # fmt: skip
    a = ap.parse_args()

    reader = Reader()
    work = Path(a.work)
    clips = [("clips", Path(c).stem, c) for c in a.clips] if a.clips else list(CLIPS)
    clips = [c for c in clips if not a.only or c[1] in a.only]
    out = a.out or (None if a.only or a.clips else Path(__file__).parent / "results" / "mouth_independent.json")
    rows, t0 = [], time.time()
    for s, name, clip in clips:
        t = time.time()
        folder = work / f"{s}_{name}"
        code = capture(clip, folder, a.fresh)
        P = source_points(reader, clip, work / "_source_dlib")
        person = gaps(P)
        C = read_points(reader, video_frames(folder / "avatar.mp4", crop_right_square=True), detect_scale=0.5)
        row = {
            "set": s,
            "clip": name,
            "path": clip,
            "frames": len(P),
            "avatar_frames": len(C),
            "person_detected": round(float(np.isfinite(person["height"]).mean()), 3),
            "character": compare(person, C),
            "code": code,
        }
        if not a.no_ict:
            row["ict"] = compare(person, read_points(reader, render_ict(folder / "capture.npz")))
        row["seconds"] = round(time.time() - t, 1)
        rows.append(row)
        ch, ict = row["character"], row.get("ict", {})
        print(f"{s:9s} {name:20s} frames {row['frames']:4d}  person {row['person_detected']:.2f}  "
              f"character r {ch['r']} (eyes {ch['r_eyes']}, outer {ch['r_outer']}, "
              f"best {ch['r_best_lag']}@{ch['lag']}) "
              f"det {ch['detected']:.2f} n {ch['frames_counted']}  ict r {ict.get('r')}  {row['seconds']} s",
              flush=True)  # fmt: skip
    if out is None:
        return
    rs = [r["character"]["r"] for r in rows]
    summary = {
        "clips": len(rows),
        "frames": int(sum(r["frames"] for r in rows)),
        "frames_counted": int(sum(r["character"]["frames_counted"] for r in rows)),
        "target_r": TARGET_R,
        "clips_at_target": int(sum(r is not None and r >= TARGET_R for r in rs)),
        "min_r": min((r for r in rs if r is not None), default=None),
        "below_target": [r["clip"] for r in rows if r["character"]["r"] is None or r["character"]["r"] < TARGET_R],
        "seconds": round(time.time() - t0, 1),
    }
    if not a.no_ict:
        ri = [r["ict"]["r"] for r in rows]
        summary["ict_clips_at_target"] = int(sum(r is not None and r >= TARGET_R for r in ri))
        summary["ict_min_r"] = min((r for r in ri if r is not None), default=None)
    write_json(out, {
        "what": "development check on shared clips (not held out); the reader shares nothing with anima",
        "protocol": "benchmarks/mouth_independent.py docstring",
        "reader": f"dlib {dlib.__version__} HOG detector + shape_predictor_68_face_landmarks.dat "
                  f"(face_recognition_models; sha256 {model_hash(reader.path)[:16]}; trained on iBUG 300-W, "
                  "research-only data)",
        "measure": "inner-lip gap (mean of 61-67, 62-66, 63-65) over the face's height (27-8), per frame; "
                   "r_eyes: over the outer eye corners (36-45); r_outer: outer lips (50-58, 51-57, 52-56) over 27-8",
        "code_when_read": code_state(),  # each row's "code": the code its capture ran with
        "summary": summary,
        "rows": rows,
    })  # fmt: skip
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
