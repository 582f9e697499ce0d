"""Clip selection rules (seed 000 §5.1), each configurable and counted.

1. ``length``: clips must last ``min_s``-``max_s`` seconds (default 5-10 s, as the seed); longer videos are
   cut into equal consecutive clips inside the window; shorter ones are removed.
2. ``action_keywords``: clips whose imported annotations contain "turn", "shake head" or "head wagging".
3. ``head_yaw``: any tracked frame with |yaw| > 35 degrees (from the fitted head pose).
4. ``fit_error``: the failsafe - any tracked frame whose fit NME exceeds ``max_fit_nme``.
5. ``low_confidence``: less than ``min_tracked`` of the frames have a face, or too many low-confidence frames.
6. ``occlusion`` (seed 000 §5.1 removes occluded faces by hand: microphones, masks, sunglasses): more than
   ``max_occluded`` of the tracked frames have a hand over the lower face, i.e. at least ``occluding_joints``
   hand joints of the capture's own skeleton (``body_image``) inside the box from the nose tip to the chin
   and from cheek to cheek of the face landmarks. Objects (microphones) and sunglasses are not detected.
"""

from __future__ import annotations

import numpy as np

from anima.core.occlusion import hand_over_face
from anima.dataset.attributes import head_angles_deg
from anima.dataset.config import FilterConfig
from anima.io.sequence import FLAG_LOW_CONFIDENCE


def cut_clips(n_frames: int, fps: float, cfg: FilterConfig) -> list[tuple[int, int]]:
    """Frame ranges ``[a, b)`` of the clips of a video inside the length window ([] if too short)."""
    dur = n_frames / fps
    if "length" not in cfg.enabled:
        return [(0, n_frames)]
    if dur < cfg.min_s - 1e-6:
        return []
    k = max(1, int(np.ceil(dur / cfg.max_s - 1e-9)))
    edges = np.round(np.linspace(0, n_frames, k + 1)).astype(int)
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:]) if (b - a) / fps >= cfg.min_s - 1e-6]


def clip_rejection(seq, a: int, b: int, events: list | None, cfg: FilterConfig) -> str | None:
    """The first rule a clip ``[a, b)`` breaks, or None to keep it."""
    tracked = seq.tracked[a:b]
    if "low_confidence" in cfg.enabled:
        low = ((seq.flags[a:b] & FLAG_LOW_CONFIDENCE) > 0).mean()
        if tracked.mean() < cfg.min_tracked or low > cfg.max_low_conf:
            return "low_confidence"
    if "action_keywords" in cfg.enabled and events:
        t0, t1 = a / seq.fps, b / seq.fps
        if any(n in cfg.action_keywords and s < t1 and e > t0 for n, s, e in events):
            return "action_keywords"
    if "head_yaw" in cfg.enabled:
        yaw = np.abs(head_angles_deg(seq)[a:b, 0])[tracked]
        if len(yaw) and yaw.max() > cfg.max_yaw_deg:
            return "head_yaw"
    if "fit_error" in cfg.enabled:
        nme = seq.fit_nme[a:b][tracked]
        if len(nme) and np.nanmax(nme) > cfg.max_fit_nme:
            return "fit_error"
    if "occlusion" in cfg.enabled and tracked.any():
        if hand_over_face(seq, cfg.occluding_joints)[a:b][tracked].mean() > cfg.max_occluded:
            return "occlusion"
    return None
