"""Controls for the k-NN search (seed 004 §5.3.2.1, §5.4.2): per-frame masks of the database from
percentiles of wrist height, wrist speed and hand symmetry, applied in time ranges.

Syntax: ``NAME OP VALUE[@START-ENDs]``, e.g. ``left_wrist_height>=p85@0-5s`` (VALUE ``pXX`` is a percentile of
the database; a plain number is in the feature's units: metres, metres/second; symmetry is minus the
distance between the left wrist and the mirrored right wrist, so higher is more symmetric).
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass

import numpy as np

from anima.core.skeleton import JOINT_NAMES
from anima.errors import InputError
from anima.gesture.features import FPS

_LW, _RW = JOINT_NAMES.index("left_wrist"), JOINT_NAMES.index("right_wrist")


def control_features(G: np.ndarray, fps: float = FPS) -> dict[str, np.ndarray]:
    """G (M, T, 165) -> per-frame control features (M, T)."""
    J = G.reshape(G.shape[0], G.shape[1], -1, 3)
    lw, rw = J[..., _LW, :], J[..., _RW, :]
    speed = lambda w: np.concatenate([np.zeros_like(w[:, :1, 0]), np.linalg.norm(np.diff(w, axis=1), axis=-1) * fps], 1)
    return {
        "left_wrist_height": lw[..., 1],
        "right_wrist_height": rw[..., 1],
        "left_wrist_speed": speed(lw),
        "right_wrist_speed": speed(rw),
        "hand_symmetry": -np.linalg.norm(lw - rw * np.array([-1.0, 1.0, 1.0]), axis=-1),
    }


NAMES = tuple(control_features(np.zeros((1, 2, 165))).keys())
_RE = re.compile(r"^\s*([a-z_]+)\s*(>=|<=|>|<)\s*(p?)([0-9.]+)\s*(?:@\s*([0-9.]+)\s*-\s*([0-9.]+)\s*s)?\s*$")


@dataclass
class Control:
    name: str
    op: str
    value: float
    percentile: bool
    start_s: float = 0.0
    end_s: float = float("inf")
    text: str = ""

    def threshold(self, feats: dict) -> float:
        x = feats[self.name]
        return float(np.percentile(x, self.value)) if self.percentile else self.value

    def frame_mask(self, feats: dict, thr: float | None = None) -> np.ndarray:
        x = feats[self.name]
        t = self.threshold(feats) if thr is None else thr
        return {">=": x >= t, "<=": x <= t, ">": x > t, "<": x < t}[self.op]


def parse_control(text: str) -> Control:
    m = _RE.match(text.lower())
    if not m:
        raise InputError(f"cannot read control {text!r}: expected e.g. 'left_wrist_height>=p85@0-5s'")
    name, op, p, v, a, b = m.groups()
    if name not in NAMES:
        raise InputError(f"unknown control {name!r}; known: {', '.join(NAMES)}")
    try:
        value = float(v)
        start, end = (float(a) if a else 0.0), (float(b) if b else float("inf"))
    except ValueError:
        raise InputError(f"cannot read the numbers of control {text!r}") from None
    if p and not 0 <= value <= 100:
        raise InputError(f"percentile out of range in {text!r}")
    if not start < end:
        raise InputError(f"control {text!r}: its time range ends before it starts ({start:g}-{end:g} s)")
    return Control(name, op, value, bool(p), start, end, text)


def speed_steps(controls: list[Control], n_steps: int, step_s: float) -> set[int]:
    """The search steps a wrist-speed control applies to (their joins are left unblended)."""
    return {
        k for k in range(n_steps) for c in controls if c.name.endswith("_speed") and c.start_s <= k * step_s < c.end_s
    }


def step_masks(
    db,
    controls: list[Control],
    n_steps: int,
    step_s: float,
    threshold_rows: np.ndarray | None = None,
    every_frame: bool = True,
) -> tuple[list, list[dict]]:
    """Per search step, the window-start mask (None = no control) and a report per control: the threshold
    used, and how far it was relaxed (towards the median) when no database window satisfied it. Percentiles
    are taken over the database windows ``threshold_rows`` (default: all). ``every_frame``: a start is allowed
    when all N frames it gives satisfy the controls (False: its first and last frame, the seed's rule)."""
    if not controls:
        return [None] * n_steps, []
    feats = control_features(db.G_rig)
    ref = feats if threshold_rows is None else {k: v[threshold_rows] for k, v in feats.items()}
    report = []
    masks_by_control = []
    for c in controls:
        thr = c.threshold(ref)
        fm = c.frame_mask(feats, thr)
        relaxed_to = None
        if not db.start_mask(fm, every_frame).any():
            med = float(np.median(ref[c.name]))
            for f in np.linspace(0, 1, 21)[1:]:
                t2 = thr + (med - thr) * f
                fm = c.frame_mask(feats, t2)
                if db.start_mask(fm, every_frame).any():
                    relaxed_to = t2
                    break
            warnings.warn(
                f"control {c.text!r}: no database window satisfies it; relaxed from {thr:.3f} to {relaxed_to:.3f}"
                if relaxed_to is not None
                else f"control {c.text!r} cannot be met",
                stacklevel=2,
            )
        masks_by_control.append(fm)
        report.append(
            {
                "control": c.text,
                "threshold": thr,
                "relaxed_to": relaxed_to,
                "start_s": c.start_s,
                "end_s": None if c.end_s == float("inf") else c.end_s,
            }
        )
    out = []
    for k in range(n_steps):
        t = k * step_s
        active = [fm for c, fm in zip(controls, masks_by_control) if c.start_s <= t < c.end_s]
        if not active:
            out.append(None)
            continue
        fm = np.logical_and.reduce(active)
        sm = db.start_mask(fm, every_frame)
        for fallback in (db.start_mask(active[0], every_frame), db.start_mask(active[0], False)):
            if sm.any():
                break
            sm = fallback  # the controls together cannot be met: the first one alone, then at its ends
        out.append(sm if sm.any() else None)
    return out, report
