"""A skinned character and a motion on its skeleton, declared once: what the character writers take
(:func:`anima.io.gltf.write_character_glb`, :func:`anima.io.gltf.write_vrma`) instead of long argument lists.
Plain data, metres, glTF's axes (+y up, +z the character's forward)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Skeleton:
    """Joints ``names [J]`` with ``parents [J]`` (-1 for the root; parents first) at their rest world positions
    ``rest [J, 3]``. ``rest_rotations [J, 3, 3]``: the joints' rest *world* rotations (None: identity, anima's own
    rig; a rig with other rest axes, an A-pose or rolled bones, has them)."""

    names: list[str]
    parents: np.ndarray
    rest: np.ndarray
    rest_rotations: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class CharacterMesh:
    """A skinned mesh on ``skeleton``: rest-pose ``vertices [V, 3]`` with ``normals [V, 3]`` and ``faces [T, 3]``,
    four joints and weights a vertex (``skin_joints``, ``skin_weights [V, 4]``), morph targets ``morphs``
    (``(vertex indices, deltas)`` each) named ``morph_names``, and optional vertex ``colors [V, 3]`` (linear RGB
    in [0, 1])."""

    skeleton: Skeleton
    vertices: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    skin_joints: np.ndarray
    skin_weights: np.ndarray
    morphs: list[tuple[np.ndarray, np.ndarray]]
    morph_names: list[str]
    colors: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class Motion:
    """A motion on a skeleton at ``fps``: the root's position ``root [F, 3]``, the joints' local rotations
    ``local_quats [F, J, 4]`` (x, y, z, w), morph ``weights [F, E]`` (None: none), and which joints it animates
    (``animated [J]`` booleans; None: every joint)."""

    root: np.ndarray
    local_quats: np.ndarray
    fps: float
    weights: np.ndarray | None = None
    animated: np.ndarray | None = None

    @property
    def n_frames(self) -> int:
        return len(self.root)
