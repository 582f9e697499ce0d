"""The target database (seed 001 §3.2, fig. 3.3): per target frame, ICT expression weights, head pose and
weak-perspective camera, and the colours of the re-enacted region's vertices sampled at their projected
positions. Several videos of the same person form one database (each keeps its own identity).

Region (``REGION``): the ICT face vertices below the nose base (``lower_face``) plus the model's own mouth
interior geometry (``mouth_socket``, ``teeth``, ``gums_tongue``): the seed fills the BFM's mouth hole by a
Delaunay fan from its boundary; the ICT model has real interior geometry, so the interior is sampled and
rendered like the skin, deterministically, with the z-buffer deciding what shows.

Artifact ``anima.reenact_db`` v1 (``.npz``, no pickles; one writer :func:`write_database`, one reader
:func:`read_database`):

==============  =================  ==================================================================
array           shape, dtype       meaning
==============  =================  ==================================================================
expression      (N, 53) f4         ICT expression weights per database frame
rotation        (N, 3) f4          head rotation (axis-angle), model to camera
scale           (N,) f4            weak-perspective scale, pixels per cm
translation     (N, 3) f4          camera-space translation, pixels
video           (N,) i4            index into meta.videos
frame           (N,) i4            frame index in that video
identity        (M, 100) f4        ICT identity per video
colors          (N, V, 3) u1       RGB of the region's V vertices in each frame
vertex_ids      (V,) i4            the region's vertex indices in the full ICT model
==============  =================  ==================================================================

``meta`` (JSON): schema, version, videos (path, fps, width, height, n_frames), region, face_model,
anima_version.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from anima import __version__
from anima.capture.config import CaptureConfig
from anima.capture.pipeline import capture_face
from anima.errors import InputError, SchemaError
from anima.facemodel.ict import load_face_model
from anima.io.atomic import write_npz
from anima.io.validate import check_expansion, input_file, npz_headers, parse_json
from anima.io.video import iter_frames, probe_video
from anima.reenact.render import visible_vertices

SCHEMA = "anima.reenact_db"
VERSION = 1
REGION = ("lower_face", "mouth_socket", "teeth", "gums_tongue")
MIN_FRAMES = 100  # the seed's n = 100 nearest frames need at least this many


@dataclass
class ReenactDB:
    expression: np.ndarray
    rotation: np.ndarray
    scale: np.ndarray
    translation: np.ndarray
    video: np.ndarray
    frame: np.ndarray
    identity: np.ndarray
    colors: np.ndarray  # (N, V, 3) uint8
    vertex_ids: np.ndarray
    meta: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.expression)


def region_ids(model) -> np.ndarray:
    """The re-enacted vertices: the lower face cut to the inside of the jaw line (iBUG points 3-13 of the
    neutral mesh, so the neck, the ears and the silhouette, where projected colours would be background,
    stay the target's own pixels) plus the mouth interior geometry."""
    from matplotlib.path import Path as Poly

    lower = model.region("lower_face")
    lm = model.neutral[model.landmarks68]
    top = lm[33, 1] + 0.5
    jaw = lm[3:14, :2]
    poly = np.concatenate([[[jaw[0, 0], top + 5.0]], jaw, [[jaw[-1, 0], top + 5.0]]])
    inside = Poly(poly).contains_points(model.neutral[lower, :2])
    interior = np.concatenate([model.region(r) for r in REGION[1:]])
    return np.unique(np.concatenate([lower[inside], interior])).astype(np.int32)


INTERIOR = REGION[1:]
RING_CM = 1.0  # skin ring: lower-face skin farther than this from every lip landmark (neutral mesh)


def skin_ring(model, vertex_ids: np.ndarray) -> np.ndarray:
    """Boolean mask over ``vertex_ids``: the lower-face skin around the mouth (not the mouth interior, not
    within ``RING_CM`` of the lips), whose colour tells a frame's lighting and white balance and hardly
    changes with the expression. ``model`` is the full face model."""
    vertex_ids = np.asarray(vertex_ids, np.int64)
    interior = np.concatenate([model.region(r) for r in INTERIOR])
    lips = model.neutral[model.landmarks68[48:68]]
    d = np.linalg.norm(model.neutral[vertex_ids][:, None] - lips[None], axis=-1).min(1)
    return np.isin(vertex_ids, model.region("lower_face")) & ~np.isin(vertex_ids, interior) & (d > RING_CM)


def seen_region(model, vertex_ids: np.ndarray, tris: np.ndarray, seen: np.ndarray) -> np.ndarray:
    """The region's vertices worth keeping: all skin, and the mouth interior's vertices on a triangle that
    has a vertex the z-buffer showed in some database frame (``seen``, over ``vertex_ids``). Teeth, gums and
    tongue never seen in the target only cost texture and raster time, and their colours would be sampled
    from whatever covers them. Returns a boolean mask over ``vertex_ids``."""
    interior = np.isin(vertex_ids, np.concatenate([model.region(r) for r in INTERIOR]))
    keep = ~interior
    on_seen = seen[tris].any(1)
    keep[np.unique(tris[on_seen])] = True
    return keep


def sample_colors(frame: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear RGB at pixel positions ``uv`` (V, 2) (pixel centres at integer + 0.5 as in the rasterizer)."""
    import cv2

    m = np.ascontiguousarray((uv - 0.5).astype(np.float32))
    out = cv2.remap(frame, m[:, 0:1], m[:, 1:2], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return out[:, 0, :]


def build_database(
    videos: list[str],
    max_frames: int | None = None,
    progress: bool = True,
    exclude: dict[int, tuple[int, int]] | None = None,
    seqs: list | None = None,
    visible_only: bool = True,
):
    """Capture each target video (face only; or take the given ``seqs``), then sample the region's colours
        in every well-tracked frame. ``exclude``: per video index, a frame range kept out of the database
        (self-re-enactment). ``visible_only``: drop the mouth-interior vertices the z-buffer never showed in any
    kept frame (:func:`seen_region`). Returns (database, the target sequences)."""
    from tqdm import tqdm

    model = load_face_model()
    vid = region_ids(model)
    sub = model.subset(vid)
    tris = sub.triangles()
    seen = np.zeros(len(vid), bool)
    rows = {k: [] for k in ("expression", "rotation", "scale", "translation", "video", "frame", "colors")}
    identities, metas, out_seqs = [], [], []
    for vi, path in enumerate(videos):
        seq = seqs[vi] if seqs else capture_face(str(path), CaptureConfig(max_frames=max_frames), progress=progress)
        out_seqs.append(seq)
        identities.append(seq.identity)
        metas.append(
            {
                "path": str(Path(path).resolve()),
                "fps": seq.fps,
                "width": seq.width,
                "height": seq.height,
                "n_frames": seq.n_frames,
            }
        )
        R = seq.rotation_matrices()
        good = seq.flags == 0
        lo, hi = (exclude or {}).get(vi, (0, 0))
        V = sub.vertices(seq.identity[None], seq.expression)  # (F, V, 3)
        X = seq.scale[:, None, None] * np.einsum("fij,fnj->fni", R, V) + seq.translation[:, None, :]
        uv = np.stack([X[..., 0], -X[..., 1]], -1)
        info = probe_video(path)
        for f, rgb in enumerate(
            tqdm(
                iter_frames(info),
                total=seq.n_frames,
                disable=not progress,
                desc=f"database {Path(path).name}",
                unit="frame",
            )
        ):
            if f >= seq.n_frames:
                break
            if not good[f] or lo <= f < hi:
                continue
            rows["colors"].append(sample_colors(rgb, uv[f]))
            seen |= visible_vertices(np.concatenate([uv[f], X[f, :, 2:3]], 1), tris)
            rows["expression"].append(seq.expression[f])
            rows["rotation"].append(seq.rotation[f])
            rows["scale"].append(seq.scale[f])
            rows["translation"].append(seq.translation[f])
            rows["video"].append(vi)
            rows["frame"].append(f)
    n = len(rows["frame"])
    if n < MIN_FRAMES:
        raise InputError(
            f"the target gives {n} usable frames; the database needs at least {MIN_FRAMES} "
            f"(the seed's n = 100 nearest frames): use a longer target video or several"
        )
    keep = seen_region(model, vid, tris, seen) if visible_only else np.ones(len(vid), bool)
    arr = {k: np.asarray(v) for k, v in rows.items()}
    arr["colors"] = arr["colors"][:, keep]
    vid = vid[keep]
    return ReenactDB(
        arr["expression"].astype(np.float32),
        arr["rotation"].astype(np.float32),
        arr["scale"].astype(np.float32),
        arr["translation"].astype(np.float32),
        arr["video"].astype(np.int32),
        arr["frame"].astype(np.int32),
        np.asarray(identities, np.float32),
        arr["colors"].astype(np.uint8),
        vid,
        {
            "videos": metas,
            "region": list(REGION),
            "region_vertices": {"all": int(len(keep)), "kept": int(keep.sum()), "visible_only": visible_only},
            "anima_version": __version__,
            "face_model": "ICT-FaceKit light",
        },
    ), out_seqs


def write_database(db: ReenactDB, path: str | Path) -> Path:
    meta = dict(db.meta, schema=SCHEMA, version=VERSION)
    write_npz(
        path,
        compressed=False,
        expression=db.expression,
        rotation=db.rotation,
        scale=db.scale,
        translation=db.translation,
        video=db.video,
        frame=db.frame,
        identity=db.identity,
        colors=db.colors,
        vertex_ids=db.vertex_ids,
        meta=np.array(json.dumps(meta)),
    )
    return Path(path)


DB_ARRAYS = ("expression", "rotation", "scale", "translation", "video", "frame", "identity", "colors", "vertex_ids")
PER_FRAME = ("expression", "rotation", "scale", "translation", "video", "frame", "colors")


def read_database(path: str | Path) -> ReenactDB:
    """Read a database written by :func:`write_database`, checked from the npz headers before anything is
    inflated (declared sizes bounded by the file's, :func:`anima.io.validate.check_expansion`), then for
    consistent frame counts and finite values."""
    path = input_file(path, "re-enactment database")
    headers = npz_headers(path)
    missing = [k for k in (*DB_ARRAYS, "meta") if k not in headers]
    if missing:
        raise SchemaError(f"{path} is not an {SCHEMA} file (no {', '.join(missing)})")
    check_expansion(path, headers, [*DB_ARRAYS, "meta"])
    n = headers["expression"][0][0] if headers["expression"][0] else -1
    if any(not headers[k][0] or headers[k][0][0] != n for k in PER_FRAME) or headers["meta"][1].kind != "U":
        raise SchemaError(f"{path}: its arrays do not describe one frame per row")
    try:
        with np.load(path, allow_pickle=False) as d:
            meta = parse_json(str(d["meta"][()]), f"{path} (meta)")
            arrays = {k: d[k] for k in DB_ARRAYS}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as e:
        raise InputError(f"{path} is not a readable re-enactment database ({str(e)[:100]})") from None
    if not isinstance(meta, dict) or meta.get("schema") != SCHEMA:
        raise SchemaError(f"{path} is not an {SCHEMA} file")
    if meta.get("version") != VERSION:
        raise SchemaError(f"{path} is {SCHEMA} version {meta.get('version')}; this anima reads version {VERSION}")
    for k, a in arrays.items():
        if a.dtype.kind == "f" and not np.isfinite(a).all():
            raise InputError(f"{path}: {k} holds NaN or infinite values")
    return ReenactDB(*(arrays[k] for k in DB_ARRAYS), meta=meta)
