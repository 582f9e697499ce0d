"""Wavefront OBJ reader for polygon meshes (positions, UVs, faces up to quads)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from anima.errors import InputError


def read_obj(path: str | Path, max_corners: int = 4, dtype=np.float32) -> dict:
    """Return ``{"v": (N,3) dtype, "vt": (M,2) float32, "f": (P,C) int32, "ft": (P,C) int32}`` with
    0-based indices and ``-1`` padding for polygons with fewer than ``max_corners`` corners."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"OBJ file not found: {path}")
    v, vt, f, ft = [], [], [], []
    with open(path, encoding="utf-8", errors="replace") as fh:
        for line in fh:
            if line.startswith("v "):
                v.append(line.split()[1:4])
            elif line.startswith("vt "):
                vt.append(line.split()[1:3])
            elif line.startswith("f "):
                corners = line.split()[1:]
                if len(corners) > max_corners:
                    raise InputError(f"{path}: polygon with {len(corners)} corners (max {max_corners})")
                vi, ti = [], []
                for c in corners:
                    parts = c.split("/")
                    vi.append(int(parts[0]) - 1)
                    ti.append(int(parts[1]) - 1 if len(parts) > 1 and parts[1] else -1)
                pad = max_corners - len(corners)
                f.append(vi + [-1] * pad)
                ft.append(ti + [-1] * pad)
    if not v:
        raise InputError(f"{path}: no vertices (not an OBJ mesh?)")
    return {
        "v": np.asarray(v, dtype=dtype),
        "vt": np.asarray(vt, dtype=np.float32).reshape(-1, 2),
        "f": np.asarray(f, dtype=np.int32).reshape(-1, max_corners),
        "ft": np.asarray(ft, dtype=np.int32).reshape(-1, max_corners),
    }
