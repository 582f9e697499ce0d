"""Matching features of seed 004 §5.3.1.2, at 15 fps. Pure functions.

* audio f_t (112): the 13 MFCC + log energy (the first 14 of anima's 28 speech features) at t, t+2, ..., t+14;
* pose p_t (96): 3D positions of both wrists, elbows, index-finger roots and little-finger roots at t, t+2,
  t+4, t+6 (the hand trajectory over the next 0.5 s);
* gesture g_t (165): the 55-joint skeleton (pelvis-relative metres).
Frames past the end of a window repeat its last frame.
"""

from __future__ import annotations

import numpy as np

from anima.core.contract import GESTURE_FPS, SPEECH_STATIC_DIM, WINDOW
from anima.core.skeleton import JOINT_NAMES

FPS = GESTURE_FPS  # the rate the matching features are defined at (offsets below are frames at this rate)
T_MATCH = WINDOW
N_STEP = 8
AUDIO_OFFSETS = tuple(range(0, 15, 2))
POSE_OFFSETS = (0, 2, 4, 6)
POSE_JOINTS = [
    JOINT_NAMES.index(n)
    for n in (
        "left_wrist",
        "left_elbow",
        "left_hand_index_mcp",
        "left_hand_pinky_mcp",
        "right_wrist",
        "right_elbow",
        "right_hand_index_mcp",
        "right_hand_pinky_mcp",
    )
]


def _ahead(x: np.ndarray, offsets) -> np.ndarray:
    """(T, ...) -> (T, len(offsets), ...) with x[min(t + o, T - 1)]."""
    T = len(x)
    idx = np.minimum(np.arange(T)[:, None] + np.asarray(offsets)[None], T - 1)
    return x[idx]


def audio_features(speech: np.ndarray) -> np.ndarray:
    """speech (T, 28) anima speech features -> (T, 112)."""
    return _ahead(np.asarray(speech, np.float32)[:, :SPEECH_STATIC_DIM], AUDIO_OFFSETS).reshape(len(speech), -1)


def pose_features(joints: np.ndarray) -> np.ndarray:
    """joints (T, 55, 3) -> (T, 96)."""
    J = np.asarray(joints, np.float32)[:, POSE_JOINTS]
    return _ahead(J, POSE_OFFSETS).reshape(len(J), -1)
