"""``anima facemodel correspondence``: rebuild the MediaPipe <-> ICT correspondence from MediaPipe run on
real portraits (the template of :mod:`anima.facemodel.correspondence`, step 1)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from anima.core.camera import mediapipe_to_camera
from anima.errors import InputError
from anima.facemodel.correspondence import (
    DEFAULT_TEMPLATE_IMAGES,
    FILENAME,
    build_correspondence,
    procrustes_mean,
    save_correspondence,
)
from anima.facemodel.ict import load_face_model
from anima.io.assets import asset, package_data
from anima.io.outdir import check_out_file
from anima.io.validate import npz_headers
from anima.track import get


def mediapipe_template(images: list[np.ndarray]) -> np.ndarray:
    """Generalised-Procrustes mean of MediaPipe landmarks (camera space) over RGB images."""
    shapes = []
    with get().face_mesh(static=True) as tr:
        for im in images:
            lm = tr(im)
            if lm is not None:
                shapes.append(mediapipe_to_camera(lm, im.shape[1], im.shape[0]))
    return procrustes_mean(shapes)


def read_rgb(path: str | Path) -> np.ndarray:
    im = cv2.imread(str(path))
    if im is None:
        raise InputError(f"cannot read image {path} (missing, or not an image OpenCV can decode)")
    return np.ascontiguousarray(im[:, :, ::-1])


def rebuild_correspondence(images: list[str] | None = None, out: str | Path | None = None) -> dict:
    """Rebuild and save the correspondence (default: the packaged file from the documented portraits)."""
    dest = Path(out) if out else package_data(FILENAME)
    check_out_file(
        dest, inputs=images or (), suffixes=(".npz",), what="a correspondence",
        ours=lambda q: {"vertex_ids", "bary", "meta"} <= set(npz_headers(q)),
    )  # fmt: skip
    paths = images or [str(asset(p)) for p in DEFAULT_TEMPLATE_IMAGES]
    ims = [read_rgb(p) for p in paths]
    c = build_correspondence(mediapipe_template(ims), load_face_model())
    save_correspondence(c, dest)
    return {"out": str(dest), "valid": int(c.valid.sum()), **c.meta}
