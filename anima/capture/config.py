"""The capture's settings (light: no MediaPipe, no model), so the command line builds its options from them:
:class:`FitConfig` (the face-model fit) and :class:`CaptureConfig` (the whole capture)."""

from __future__ import annotations

from dataclasses import dataclass, field

from anima.track import DEFAULT as DEFAULT_TRACKER
from anima.track import TRACKERS


@dataclass
class FitConfig:
    z_weight: float = 0.5
    """Weight of MediaPipe's depth residual relative to the image-plane residual."""
    lam_expr: float = 0.5
    """L2 regularisation of expression weights (cm^2 per unit weight^2, summed over landmarks)."""
    lam_expr_l1: float = 0.05
    """L1 (sparsity) regularisation of expression weights."""
    lam_id: float = 2.0
    """L2 regularisation of identity coefficients (PCA modes, prior N(0, 1))."""
    n_keyframes: int = 12
    """Frames used to fit the per-clip identity."""
    n_alternations: int = 3
    """Pose / expression alternations per frame."""
    qp_sweeps: int = 200
    """Maximum coordinate-descent sweeps of the bounded expression solve (stops earlier on convergence)."""
    use_iris: bool = True
    """Use MediaPipe's 10 iris landmarks (468-477) for the eye-gaze shapes."""
    huber_cm: float = 0.3
    """Huber threshold (cm) of the robust identity fit."""
    reader: bool = True
    """Read the expression from the posed landmarks with the shipped expression reader
    (:mod:`anima.facemodel.reader`, learned on renders with known weights); off: the least-squares fit's weights."""


FIT_FOR_DETECTORS = FitConfig(reader=False)
"""The fit the dataset's event detectors read (``anima dataset build``, the library, their evaluations): their
thresholds were calibrated on the least-squares fit's weights, not on the expression reader's."""


@dataclass
class CaptureConfig:
    smooth_sigma: float = field(default=1.0, metadata={"flag": "--sigma", "range": (0.0, 100.0)})
    """Gaussian temporal smoothing of the fitted parameters, in frames (0 = off). Zero-phase, so no lag.
    1.0 is the smoothing the dataset's detectors' thresholds were calibrated on. ``anima eval stability``
    chooses a sigma on its validation clips, always one whose landmark error there stays within 10 % of the
    unsmoothed fit's (together with the detectors' F1 among those that also remove at least 40 % of
    MediaPipe's landmark jitter), and says whether its choice and this default each meet those targets on
    the validation and the test clips. Seed 004 used 1.5 frames on 15 fps."""
    max_frames: int | None = field(default=None, metadata={"range": (1, None)})
    """Only the first N frames (default: the whole video)."""
    low_conf_nme: float = 0.05
    """Frames whose fit NME exceeds this are flagged low-confidence."""
    min_face_px: float = 40.0
    """Faces whose landmark box is smaller than this (sqrt of area, px) are flagged low-confidence."""
    identity_tolerance_cm: float = 0.05
    """Fit-while-tracking keeps its per-frame fits if the whole-clip identity moves its landmarks by less
    than this on average (else the clip is refitted)."""
    stream: bool = True
    """Fit chunks of frames on a worker thread while MediaPipe tracks (hides most of the fitting time)."""
    face_only: bool = False
    """Track the face only (MediaPipe face mesh: the fast path); otherwise Holistic: face, body and hands."""
    tracker: str = field(default=DEFAULT_TRACKER, metadata={"choices": tuple(TRACKERS)})
    """The tracker that finds the face, body and hands (docs/architecture.md says how to add one)."""
    body_min_conf: float = 0.5
    """Body joints with a pose visibility below this are dropped before interpolation."""
    max_gap: int = field(default=8, metadata={"range": (0, 10_000)})
    """Longest hand/body drop-out (frames) filled by cubic interpolation; longer gaps stay missing and flagged."""
    body_sigma: float = 1.5
    """Gaussian smoothing of the skeleton, frames (seed 004 §4.3.1)."""
    fixed_bones: bool = False
    """Impose the clip's median bone lengths on every frame."""
    body_3d: str = field(default="mediapipe", metadata={"choices": ("mediapipe", "lifter")})
    """Where the body's 3D comes from: ``mediapipe`` (Pose world landmarks) or ``lifter`` (anima's trained
    2D->3D lifter on MediaPipe's 2D keypoints, :mod:`anima.pose3d`)."""
    pose_model: str | None = None
    """Lifter checkpoint for --body-3d lifter (default: $ANIMA_HOME/models/pose_lifter.pt, where
    ``anima train pose`` writes)."""
    posture: str = field(default="auto", metadata={"choices": ("auto", "seated", "standing")})
    """How the character's legs stand where the video shows none: ``seated`` (thighs level, shins down: a
    speaker at a desk), ``standing``, or ``auto`` (legs in the picture are followed; without them, seated only
    when the hips are seen at the picture's bottom edge, standing otherwise, a chest-up framing included;
    info.json says which and why)."""
    fit: FitConfig = field(default_factory=FitConfig)
