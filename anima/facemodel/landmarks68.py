"""The 68 iBUG landmarks as ICT vertices, calibrated on annotated faces.

ICT ships 68 landmark vertices (and jawline substitutes); annotation conventions differ (where exactly a
brow or jaw point sits), so anima calibrates them once on 68-point annotated faces that are *not* test
images (``anima.capture.landmark_sets``): each point becomes the ICT face vertex, within ``radius_cm`` of the
upstream definition, whose projection under the fitted model is closest on average to the annotations.
The result is shipped as ``anima/facemodel/data/ibug68_vertices.json`` (project-made; rebuild with
``anima facemodel landmarks68``). Without it the upstream definition (+ jaw substitutes) is used.
"""

from __future__ import annotations

import json
from functools import lru_cache

import numpy as np

from anima.facemodel.ict import FaceModel
from anima.io.assets import package_data

FILENAME = "ibug68_vertices.json"
# ICT README: "Right jawline (substitutes 0-7 in Multi PIE)" and "Left jawline (substitutes 9-16)".
JAW_SUBSTITUTES = {
    0: 1278,
    1: 1272,
    2: 12,
    3: 1834,
    4: 243,
    5: 781,
    6: 2199,
    7: 1447,
    9: 3661,
    10: 4390,
    11: 3022,
    12: 2484,
    13: 4036,
    14: 2253,
    15: 3490,
    16: 3496,
}


def upstream_ibug68(model: FaceModel) -> np.ndarray:
    lm = model.landmarks68.astype(np.int64).copy()
    for i, v in JAW_SUBSTITUTES.items():
        lm[i] = v
    return lm


@lru_cache(maxsize=1)
def _load() -> np.ndarray | None:
    p = package_data(FILENAME)
    if not p.is_file():
        return None
    return np.asarray(json.loads(p.read_text())["vertices"], np.int64)


def ibug68_vertices(model: FaceModel) -> np.ndarray:
    """The calibrated 68 vertex indices (or the upstream definition if the file is absent)."""
    v = _load()
    return v if v is not None else upstream_ibug68(model)


def calibrate(model: FaceModel, uv_of_vertices: list, gts: list[np.ndarray], radius_cm: float = 1.2):
    """``uv_of_vertices[s]``: image points ``[V_face, 2]`` of the fitted face vertices of sample s,
    ``gts[s]``: its 68 annotated points. Returns (vertices ``[68]``, per-point mean NME before/after)."""
    face = np.arange(9409)
    base = upstream_ibug68(model)
    norm = [np.sqrt(np.prod(g.max(0) - g.min(0))) for g in gts]
    out = base.copy()
    before, after = np.full(68, np.nan), np.full(68, np.nan)
    for i in range(17, 68):  # the jawline keeps ICT's documented substitutes (conventions differ most there)
        d = np.linalg.norm(model.neutral[face] - model.neutral[base[i]], axis=1)
        cand = face[d < radius_cm]
        err = np.mean(
            [np.linalg.norm(uv[cand] - g[i], axis=1) / n for uv, g, n in zip(uv_of_vertices, gts, norm)], axis=0
        )
        j = int(np.argmin(err))
        out[i] = cand[j]
        before[i] = np.mean([np.linalg.norm(uv[base[i]] - g[i]) / n for uv, g, n in zip(uv_of_vertices, gts, norm)])
        after[i] = err[j]
    return out, before, after
