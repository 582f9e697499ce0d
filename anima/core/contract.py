"""The data contract, declared once: frame rates, feature sizes and the layout of the training pairs.

Every stage that makes or reads motion data takes its sizes from here, and its frame rate from the data it
reads (the ``fps`` stored in every tracked sequence, dataset row and checkpoint config); the rates below
are what the dataset builder *writes*, not what a reader may assume.

Face motion frame (text2face clips, the face of (audio, motion) windows, generated faces)::

    [0, 53)   ICT-FaceKit expression weights in [0, 1] (ARKit names, ``anima.facemodel.ict``)
    [53, 56)  head rotation, model-to-camera axis-angle, radians

Body frame (seed 004 §4.3): 55 joints x 3 (metres, pelvis-relative), ``anima.core.skeleton`` order::

    [0, 39)    13 upper-body joints,  [39, 102) left hand (21 joints),  [102, 165) right hand (21 joints)

Speech frame (``anima.audio.features``): 13 MFCC + log mean energy (14), then their first derivatives (14).

(audio, motion) window: ``WINDOW`` frames at ``GESTURE_FPS``, hop ``HOP``; arrays ``speech [T, 28]``,
``body [T, 165]`` (all NaN for a face-only window), ``face [T, 56]``.
(text, motion) clip: ``[T, 56]`` at ``TEXT_FPS``.
"""

from __future__ import annotations

N_IDENTITY = 100
N_EXPR = 53
HEAD_ROT_DIM = 3
FACE_DIM = N_EXPR + HEAD_ROT_DIM  # 56

N_BODY_JOINTS = 13
N_HAND_JOINTS = 21
N_JOINTS = N_BODY_JOINTS + 2 * N_HAND_JOINTS  # 55
BODY_DIM = 3 * N_JOINTS  # 165

N_MFCC = 13
SPEECH_STATIC_DIM = N_MFCC + 1  # 13 MFCC + log energy
SPEECH_DIM = 2 * SPEECH_STATIC_DIM  # 28: + first derivatives

TEXT_FPS = 30.0  # the (text, motion) clips the dataset builder writes, and text2face's output rate
GESTURE_FPS = 15.0  # the (audio, motion) windows (seed 004), the gesture models' rate
WINDOW = 64  # frames per (audio, motion) window
HOP = 32  # frames between window starts

assert FACE_DIM == 56 and BODY_DIM == 165 and SPEECH_DIM == 28
