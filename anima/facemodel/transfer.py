"""Expression transfer by geometry: the character's face moved as the fitted ICT face moves, not by the names of
their blendshapes. Pure functions.

The 53 weights fitted on the ICT face mean "this much of ICT's jawOpen, of ICT's mouthSmile_L"; the character's
own 53 morphs (MakeHuman's Face Units) carry the same names but move its face differently (its jawOpen parts
the lips less, its smile lifts the corners less, its brows barely move). Applied by name, a man frowning hard
reads as a blank face. Here the character's weights are chosen, per frame, so that twelve points of its face
move as the same twelve points of the fitted face do:

* **The points** (:func:`face_points`), found on each model by what its own morphs do (the same definitions
  on both, so their semantics match): the upper lid's centre of each eye (what eyeBlink moves most) and the
  lower lid's (the still vertex nearest where the blink takes the upper lid), the inner and outer brow of each
  side (browInnerUp, browOuterUp), the mouth's corners (mouthSmile), and the inner edges of the upper and lower
  lip on the midline (mouthUpperUp, mouthLowerDown).
* **The match** (:class:`Transfer`): each point's displacement from the rest face, in units of the face's size
  (the distance between the upper lids), on the ICT face (exact, from the fitted weights and the person's
  identity) and on the character (linear in its weights); the character's weights of :data:`TRANSFERRED` (the
  brows and the lids, where the two models' morphs differ most) minimise the squared difference of the brows'
  and lids' displacements plus :data:`PULL` times their squared difference from the fitted weights, then are
  clipped to [0, 1]; the other channels keep the fitted weights. The mouth is left by name: read back from a
  close-up render by a face tracker (``benchmarks/face_readback.py``), the mouth followed the video better by
  name (r 0.70-0.98 against 0.59-0.94 with the lips in the match, on five clips), the brows better by geometry
  (Obama's r 0.53 by name, 0.74 matched).
"""

from __future__ import annotations

import numpy as np

POINTS = ("upper_lid_L", "lower_lid_L", "upper_lid_R", "lower_lid_R", "brow_in_L", "brow_out_L", "brow_in_R",
          "brow_out_R", "corner_L", "corner_R", "upper_lip", "lower_lip")  # fmt: skip
PULL = 0.01
"""How strongly a character weight stays at the fitted weight (against the points' squared displacement, in
face sizes)."""
TRANSFERRED = tuple(f"{b}_{s}" for b in ("browDown", "browInnerUp", "browOuterUp", "eyeBlink", "eyeSquint", "eyeWide")
                    for s in ("L", "R"))  # fmt: skip
MATCHED = ("upper_lid_L", "lower_lid_L", "upper_lid_R", "lower_lid_R", "brow_in_L", "brow_out_L", "brow_in_R",
           "brow_out_R")  # fmt: skip
"""The points the match uses (the brows' and the lids')."""


def face_points(V: np.ndarray, D: np.ndarray, names: list[str]) -> tuple[np.ndarray, float]:
    """The vertex indices of :data:`POINTS` on a face of rest vertices ``V [N, 3]`` and expression deltas
    ``D [E, N, 3]`` named ``names`` (ICT's 53), and the face's size (the upper lids' distance)."""
    ix = {n: i for i, n in enumerate(names)}
    mag = lambda n: np.linalg.norm(D[ix[n]], axis=-1)
    out = {}
    for s in ("L", "R"):
        m = mag(f"eyeBlink_{s}")
        up = int(np.argmax(m))
        out[f"upper_lid_{s}"] = up
        goal = V[up] + D[ix[f"eyeBlink_{s}"]][up]
        still = np.flatnonzero(m < 0.3 * m.max())
        out[f"lower_lid_{s}"] = int(still[np.argmin(np.linalg.norm(V[still] - goal, axis=-1))])
        out[f"brow_in_{s}"] = int(np.argmax(mag(f"browInnerUp_{s}")))
        out[f"brow_out_{s}"] = int(np.argmax(mag(f"browOuterUp_{s}")))
        out[f"corner_{s}"] = int(np.argmax(mag(f"mouthSmile_{s}")))
    size = float(np.linalg.norm(V[out["upper_lid_L"]] - V[out["upper_lid_R"]]))
    cx = (V[out["upper_lid_L"], 0] + V[out["upper_lid_R"], 0]) / 2
    mid = np.abs(V[:, 0] - cx) < 0.03 * size
    up = mag("mouthUpperUp_L") + mag("mouthUpperUp_R")
    c = np.flatnonzero(mid & (up > 0.5 * up[mid].max()))
    out["upper_lip"] = int(c[np.argmin(V[c, 1])])  # the inner edge: the lowest of the upper lip's midline
    lo = mag("mouthLowerDown_L") + mag("mouthLowerDown_R")
    c = np.flatnonzero(mid & (lo > 0.5 * lo[mid].max()))
    out["lower_lip"] = int(c[np.argmax(V[c, 1])])
    return np.array([out[p] for p in POINTS]), size


class Transfer:
    """``Transfer(ict_rest, ict_deltas, ict_names, char_rest, char_deltas, char_names)(W [F, 53]) -> [F, 53]``:
    the character's weights for fitted ICT weights ``W`` (columns in ``char_names`` order, the same 53 names),
    see the module docstring. ``ict_rest``: the person's neutral ICT face (identity applied)."""

    def __init__(self, ict_rest, ict_deltas, ict_names, char_rest, char_deltas, char_names, pull: float = PULL):
        pi, si = face_points(ict_rest, ict_deltas, list(ict_names))
        pc, sc = face_points(char_rest, char_deltas, list(char_names))
        order = [list(ict_names).index(n) for n in char_names]
        self.Ai = np.asarray(ict_deltas, np.float64)[order][:, pi] / si  # [53, 12, 3] per ICT weight
        self.Bc = np.asarray(char_deltas, np.float64)[:, pc] / sc  # [53, 12, 3] per character weight
        self.free = np.array([n in TRANSFERRED for n in char_names])
        self.used = np.array([p in MATCHED for p in POINTS])
        B = self.Bc[self.free][:, self.used].reshape(int(self.free.sum()), -1)
        self.pull = pull
        self.solve = np.linalg.inv(B @ B.T + pull * np.eye(len(B)))
        self.B = B

    def targets(self, W: np.ndarray) -> np.ndarray:
        """The ICT face's point displacements ``[F, 12, 3]`` (face sizes) for weights ``W [F, 53]``."""
        return np.einsum("fe,epc->fpc", np.asarray(W, np.float64), self.Ai)

    def character(self, Wc: np.ndarray) -> np.ndarray:
        """The character's point displacements ``[F, 12, 3]`` for its weights ``Wc [F, 53]``."""
        return np.einsum("fe,epc->fpc", np.asarray(Wc, np.float64), self.Bc)

    def __call__(self, W: np.ndarray) -> np.ndarray:
        W = np.asarray(W, np.float64)
        fixed = W.copy()
        fixed[:, self.free] = 0.0
        # what the free channels must add to the fixed ones' displacement of the matched points
        T = (self.targets(W) - self.character(fixed))[:, self.used].reshape(len(W), -1)
        out = W.copy()
        out[:, self.free] = (T @ self.B.T + self.pull * W[:, self.free]) @ self.solve.T
        return np.clip(out, 0.0, 1.0)
