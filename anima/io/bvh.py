"""BVH (Biovision hierarchy) writer for anima skeletons and a general BVH reader with forward kinematics.

Writer (:func:`write_bvh`): every joint has channels ``Zrotation Xrotation Yrotation`` (the root also
``Xposition Yposition Zposition``), units centimetres, Y up. Bone lengths are fixed to their median over the
clip first. **Rest pose**: the clip's reference frame (the first frame where every joint is tracked) with
those bone lengths; rotations are relative to that pose. Joint positions are turned into rotations with
:func:`anima.core.bvh_math.positions_to_rotations`. Frames with missing joints hold the nearest tracked
values (the tracked-sequence file keeps the flags). Leaf joints get an ``End Site`` of zero length.

Reader (:func:`read_bvh`): any channel order, position channels on any joint, End Sites; returns names,
parents, offsets, frame time and joint positions by forward kinematics.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from anima.core.bvh_math import (
    axis_matrix,
    forward_kinematics,
    local_rotations,
    matrix_to_euler_zxy,
    positions_to_rotations,
)
from anima.core.skeleton import fix_bone_lengths
from anima.errors import InputError
from anima.io.atomic import write_text

M_TO_CM = 100.0


@dataclass
class BVH:
    names: list[str]
    parents: np.ndarray
    offsets: np.ndarray  # (J, 3)
    channels: list[list[str]]
    frame_time: float
    motion: np.ndarray  # (F, n_channels)

    def positions(self) -> np.ndarray:
        """Global joint positions ``[F, J, 3]`` by forward kinematics (file units)."""
        F, J = len(self.motion), len(self.names)
        L = np.tile(np.eye(3), (F, J, 1, 1))
        root_pos = np.zeros((F, 3))
        pos_local = np.zeros((F, J, 3))
        col = 0
        for j, chans in enumerate(self.channels):
            R = np.tile(np.eye(3), (F, 1, 1))
            for ch in chans:
                v = self.motion[:, col]
                col += 1
                if ch.endswith("rotation"):
                    R = R @ axis_matrix(ch[0].upper(), v)
                else:
                    pos_local[:, j, "XYZ".index(ch[0].upper())] = v
            L[:, j] = R
        F_, J_ = L.shape[:2]
        G = np.zeros_like(L)
        P = np.zeros((F_, J_, 3))
        for j in range(J_):
            p = self.parents[j]
            off = self.offsets[j] + pos_local[:, j]
            if p < 0:
                G[:, j] = L[:, j]
                P[:, j] = off
            else:
                G[:, j] = G[:, p] @ L[:, j]
                P[:, j] = P[:, p] + (G[:, p] @ off[:, :, None])[:, :, 0]
        del root_pos
        return P


def read_bvh(path: str | Path) -> BVH:
    path = Path(path)
    if not path.is_file():
        raise InputError(f"BVH file not found: {path}")
    tokens = path.read_text(errors="replace").split()
    names, parents, offsets, channels = [], [], [], []
    stack: list[int] = []
    i = 0
    pending_end = False
    try:
        while i < len(tokens) and tokens[i] != "MOTION":
            t = tokens[i]
            if t in ("ROOT", "JOINT"):
                names.append(tokens[i + 1])
                parents.append(stack[-1] if stack else -1)
                offsets.append([0.0, 0.0, 0.0])
                channels.append([])
                i += 2
            elif t == "End":
                pending_end = True
                i += 2
            elif t == "{":
                stack.append(-2 if pending_end else len(names) - 1)
                pending_end = False
                i += 1
            elif t == "}":
                stack.pop()
                i += 1
            elif t == "OFFSET":
                vals = [float(x) for x in tokens[i + 1 : i + 4]]
                if stack and stack[-1] != -2:
                    offsets[stack[-1]] = vals
                i += 4
            elif t == "CHANNELS":
                n = int(tokens[i + 1])
                channels[stack[-1]] = tokens[i + 2 : i + 2 + n]
                i += 2 + n
            else:
                i += 1
        # parents recorded while inside an End Site never happen (End Sites have no children)
        i += 1  # MOTION
        assert tokens[i] == "Frames:"
        n_frames = int(tokens[i + 1])
        assert tokens[i + 2] == "Frame" and tokens[i + 3] == "Time:"
        frame_time = float(tokens[i + 4])
        vals = np.array(tokens[i + 5 :], dtype=np.float64)
    except (IndexError, ValueError, AssertionError) as e:
        raise InputError(f"{path}: not a valid BVH file ({type(e).__name__})") from None
    n_ch = sum(len(c) for c in channels)
    if n_ch == 0 or vals.size < n_frames * n_ch:
        raise InputError(f"{path}: motion data has {vals.size} values, expected {n_frames} x {n_ch}")
    return BVH(
        names,
        np.array(parents),
        np.array(offsets, np.float64),
        channels,
        frame_time,
        vals[: n_frames * n_ch].reshape(n_frames, n_ch),
    )


def _hold_missing(P: np.ndarray) -> np.ndarray:
    P = P.copy()
    F = len(P)
    for j in range(P.shape[1]):
        ok = np.isfinite(P[:, j]).all(-1)
        if ok.all() or not ok.any():
            continue
        idx = np.flatnonzero(ok)
        near = idx[np.clip(np.searchsorted(idx, np.arange(F)), 0, len(idx) - 1)]
        prev = idx[np.clip(np.searchsorted(idx, np.arange(F)) - 1, 0, len(idx) - 1)]
        pick = np.where(np.abs(prev - np.arange(F)) < np.abs(near - np.arange(F)), prev, near)
        P[~ok, j] = P[pick[~ok], j]
    return P


def skeleton_rest_offsets(P: np.ndarray, parents: np.ndarray) -> tuple[np.ndarray, int]:
    """Rest offsets ``[J, 3]`` (reference frame's bone directions, median bone lengths) and the reference
    frame index."""
    ok = np.isfinite(P).all((1, 2))
    if not ok.any():
        raise InputError("no frame where every joint is tracked: cannot define a rest pose")
    ref = int(np.flatnonzero(ok)[0])
    par = np.where(parents < 0, 0, parents)
    vec = P - P[:, par]
    lengths = np.nanmedian(np.linalg.norm(vec, axis=-1), 0)
    d = vec[ref]
    n = np.linalg.norm(d, axis=-1, keepdims=True)
    off = np.where(n > 1e-9, d / np.maximum(n, 1e-9), 0.0) * lengths[:, None]
    off[parents < 0] = P[ref, parents < 0]
    return off, ref


def write_bvh(path: str | Path, joints_m: np.ndarray, names: list[str], parents: np.ndarray, fps: float) -> Path:
    """Write joint positions ``[F, J, 3]`` (metres) as a BVH in centimetres."""
    parents = np.asarray(parents)
    P = fix_bone_lengths(_hold_missing(np.asarray(joints_m, np.float64)) * M_TO_CM, parents=parents)
    offsets, _ = skeleton_rest_offsets(P, parents)
    G = positions_to_rotations(P, parents, offsets)
    L = local_rotations(G, parents)
    eul = matrix_to_euler_zxy(L)  # (F, J, 3)
    kids = {j: [int(c) for c in np.flatnonzero(parents == j)] for j in range(len(names))}
    lines = ["HIERARCHY"]

    def emit(j, depth):
        ind = "\t" * depth
        kw = "ROOT" if parents[j] < 0 else "JOINT"
        lines.append(f"{ind}{kw} {names[j]}")
        lines.append(f"{ind}{{")
        o = offsets[j] if parents[j] >= 0 else np.zeros(3)
        lines.append(f"{ind}\tOFFSET {o[0]:.6f} {o[1]:.6f} {o[2]:.6f}")
        if parents[j] < 0:
            lines.append(f"{ind}\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation")
        else:
            lines.append(f"{ind}\tCHANNELS 3 Zrotation Xrotation Yrotation")
        for c in kids[j]:
            emit(c, depth + 1)
        if not kids[j]:
            lines.append(f"{ind}\tEnd Site")
            lines.append(f"{ind}\t{{")
            lines.append(f"{ind}\t\tOFFSET 0.000000 0.000000 0.000000")
            lines.append(f"{ind}\t}}")
        lines.append(f"{ind}}}")

    order = []

    def dfs(j):
        order.append(j)
        for c in kids[j]:
            dfs(c)

    root = int(np.flatnonzero(parents < 0)[0])
    emit(root, 0)
    dfs(root)
    lines += ["MOTION", f"Frames: {len(P)}", f"Frame Time: {1.0 / fps:.8f}"]
    for f in range(len(P)):
        row = [*P[f, root]] + [v for j in order for v in eul[f, j]]
        lines.append(" ".join(f"{v:.5f}" for v in row))
    return write_text(path, "\n".join(lines) + "\n")


def bvh_to_anima_order(b: BVH, names: list[str]) -> np.ndarray:
    """Positions of ``b`` in the joint order ``names`` (file units)."""
    P = b.positions()
    return P[:, [b.names.index(n) for n in names]]


__all__ = ["BVH", "read_bvh", "write_bvh", "bvh_to_anima_order", "forward_kinematics"]
