"""The gesture feature's settings (light: no torch), so the command line builds its options from them: the
search (:class:`GestureConfig`) and the models ``anima train gesture`` trains (:data:`MODELS`)."""

from __future__ import annotations

from dataclasses import dataclass, field

MODELS = ("refiner", "generator", "regression", "lstm", "velocity_adversarial", "moglow")


@dataclass
class GestureConfig:
    k: int = field(default=0, metadata={"range": (0, 1000)})
    """Take the k-th best candidate at every step (variety; 0 = the best)."""
    init: str = field(default="mean", metadata={"choices": ("mean", "random")})
    """Initial pose feature: the database mean, or a random database frame (seeded)."""
    seed: int = 0
    """Random seed (``--init random``)."""
    all_splits: bool = False
    """Search the windows of every split (default: the training split only)."""
    control: list = field(default_factory=list, metadata={"metavar": "CONTROL", "repeat": True})
    """A control, repeatable: NAME OP VALUE[@START-ENDs], e.g. left_wrist_height>=p85@0-5s (names:
    left/right_wrist_height, left/right_wrist_speed, hand_symmetry; pXX = percentile of the database)."""
    keyword: list = field(default_factory=list, metadata={"metavar": "WORD@START-ENDs", "repeat": True})
    """A keyword spoken at that time (e.g. from a speech recogniser): while it is spoken, gestures come from
    its --keyword-db (repeatable)."""
    keyword_db: list = field(default_factory=list, metadata={"metavar": "WORD=DATASET", "repeat": True})
    """The gesture database of a keyword: a dataset folder (repeatable)."""
    no_repeat_s: float = field(default=4.0, metadata={"range": (0.0, 60.0)})
    """Do not replay a stretch of database motion output within the last this-many seconds (variety; 0 = the
    seed's search, which can loop over a few windows). With a motion library (built-in or --library) it is raised
    to half the library's distinct seconds, at most 20; a mirrored or speed-varied copy counts as its source."""
    stroke_rank: float = field(default=3.0, metadata={"range": (0.0, 100.0)})
    """Weight of the stroke rank in the search: at a step with stressed syllables, candidates whose wrist-speed
    peaks (strokes) fall on them rank higher, added to the seed's audio and pose ranks (0: the seed's ranking;
    3 was the best of 0-4 on three speeches of none of the benchmark's speakers, docs/gesture.md)."""
    stroke_shift: float = field(default=2.0, metadata={"range": (0.0, 4.0)})
    """Re-time the motion so a stroke within this many frames (15 fps) of a stressed syllable meets it (local rate
    within 1/1.35-1.35; 0: off)."""
    variants: bool = True
    """With a motion library (built-in or --library), also search its mirrored and speed-varied (1/1.15x, 1.15x)
    copies (off: --no-variants)."""
    blend: bool = True
    """Blend the joins between database windows (inertialization over one 8-frame step; off: --no-blend, the
    seed's raw concatenation)."""
    control_ends_only: bool = False
    """Check a control on the first and last frame of each 8-frame step only, as the seed does (default: on
    every frame, so the frames between them keep the control too)."""


@dataclass
class GestureTrainConfig:
    """What ``anima train gesture`` trains (:func:`anima.gesture.train.train_from_dataset`)."""

    model: str = field(default="refiner", metadata={"choices": MODELS})
    """refiner: the cGAN refiner of k-NN gestures (section 5.3.3); generator, regression, lstm,
    velocity_adversarial, moglow: the section 4.4 generator and its baselines."""
    steps: int | None = field(default=None, metadata={"range": (1, 10_000_000)})
    """generator steps (default 600 refiner, 1000 others)"""
    seed: int = 0
    """random seed"""
    all_splits: bool = False
    """train on all splits (default: train only)"""
