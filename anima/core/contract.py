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

Every name here is assigned here only (``tests/test_architecture.py`` checks it, and that no data path writes
the magic numbers ``30.0``, ``15.0``, ``53`` or ``56``): import them.
"""

from __future__ import annotations

N_IDENTITY = 100
N_FACE_LANDMARKS = 478  # MediaPipe Face Mesh's refined landmarks (the tracked sequence's landmarks)
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
CHARACTER_FPS = TEXT_FPS  # the rate generated motion plays on the character (gesture's files, text2face's)
WINDOW = 64  # frames per (audio, motion) window
HOP = 32  # frames between window starts

# the 53 ICT-FaceKit expressions, in the face model's order (ARKit names with _L/_R): the first N_EXPR values
# of every face frame
EXPR_NAMES = (
    "browDown_L", "browDown_R", "browInnerUp_L", "browInnerUp_R", "browOuterUp_L", "browOuterUp_R", "cheekPuff_L",
    "cheekPuff_R", "cheekSquint_L", "cheekSquint_R", "eyeBlink_L", "eyeBlink_R", "eyeLookDown_L", "eyeLookDown_R",
    "eyeLookIn_L", "eyeLookIn_R", "eyeLookOut_L", "eyeLookOut_R", "eyeLookUp_L", "eyeLookUp_R", "eyeSquint_L",
    "eyeSquint_R", "eyeWide_L", "eyeWide_R", "jawForward", "jawLeft", "jawOpen", "jawRight", "mouthClose",
    "mouthDimple_L", "mouthDimple_R", "mouthFrown_L", "mouthFrown_R", "mouthFunnel", "mouthLeft",
    "mouthLowerDown_L", "mouthLowerDown_R", "mouthPress_L", "mouthPress_R", "mouthPucker", "mouthRight",
    "mouthRollLower", "mouthRollUpper", "mouthShrugLower", "mouthShrugUpper", "mouthSmile_L", "mouthSmile_R",
    "mouthStretch_L", "mouthStretch_R", "mouthUpperUp_L", "mouthUpperUp_R", "noseSneer_L", "noseSneer_R",
)  # fmt: skip

# the tracked skeleton (seed 004 §4.3): 13 body joints, then 21 per hand (MediaPipe hand order); "left" is the
# subject's left. Parents index into the same list (-1: the root).
BODY_JOINTS = (
    "pelvis", "left_hip", "right_hip", "spine", "neck", "head", "nose",
    "left_shoulder", "left_elbow", "left_wrist", "right_shoulder", "right_elbow", "right_wrist",
)  # fmt: skip
BODY_PARENTS = (-1, 0, 0, 0, 3, 4, 5, 4, 7, 8, 4, 10, 11)
# the legs, where Holistic sees them (an optional track beside the 55 joints; the rig stands in elsewhere)
LEG_JOINTS = (
    "left_knee", "left_ankle", "left_heel", "left_foot_index",
    "right_knee", "right_ankle", "right_heel", "right_foot_index",
)  # fmt: skip
HAND_JOINTS = (
    "wrist", "thumb_cmc", "thumb_mcp", "thumb_ip", "thumb_tip", "index_mcp", "index_pip", "index_dip", "index_tip",
    "middle_mcp", "middle_pip", "middle_dip", "middle_tip", "ring_mcp", "ring_pip", "ring_dip", "ring_tip",
    "pinky_mcp", "pinky_pip", "pinky_dip", "pinky_tip",
)  # fmt: skip
HAND_PARENTS = (-1, 0, 1, 2, 3, 0, 5, 6, 7, 0, 9, 10, 11, 0, 13, 14, 15, 0, 17, 18, 19)


def _joint_list() -> tuple[tuple[str, ...], tuple[int, ...]]:
    names, parents = list(BODY_JOINTS), list(BODY_PARENTS)
    for side in ("left", "right"):
        off, wrist = len(names), BODY_JOINTS.index(f"{side}_wrist")
        names += [f"{side}_hand_{n}" for n in HAND_JOINTS]
        parents += [wrist if p < 0 else off + p for p in HAND_PARENTS]
    return tuple(names), tuple(parents)


JOINT_NAMES, JOINT_PARENTS = _joint_list()

FINGERS = ("Thumb", "Index", "Middle", "Ring", "Pinky")


def _rig_list() -> tuple[tuple[str, ...], tuple[int, ...]]:
    """The character's rig, every skeleton anima exports: Mixamo's hierarchy (a three-bone spine, neck, head,
    collarbones, arms, hands with three-bone fingers, legs, feet and toes) and the end joints of the head, the
    fingers and the toes; depth-first, parents first. Other naming conventions: ``anima.core.rig.CONVENTIONS``."""
    names: list[str] = []
    parents: list[int] = []

    def add(name: str, parent: str | None) -> None:
        names.append(name)
        parents.append(names.index(parent) if parent else -1)

    add("Hips", None)
    add("Spine", "Hips")
    add("Spine1", "Spine")
    add("Spine2", "Spine1")
    add("Neck", "Spine2")
    add("Head", "Neck")
    add("HeadTop_End", "Head")
    for side in ("Left", "Right"):
        add(f"{side}Shoulder", "Spine2")
        add(f"{side}Arm", f"{side}Shoulder")
        add(f"{side}ForeArm", f"{side}Arm")
        add(f"{side}Hand", f"{side}ForeArm")
        for f in FINGERS:
            for k in range(1, 5):
                add(f"{side}Hand{f}{k}", f"{side}Hand{f}{k - 1}" if k > 1 else f"{side}Hand")
    for side in ("Left", "Right"):
        add(f"{side}UpLeg", "Hips")
        add(f"{side}Leg", f"{side}UpLeg")
        add(f"{side}Foot", f"{side}Leg")
        add(f"{side}ToeBase", f"{side}Foot")
        add(f"{side}Toe_End", f"{side}ToeBase")
    return tuple(names), tuple(parents)


RIG_JOINTS, RIG_PARENTS = _rig_list()

assert FACE_DIM == 56 and BODY_DIM == 165 and SPEECH_DIM == 28
assert len(EXPR_NAMES) == N_EXPR and len(JOINT_NAMES) == N_JOINTS and len(RIG_JOINTS) == 65 and len(LEG_JOINTS) == 8
