"""The expression reader: its maths, the shipped table, and what it changes on a real clip."""

import json
import re

import numpy as np
import pytest

from anima.capture.config import CaptureConfig, FitConfig
from anima.capture.pipeline import fit_landmark_sequence
from anima.facemodel.reader import DATA, fit_reader, load_reader


def test_fit_reader_recovers_a_linear_map_and_ignores_the_prior_directions():
    rng = np.random.default_rng(0)
    P, C, N = 30, 4, 4000
    A_true = rng.normal(size=(P, C))
    nuisance = rng.normal(size=(P, 2))
    X = rng.normal(size=(N, P))
    Y = X @ A_true + 0.3
    mx, my, A = fit_reader(X, Y, np.zeros((P, P)), 1e-6)
    assert np.allclose(A, A_true, atol=1e-3) and np.allclose(my - mx @ A, 0.3, atol=1e-3)
    # with the nuisance directions in the prior, moving along them barely moves the output
    mx, my, A = fit_reader(X, Y, 100.0 * nuisance @ nuisance.T, 1e-6)
    assert np.abs(nuisance.T @ A).max() < 0.05 * np.abs(nuisance.T @ A_true).max()


def test_the_shipped_reader_is_whole_and_says_how_it_was_made():
    r = load_reader()
    assert r is not None, f"{DATA} is missing"
    assert list(r.landmarks) == list(range(468))  # no iris: the renders never turn the eyes
    assert len(r.channels) == 53 - 8 and r.A.shape == (468 * 3, len(r.channels))
    assert np.isfinite(r.A).all() and np.isfinite(r.mean_in).all()
    meta = json.loads(DATA.with_suffix(".json").read_text())
    assert meta["identities"] >= 16 and meta["frames"] > 30_000
    bench = (DATA.parents[3] / "benchmarks" / "roundtrip_face.py").read_text()
    seed = int(re.search(r"^SEED = (\d+)", bench, re.M).group(1))
    assert meta["seed"] != seed  # no training identity is a round-trip identity


@pytest.fixture(scope="module")
def d0_both(d0_capture):
    """d0's landmarks fitted with the reader (the default) and without it."""
    seq = d0_capture
    lm = np.asarray(seq.landmarks, np.float64)
    off = fit_landmark_sequence(lm, seq.width, seq.height, seq.fps, CaptureConfig(fit=FitConfig(reader=False)))
    return seq, off


def test_the_reader_keeps_the_gaze_and_says_where_the_weights_came_from(d0_both):
    on, off = d0_both
    names = on.expr_names
    look = [k for k, n in enumerate(names) if n.startswith("eyeLook")]
    assert np.allclose(on.expression[:, look], off.expression[:, look], atol=1e-6)
    assert "reader" in on.meta["expression_from"] and off.meta["expression_from"] == "the fit"
    assert ((on.expression >= 0) & (on.expression <= 1)).all()
    assert np.abs(on.expression - off.expression).max() > 0.1  # it does read something else


def test_a_neutral_stretch_of_d0_reads_near_rest_with_the_reader(d0_both):
    """d0's labelled neutral frames (tests/labels/d0_labels.json): the reader's smile and brows stay low there."""
    on, _ = d0_both
    labels = json.loads((DATA.parents[3] / "tests" / "labels" / "d0_labels.json").read_text())
    neutral = np.r_[tuple(slice(a, b + 1) for a, b in labels["neutral"])]
    n = on.expr_names
    for ch in ("mouthSmile_L", "mouthSmile_R", "browDown_L", "browDown_R"):
        assert on.expression[neutral, n.index(ch)].mean() < 0.2, ch
