"""The independent mouth reader of ``benchmarks/mouth_independent.py``: dlib's 68 points (a reader that
shares nothing with anima's MediaPipe tracker) found on a real frame, and its mouth measure sane there."""

import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("dlib")


def test_the_reader_finds_68_points_and_an_open_mouth_on_a_real_frame():
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from mouth_independent import CREMA, Reader, gaps, pearson, video_frames

    from anima.io.assets import asset

    frames = video_frames(asset(CREMA.format("ANG")))
    rgb = next(f for i, f in enumerate(frames) if i == 30)  # mid-sentence: the mouth open
    P = Reader()(rgb)
    assert P is not None and P.shape == (68, 2) and np.isfinite(P).all()
    x0, y0 = P.min(0)
    x1, y1 = P.max(0)
    assert 40 < x1 - x0 < 200 and 40 < y1 - y0 < 200  # CREMA-D's 480 x 360 frame: a face ~100 pixels across
    g = gaps(P[None])
    assert 0.02 < g["height"][0] < 0.4 and 0.02 < g["eyes"][0] < 0.6
    assert pearson(np.arange(10.0), np.arange(10.0) * 2 + 1) == pytest.approx(1.0)
