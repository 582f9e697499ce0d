"""Attribute detectors vs labels made by watching frames (``anima eval annotations``).

Labels: ``anima/eval/labels/attributes/*.json``; per clip, for each *evaluated* attribute, the labelled frame
ranges (inclusive; an empty list means "never happens here"), and ``ignore`` ranges where an attribute is
ambiguous (detections there are not counted, nor are those frames).

Protocol, per attribute pooled over clips:
* event level: a detection is a true positive if it overlaps a labelled event (any overlap); precision =
  true detections / detections, recall = labelled events overlapped by a detection / labelled events;
* frame level: precision and recall over frames, outside ignore ranges.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from anima.capture.pipeline import CaptureConfig, capture_video
from anima.dataset.attributes import ATTRIBUTES, DetectorConfig, detect, frame_mask
from anima.io.assets import asset

LABELS = Path(__file__).resolve().parent / "labels" / "attributes"


def load_labels() -> list[dict]:
    return [json.loads(p.read_text()) | {"name": p.stem} for p in sorted(LABELS.glob("*.json"))]


def _ranges_mask(ranges, n):
    m = np.zeros(n, bool)
    for a, b in ranges:
        m[a : b + 1] = True
    return m


def capture_labelled(lab: dict):

    return capture_video(
        str(asset(lab["clip"])), CaptureConfig(face_only=True, max_frames=lab.get("frames")), progress=False
    )


def score(seqs_and_labels, cfg: DetectorConfig | None = None) -> dict:
    acc = {
        a: {"tp_det": 0, "det": 0, "hit_lab": 0, "lab": 0, "tp_f": 0, "det_f": 0, "lab_f": 0, "clips": 0}
        for a in ATTRIBUTES
    }
    for seq, lab in seqs_and_labels:
        events = detect(seq, cfg)
        n = seq.n_frames
        for attr, ranges in lab["labels"].items():
            if attr not in acc:
                continue
            a = acc[attr]
            a["clips"] += 1
            ign = _ranges_mask(lab.get("ignore", {}).get(attr, []), n)
            truth = _ranges_mask(ranges, n)
            det = frame_mask(events, attr, n, seq.fps)
            keep = ~ign
            a["tp_f"] += int((det & truth & keep).sum())
            a["det_f"] += int((det & keep).sum())
            a["lab_f"] += int((truth & keep).sum())
            dets = [(int(round(s * seq.fps)), int(round(e * seq.fps))) for nm, s, e in events if nm == attr]
            for s, e in dets:
                span = np.zeros(n, bool)
                span[s : max(e, s + 1)] = True
                if (span & ign).sum() >= 0.5 * span.sum():
                    continue  # (mostly) inside an ambiguous range: not counted
                a["det"] += 1
                a["tp_det"] += int((span & truth).any())
            for s, e in ranges:
                a["lab"] += 1
                a["hit_lab"] += int(any(ds <= e and de > s for ds, de in dets))
    out = {}
    for attr, a in acc.items():
        if a["clips"] == 0:
            continue
        out[attr] = {
            "clips": a["clips"],
            "labelled_events": a["lab"],
            "detections": a["det"],
            "precision": a["tp_det"] / a["det"] if a["det"] else (1.0 if a["lab"] == 0 else 0.0),
            "recall": a["hit_lab"] / a["lab"] if a["lab"] else None,
            "frame_precision": a["tp_f"] / a["det_f"] if a["det_f"] else None,
            "frame_recall": a["tp_f"] / a["lab_f"] if a["lab_f"] else None,
        }
    return out


def evaluate_annotations(cfg: DetectorConfig | None = None) -> dict:
    labs = load_labels()
    pairs = [(capture_labelled(lab), lab) for lab in labs]
    return {
        "protocol": __doc__.split("Protocol, per attribute pooled over clips:")[1].strip(),
        "clips": [lab["name"] for lab in labs],
        "per_attribute": score(pairs, cfg),
    }
