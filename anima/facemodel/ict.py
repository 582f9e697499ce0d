"""ICT-FaceKit light: a linear face model with 100 identity PCA shapes and 53 ARKit-named expressions.

``V(id, e) = neutral + sum_i id_i * id_deltas[i] + sum_j e_j * expr_deltas[j]``, in centimetres, with
identity coefficients unbounded (PCA modes, ~N(0, 1)) and expression weights in [0, 1].

Two ways in, one model out:
* :func:`import_ict_obj` reads the upstream OBJ files (what a user downloads from ICT-VGL/ICT-FaceKit);
* :func:`load_face_model` reads the compact ``ict_facekit_light.npz`` (same arrays, see data README).
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from anima.core.contract import N_EXPR, N_IDENTITY
from anima.errors import InputError
from anima.io.assets import asset
from anima.io.atomic import write_npz
from anima.io.mapped import cache_key, file_stamp, mapped_arrays
from anima.io.obj import read_obj
from anima.io.outdir import check_out_file
from anima.io.owned import npz
from anima.io.validate import parse_json

N_ID = N_IDENTITY

# Geometry ranges from the upstream README's topology table (inclusive vertex / polygon index ranges).
GEOMETRY_RANGES = {
    "face": ((0, 9408), (0, 9229)),
    "narrow_face": ((0, 6705), (0, 6559)),
    "head_neck": ((9409, 11247), (9230, 11143)),
    "mouth_socket": ((11248, 13293), (11144, 13225)),
    "eye_socket_left": ((13294, 13677), (13226, 13629)),
    "eye_socket_right": ((13678, 14061), (13630, 14033)),
    "gums_tongue": ((14062, 17038), (14034, 17005)),
    "teeth": ((17039, 21450), (17006, 21495)),
    "eyeball_left": ((21451, 23020), (21496, 23093)),
    "eyeball_right": ((23021, 24590), (23094, 24691)),
    "iris_left": ((22221, 23020), (22296, 23093)),
    "iris_right": ((23791, 24590), (23894, 24691)),
    "lacrimal_fluid": ((24591, 24998), (24692, 25017)),
    "eye_blend": ((24999, 25046), (25018, 25047)),
    "eye_occlusion": ((25047, 25350), (25048, 25303)),
    "eyelashes": ((25351, 26718), (25304, 26383)),
}
# The skin surface a face tracker sees; used for fitting, rendering and exports.
SKIN_REGIONS = ("face", "head_neck")


@dataclass
class FaceModel:
    neutral: np.ndarray  # (V, 3) float32, cm
    id_deltas: np.ndarray  # (100, V, 3)
    expr_deltas: np.ndarray  # (53, V, 3)
    faces: np.ndarray  # (P, 4) int32, -1 pads triangles
    expr_names: list[str]
    landmarks68: np.ndarray  # (68,) vertex indices (iBUG / Multi-PIE order)
    uvs: np.ndarray | None = None
    face_uvs: np.ndarray | None = None
    vertex_indices: dict = field(default_factory=dict)
    vertex_ids: np.ndarray | None = None  # original vertex index of each row when this is a subset

    @property
    def n_vertices(self) -> int:
        return self.neutral.shape[0]

    # ---- evaluation -------------------------------------------------------------------------
    def vertices(self, identity: np.ndarray | None = None, expression: np.ndarray | None = None) -> np.ndarray:
        """Evaluate vertices. identity ``[..., 100]`` or None, expression ``[..., 53]`` or None; leading
        batch axes broadcast. Returns ``[..., V, 3]`` float32 (cm)."""
        out = self.neutral.astype(np.float32)
        if identity is not None:
            identity = np.asarray(identity, np.float32)
            if identity.shape[-1] != self.id_deltas.shape[0]:
                raise ValueError(f"identity must have {self.id_deltas.shape[0]} coefficients, got {identity.shape}")
            out = out + np.tensordot(identity, self.id_deltas, axes=([-1], [0]))
        if expression is not None:
            expression = np.asarray(expression, np.float32)
            if expression.shape[-1] != self.expr_deltas.shape[0]:
                raise ValueError(f"expression must have {self.expr_deltas.shape[0]} weights, got {expression.shape}")
            out = out + np.tensordot(expression, self.expr_deltas, axes=([-1], [0]))
        return out

    def triangles(self) -> np.ndarray:
        """Polygons split into triangles ``(T, 3)`` (quads as (a,b,c), (a,c,d))."""
        f = self.faces
        tri = f[:, [0, 1, 2]]
        quad = f[f[:, 3] >= 0]
        return np.concatenate([tri, quad[:, [0, 2, 3]]], 0).astype(np.int32)

    # ---- regions ----------------------------------------------------------------------------
    def region(self, name: str) -> np.ndarray:
        """Vertex indices of a named region (see :func:`region_names`)."""
        if self.vertex_ids is not None:
            raise ValueError("regions are defined on the full model; call region() before subset()")
        return region_vertices(self, name)

    def subset(self, vertex_idx: np.ndarray) -> FaceModel:
        """Restrict to ``vertex_idx``; keeps polygons whose corners are all inside. Landmarks must be in."""
        vertex_idx = np.asarray(vertex_idx, np.int64)
        remap = -np.ones(self.n_vertices + 1, np.int64)
        remap[vertex_idx] = np.arange(len(vertex_idx))
        f = remap[self.faces]  # -1 index maps to remap[-1] = -1
        f[self.faces < 0] = -1
        keep = (f[:, :3] >= 0).all(1) & ((self.faces[:, 3] < 0) | (f[:, 3] >= 0))
        lm = remap[self.landmarks68]
        return FaceModel(
            neutral=self.neutral[vertex_idx],
            id_deltas=self.id_deltas[:, vertex_idx],
            expr_deltas=self.expr_deltas[:, vertex_idx],
            faces=f[keep].astype(np.int32),
            expr_names=self.expr_names,
            landmarks68=lm.astype(np.int32),
            uvs=self.uvs,
            face_uvs=None if self.face_uvs is None else self.face_uvs[keep],
            vertex_indices=self.vertex_indices,
            vertex_ids=vertex_idx,
        )

    def skin(self) -> FaceModel:
        """The face + head/neck skin surface only (11,248 of 26,719 vertices): fast path for fitting and
        rendering."""
        return self.subset(np.concatenate([self.region(r) for r in SKIN_REGIONS]))


def region_names() -> list[str]:
    return list(GEOMETRY_RANGES) + ["mouth", "eyes", "lower_face", "upper_face", "fitting", "rigid"]


def region_vertices(model: FaceModel, name: str) -> np.ndarray:
    """Regions: the upstream geometry ranges (``face``, ``teeth``, ...), the vertex sets of
    ``vertex_indices.json`` (``fitting`` = idx_to_fitting_verts, ``rigid`` = idx_to_rigid_verts), and
    derived face areas used for metrics: ``mouth`` (face vertices within 1.2 cm of the lip landmarks
    48-67 in the neutral mesh, plus a 2.2 cm chin/lip band), ``eyes`` (face vertices within 1.5 cm of the
    eye landmarks 36-47), ``lower_face`` (face vertices below the nose base, landmark 33) and
    ``upper_face`` (the rest of the face)."""
    if name in GEOMETRY_RANGES:
        a, b = GEOMETRY_RANGES[name][0]
        return np.arange(a, b + 1)
    if name == "fitting":
        return np.asarray(model.vertex_indices["idx_to_fitting_verts"], np.int64)
    if name == "rigid":
        return np.asarray(model.vertex_indices["idx_to_rigid_verts"], np.int64)
    face = np.arange(GEOMETRY_RANGES["face"][0][0], GEOMETRY_RANGES["face"][0][1] + 1)
    P = model.neutral[face]
    lm = model.neutral[model.landmarks68]
    if name in ("mouth", "eyes"):
        idx = np.arange(48, 68) if name == "mouth" else np.arange(36, 48)
        radius = 1.2 if name == "mouth" else 1.5
        d = np.linalg.norm(P[:, None, :] - lm[idx][None], axis=-1).min(1)
        return face[d < radius]
    if name in ("lower_face", "upper_face"):
        below = P[:, 1] < lm[33, 1]
        return face[below] if name == "lower_face" else face[~below]
    raise KeyError(f"unknown region {name!r}; known: {', '.join(region_names())}")


# ---- loading ------------------------------------------------------------------------------------


def _from_arrays(d: dict) -> FaceModel:
    names = [str(n) for n in d["expr_names"]]
    vi = json.loads(str(d["vertex_indices_json"])) if "vertex_indices_json" in d else {}
    order = vi.get("expressions", names[:N_EXPR])
    pos = [names.index(n) for n in order]
    return FaceModel(
        neutral=np.asarray(d["neutral"], np.float32),
        id_deltas=np.asarray(d["id_deltas"], np.float32),
        expr_deltas=np.asarray(d["expr_deltas"], np.float32)[pos],
        faces=np.asarray(d["faces"], np.int32),
        expr_names=list(order),
        landmarks68=np.asarray(d["landmarks68"], np.int32),
        uvs=np.asarray(d["uvs"], np.float32) if "uvs" in d else None,
        face_uvs=np.asarray(d["face_uvs"], np.int32) if "face_uvs" in d else None,
        vertex_indices=vi,
    )


@lru_cache(maxsize=2)
def load_face_model(path: str | None = None) -> FaceModel:
    """Load the compact npz (default: the asset ``ict-facekit/ict_facekit_light.npz``), through a
    memory-mapped cache of its arrays (:func:`_mapped_arrays`)."""
    p = Path(path) if path else asset("ict-facekit/ict_facekit_light.npz")
    if not p.is_file():
        raise InputError(f"face model file not found: {p}")
    return _from_arrays(_mapped_arrays(p))


def _npz_arrays(p: Path) -> dict:
    with np.load(p, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def _mapped_arrays(p: Path) -> dict:
    """The npz's arrays through a memory-mapped cache (:mod:`anima.io.mapped`, keyed on the file's path,
    size and time): inflating the compressed npz costs about 0.4 s on every command's start, mapping the
    copy about 10 ms, and the 100 identity shapes are only paged in where used."""
    return mapped_arrays("face_model", cache_key(file_stamp(p)), lambda: _npz_arrays(p))


def import_ict_obj(folder: str | Path, vertex_indices_json: str | Path | None = None) -> dict:
    """Import the upstream ICT-FaceKit OBJ folder (``FaceXModel/``) into the npz's arrays.

    Reads ``generic_neutral_mesh.obj``, every ``identityNNN.obj`` and every expression OBJ present
    (the 53 of ``vertex_indices.json`` in that order, then any extras in name order). Returns a dict with
    the keys of ``ict_facekit_light.npz``; ``expr_deltas``/``id_deltas`` hold only the shapes found.
    """
    folder = Path(folder)
    neutral_path = folder / "generic_neutral_mesh.obj"
    if not neutral_path.is_file():
        raise InputError(f"{folder}: no generic_neutral_mesh.obj (expected the FaceXModel folder of ICT-FaceKit)")
    vi_path = Path(vertex_indices_json) if vertex_indices_json else folder / "vertex_indices.json"
    if not vi_path.is_file():
        vi_path = folder.parent / "vertex_indices.json"
    if not vi_path.is_file():
        vi_path = asset("ict-facekit/vertex_indices.json")
    vi_text = vi_path.read_text(encoding="utf-8", errors="replace")
    vi = parse_json(vi_text, str(vi_path))
    if not isinstance(vi, dict) or not isinstance(vi.get("expressions"), list) or "idx_to_landmark_verts" not in vi:
        raise InputError(f"{vi_path}: not ICT-FaceKit's vertex_indices.json (no expressions / landmark vertices)")

    def vertices(p):
        v = read_obj(p, dtype=np.float64)
        if not np.isfinite(v["v"]).all() or np.abs(v["v"]).max(initial=0) > 1e5:
            raise InputError(f"{p}: vertex coordinates that are not finite or beyond 1 km: not a face model")
        return v

    base = vertices(neutral_path)  # deltas are taken in double precision, then stored f32
    neutral = base["v"]
    skip = {"generic_neutral_mesh"}
    id_files = sorted(p for p in folder.glob("identity*.obj") if re.fullmatch(r"identity\d+", p.stem))
    expr_all = {
        p.stem: p for p in folder.glob("*.obj") if p.stem not in skip and not re.fullmatch(r"identity\d+", p.stem)
    }
    order = [n for n in vi["expressions"] if n in expr_all] + sorted(set(expr_all) - set(vi["expressions"]))

    def deltas(paths):
        out = np.zeros((len(paths), *neutral.shape), np.float32)
        for i, p in enumerate(paths):
            v = vertices(p)["v"]
            if v.shape != neutral.shape:
                raise InputError(f"{p}: {v.shape[0]} vertices, expected {neutral.shape[0]}")
            out[i] = (v - neutral).astype(np.float32)
        return out

    return {
        "neutral": neutral.astype(np.float32),
        "expr_names": np.asarray(order),
        "expr_deltas": deltas([expr_all[n] for n in order]),
        "id_names": np.asarray([p.stem for p in id_files]),
        "id_deltas": deltas(id_files),
        "faces": base["f"],
        "uvs": base["vt"].astype(np.float32),
        "face_uvs": base["ft"],
        "vertex_indices_json": np.asarray(vi_text),
        "landmarks68": np.asarray(vi["idx_to_landmark_verts"], np.int32),
    }


def write_face_model(folder: str | Path, out: str | Path) -> dict:
    """``anima facemodel import``: the upstream OBJ folder -> an npz with the keys of ``ict_facekit_light.npz``
    (written atomically); returns a summary."""
    check_out_file(
        out, inputs=[folder], suffixes=(".npz",), ours=npz("id_names", "expr_names", "faces"), what="a face model"
    )
    d = import_ict_obj(folder)
    write_npz(out, **d)
    return {"out": str(out), "identity_shapes": len(d["id_names"]), "expression_shapes": len(d["expr_names"])}
