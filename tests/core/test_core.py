import numpy as np

from anima.core.camera import camera_to_image, mediapipe_to_camera, project, umeyama
from anima.core.filters import OneEuroFilter, gaussian_smooth, valid_runs
from anima.core.rotations import euler_to_matrix, matrix_to_euler, matrix_to_quat, matrix_to_rotvec, rotvec_to_matrix


def test_rotvec_roundtrip_and_orthonormal():
    rng = np.random.default_rng(0)
    rv = rng.normal(size=(100, 3))
    rv *= (np.pi * 0.99 * rng.random((100, 1))) / np.linalg.norm(rv, axis=1, keepdims=True)
    R = rotvec_to_matrix(rv)
    assert np.allclose(R @ R.transpose(0, 2, 1), np.eye(3), atol=1e-10)
    assert np.allclose(np.linalg.det(R), 1)
    assert np.allclose(matrix_to_rotvec(R), rv, atol=1e-7)


def test_euler_convention_pinned():
    # yaw about +y turns +z (the face's forward direction) towards +x (image right)
    R = euler_to_matrix(np.pi / 2, 0.0, 0.0)
    assert np.allclose(R @ [0, 0, 1], [1, 0, 0], atol=1e-12)
    # positive pitch about +x turns +z (forward) towards -y (down): the head looks down
    R = euler_to_matrix(0.0, 0.3, 0.0)
    assert (R @ [0, 0, 1])[1] < 0
    ang = np.random.default_rng(1).uniform(-1.2, 1.2, size=(50, 3))
    assert np.allclose(matrix_to_euler(euler_to_matrix(*ang.T)), ang, atol=1e-9)


def test_quaternion_matches_rotvec():
    rv = np.array([[0.0, 0.0, 0.0], [0.3, -0.2, 0.1], [0.0, np.pi - 1e-3, 0.0]])
    q = matrix_to_quat(rotvec_to_matrix(rv))
    ang = np.linalg.norm(rv, axis=1)
    assert np.allclose(np.abs(q[:, 3]), np.cos(ang / 2), atol=1e-6)


def test_umeyama_recovers_similarity():
    rng = np.random.default_rng(2)
    src = rng.normal(size=(4, 50, 3))
    R = rotvec_to_matrix(rng.normal(size=(4, 3)))
    s = rng.uniform(0.5, 3, 4)
    t = rng.normal(size=(4, 3))
    dst = s[:, None, None] * src @ R.transpose(0, 2, 1) + t[:, None]
    s2, R2, t2 = umeyama(src, dst)
    assert np.allclose(s2, s) and np.allclose(R2, R) and np.allclose(t2, t)


def test_mediapipe_camera_and_projection_conventions():
    lm = np.array([[0.25, 0.75, 0.1]])
    X = mediapipe_to_camera(lm, 200, 100)
    assert np.allclose(camera_to_image(X), [[50, 75]])  # back to pixels
    assert X[0, 2] < 0  # farther from the camera = more negative z (camera looks down -z)
    uv = project(np.array([[1.0, 1.0, 0.0]]), np.array([10.0]), np.eye(3)[None], np.array([[100.0, -50.0, 0.0]]))
    assert np.allclose(uv, [[[110, 40]]])  # +y up in model space is up (smaller v) in the image


def test_gaussian_smooth_zero_phase_and_segments():
    x = np.zeros(41)
    x[20] = 1.0
    y = gaussian_smooth(x, 1.5)
    assert np.argmax(y) == 20 and np.isclose(y.sum(), 1.0)  # no lag, mass kept
    valid = np.ones(41, bool)
    valid[10] = False
    assert valid_runs(valid) == [(0, 10), (11, 41)]
    step = np.r_[np.zeros(10), np.ones(31)]
    z = gaussian_smooth(step, 3.0, valid)
    assert np.allclose(z[:10], 0)  # segments are not blended across the gap


def test_one_euro_reduces_jitter_and_follows_motion():
    rng = np.random.default_rng(3)
    noisy = 1.0 + rng.normal(0, 0.05, 300)
    f = OneEuroFilter(30, min_cutoff=1.0, beta=2.0)
    y = np.array([f(v) for v in noisy])
    assert np.abs(np.diff(y, 2))[30:].mean() < 0.3 * np.abs(np.diff(noisy, 2))[30:].mean()
    # a fast move: the adaptive cutoff follows within a few frames, unlike a fixed 1 Hz low-pass
    step = np.r_[np.zeros(30), np.full(30, 5.0)]
    f.reset()
    ys = np.array([f(v) for v in step])
    fixed = OneEuroFilter(30, min_cutoff=1.0, beta=0.0)
    yf = np.array([fixed(v) for v in step])
    assert ys[33] > 4.0 and yf[33] < 3.0


def test_prominent_peaks_equals_scipy_find_peaks():
    """The detectors' peak finder (no scipy.signal on the cold path) agrees with scipy's find_peaks on rounded
    random walks (plateaus, ties, peaks at the ends) and on real captured head and mouth curves."""
    from scipy.signal import find_peaks

    from anima.core.contract import FACE_DIM
    from anima.core.filters import prominent_peaks
    from anima.library.builtin import load

    rng = np.random.default_rng(0)
    signals = [np.round(np.cumsum(rng.normal(size=rng.integers(2, 300))), 1) for _ in range(300)]
    lib = load()
    signals += [m[:, c].astype(np.float64) for m in lib.face_motion[:20] for c in (FACE_DIM - 3, FACE_DIM - 2, 20)]
    checked = 0
    for x in signals:
        for prom in (0.0, 0.05, 0.5, 2.0):
            want = find_peaks(x, prominence=prom)[0]
            np.testing.assert_array_equal(prominent_peaks(x, prom), want)
            checked += len(want)
    assert checked > 1000
    assert prominent_peaks(np.array([0.0, 1, 1, 1, 0]), 0.5).tolist() == [2]  # a plateau: its middle
