"""BVH (Biovision hierarchy) writer for anima skeletons and a general BVH reader with forward kinematics.

Writer (:func:`write_bvh`): a skeleton given by its rest offsets and its motion as root positions and local
rotations relative to that rest pose; every joint has channels ``Zrotation Xrotation Yrotation`` (the root
also ``Xposition Yposition Zposition``), units metres (as anima's every file; Blender's importer takes
them 1:1), Y up. anima's exports write the canonical rig
(``anima.core.rig``: T-pose rest, conventional names) through it (``anima.export.formats.export_bvh``).

Reader (:func:`read_bvh`): any channel order, position channels on any joint, End Sites; returns names,
parents, offsets, frame time and joint positions by forward kinematics.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from anima.core.bvh_math import axis_matrix, matrix_to_euler_zxy
from anima.core.kinematics import forward, forward_kinematics
from anima.errors import InputError
from anima.io.atomic import write_text


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
        return forward(L, self.parents, self.offsets[None] + pos_local)[1]


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


def write_bvh(
    path: str | Path,
    names: list[str],
    parents: np.ndarray,
    offsets_m: np.ndarray,
    root_m: np.ndarray,
    local_rotations_: np.ndarray,
    fps: float,
    end_sites_m: np.ndarray | None = None,
) -> Path:
    """Write a skeleton and its motion as BVH, in metres: rest offsets ``[J, 3]`` (the rest pose: every
    local rotation identity), root positions ``[F, 3]``, local rotations ``[F, J, 3, 3]`` relative to the rest
    pose (channels Zrotation Xrotation Yrotation; the root also Xposition Yposition Zposition), and for each
    leaf an End Site ``end_sites_m[j]`` (default zero). Written atomically."""
    parents = np.asarray(parents)
    offsets = np.asarray(offsets_m, np.float64)
    root = np.asarray(root_m, np.float64)
    ends = np.zeros_like(offsets) if end_sites_m is None else np.asarray(end_sites_m, np.float64)
    eul = matrix_to_euler_zxy(local_rotations_)  # (F, J, 3)
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
            e = ends[j]
            lines.append(f"{ind}\tEnd Site")
            lines.append(f"{ind}\t{{")
            lines.append(f"{ind}\t\tOFFSET {e[0]:.6f} {e[1]:.6f} {e[2]:.6f}")
            lines.append(f"{ind}\t}}")
        lines.append(f"{ind}}}")

    order = []

    def dfs(j):
        order.append(j)
        for c in kids[j]:
            dfs(c)

    r = int(np.flatnonzero(parents < 0)[0])
    emit(r, 0)
    dfs(r)
    lines += ["MOTION", f"Frames: {len(root)}", f"Frame Time: {1.0 / fps:.8f}"]
    motion = np.concatenate([root, eul[:, order].reshape(len(root), -1)], 1)  # [F, 3 + 3J], the channel order
    row = " ".join(["%.6f"] * motion.shape[1])  # one format per row: 3x faster than one per value
    lines += [row % tuple(r) for r in motion.tolist()]
    return write_text(path, "\n".join(lines) + "\n")


def bvh_to_anima_order(b: BVH, names: list[str]) -> np.ndarray:
    """Positions of ``b`` in the joint order ``names`` (file units)."""
    P = b.positions()
    return P[:, [b.names.index(n) for n in names]]


__all__ = ["BVH", "read_bvh", "write_bvh", "bvh_to_anima_order", "forward_kinematics"]
