"""The weakly supervised 3D pose lifter (seed 004 ch. 3): maths on real Human3.6M/HumanEva data, MediaPipe
mapping on real S9 images, a few training steps on a small slice, checkpoints, masking, capture."""

import dataclasses

import numpy as np
import pytest
import torch

from anima.eval.pose.metrics import align_procrustes, pose_metrics
from anima.io.assets import asset
from anima.pose3d import data as pdata
from anima.pose3d.joints import BONES, FLIP, H36M_PARENTS, K, mediapipe_matrix, mediapipe_to_h36m

GT = "pose3d/derived/h36m_S9_Posing1_c2f_images_gt.npz"


@pytest.fixture(scope="module")
def s9():
    return np.load(asset(GT))


def test_projection_reproduces_h36m_2d_ground_truth(s9):
    """World -> camera -> distorted pixels with the real S9 cameras matches the staged 2D ground truth."""
    checked = 0
    for ci, cam in enumerate(s9["cam_names"]):
        rows = np.flatnonzero(s9["camera"] == cam)[:20]
        if not len(rows):
            continue
        checked += 1
        Xw = s9["joints32_world_mm"][rows][:, s9["joints17_index_in_32"]].astype(np.float64)
        Xc = pdata.world_to_camera(Xw, s9["cam_R"][ci], s9["cam_T_mm"][ci])
        np.testing.assert_allclose(Xc, s9["joints17_cam_mm"][rows], atol=0.5)
        uv = pdata.project_h36m(Xc, s9["cam_f"][ci], s9["cam_c"][ci], s9["cam_k"][ci], s9["cam_p"][ci])
        assert np.abs(uv - s9["joints17_2d_px"][rows]).max() < 0.5
    assert checked == 3


def test_training_set_never_holds_test_subjects():
    h = pdata.load_h36m(("S1",), every=200)
    assert set(h.subject.tolist()) == {"S1"} and len(set(h.camera.tolist())) == 4
    assert not set(pdata.TRAIN_SUBJECTS) & set(pdata.TEST_SUBJECTS)
    # bones of real mocap are consistent across cameras (rigid transform)
    L = np.linalg.norm(h.joints_cam[:, BONES[:, 0]] - h.joints_cam[:, BONES[:, 1]], axis=-1)
    assert L.std(0).max() < 1.0


def test_metrics_protocols():
    rng = np.random.default_rng(0)
    g = rng.normal(size=(4, K, 3)) * 300
    from scipy.spatial.transform import Rotation

    R = Rotation.random(4, random_state=1).as_matrix()
    p = 1.2 * np.einsum("nij,nkj->nki", R, g) + 40
    m = pose_metrics(p, g)
    assert m["procrustes"]["mpjpe"] < 1e-6 and m["procrustes"]["pck150"] == 100
    assert m["unscaled"]["mpjpe"] > 100
    # a pure scale error is removed by the globally scaled protocol only up to rotation: here none
    m2 = pose_metrics(g * 1.3, g)
    assert m2["scaled"]["mpjpe"] < 1e-6 < m2["unscaled"]["mpjpe"]
    # known error: every joint off by 100 mm (root-relative)
    off = g.copy()
    off[:, 1:, 0] += 100
    e = pose_metrics(off, g)["unscaled"]
    assert abs(e["mpjpe"] - 100 * 16 / 17) < 1e-6 and abs(e["pck150"] - 100) < 1e-9
    assert np.allclose(align_procrustes(g, g), g)


def test_mapping_matrix_and_flip():
    M = mediapipe_matrix()
    np.testing.assert_allclose(M.sum(1), 1.0)
    assert (FLIP[FLIP] == np.arange(K)).all()
    assert H36M_PARENTS[0] == -1 and len(BONES) == K - 1


def test_mediapipe_on_real_s9_images_lands_on_the_ground_truth(s9):
    """MediaPipe Pose on three real S9 images (one per camera), mapped to H36M-17: within a few % of the
    image of the ground-truth joints."""
    import cv2

    from anima.pose3d.data import PoseDetector

    folder = asset(pdata.H36M_S9_IMAGES)
    names = {}
    for p in sorted(folder.glob("*.jpg")):
        cam = p.name.split(".")[1].split("_")[0]
        if p.stat().st_size and cam not in names:
            names[cam] = p
    det = PoseDetector(True, 1)
    index = {n: i for i, n in enumerate(s9["imgname"])}
    errs = []
    for p in names.values():
        r = det(cv2.cvtColor(cv2.imread(str(p)), cv2.COLOR_BGR2RGB))
        assert r is not None
        uv, conf = mediapipe_to_h36m(r[0].astype(np.float64), r[1].astype(np.float64))
        errs.append(np.linalg.norm(uv - s9["joints17_2d_px"][index[p.name]], axis=-1).mean())
    det.close()
    assert len(errs) == 3 and max(errs) < 30, errs  # pixels on 1000x1000 images


def test_humaneva_validation_loads_with_camera_frame_ground_truth():
    he = pdata.humaneva_validation()
    assert len(he["uv"]) > 500 and he["uv"].shape[1:] == (K, 2)
    assert (he["conf"][:, 9] == 0).all()  # no nose in HumanEva: masked
    z = he["gt3d"][..., 2]
    assert (z > 1000).mean() > 0.99  # in front of the camera, in mm
    L = np.linalg.norm(he["gt3d"][:, 5] - he["gt3d"][:, 4], axis=-1)  # thigh
    assert 300 < np.median(L) < 550


@pytest.fixture(scope="module")
def tiny_model(tmp_path_factory):
    from anima.pose3d.train import TrainConfig, train

    d = tmp_path_factory.mktemp("lifter")
    cfg = TrainConfig(steps=40, batch=64, every=40, wild=False, model={**TrainConfig().model, "width": 64})
    model, info = train(cfg, d / "tiny.pt", d / "cache", progress=False, resume=False, log_every=10)
    return model, info, d / "tiny.pt", cfg


def test_a_few_training_steps_reduce_the_loss(tiny_model):
    _, info, path, _ = tiny_model
    h = info["history"]
    first, last = sum(v for k, v in h[0].items() if k != "step"), sum(v for k, v in h[-1].items() if k != "step")
    assert last < first
    assert set(h[-1]) >= {"3d", "bone", "heat", "2d"}


def test_checkpoint_round_trip_resume_and_versions(tiny_model, tmp_path):
    from anima.errors import InputError, SchemaError
    from anima.pose3d.train import load_checkpoint, train

    model, _, path, cfg = tiny_model
    m2, ck = load_checkpoint(path)
    assert ck["step"] == 40 and ck["config"]["model"]["width"] == 64
    x = torch.randn(5, K, 2)
    c = torch.ones(5, K)
    assert torch.allclose(model(x, c)["p3d"], m2(x, c)["p3d"])
    # resume: a longer run continues from step 40
    import shutil

    p2 = tmp_path / "resume.pt"
    shutil.copy(path, p2)
    _, info = train(dataclasses.replace(cfg, steps=50), p2, tmp_path / "cache", progress=False, log_every=5)
    assert [h["step"] for h in info["history"]] == [45, 50] and load_checkpoint(p2)[1]["step"] == 50
    with pytest.raises(SchemaError):  # another config on the same file is refused, not silently mixed
        train(dataclasses.replace(cfg, steps=50, lr=0.5), p2, tmp_path / "cache", progress=False)
    bad = torch.load(path, weights_only=True)
    bad["version"] = 99
    torch.save(bad, tmp_path / "v99.pt")
    with pytest.raises(SchemaError, match="version 99"):
        load_checkpoint(tmp_path / "v99.pt")
    (tmp_path / "junk.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(SchemaError):
        load_checkpoint(tmp_path / "junk.pt")
    with pytest.raises(InputError, match="anima train pose"):
        load_checkpoint(tmp_path / "missing.pt")


def test_masked_joints_are_ignored(tiny_model):
    """b_k = 0: where a masked joint is placed does not change the prediction (eq. 3.3's mask)."""
    from anima.pose3d.train import predict

    model = tiny_model[0]
    h = pdata.load_h36m(("S1",), every=500)
    uv, conf = h.uv[:8].astype(np.float64), np.ones((8, K))
    conf[:, [3, 6]] = 0.0  # ankles out of frame
    a = predict(model, uv, conf)
    uv2 = uv.copy()
    uv2[:, [3, 6]] += 500.0
    np.testing.assert_allclose(a, predict(model, uv2, conf), atol=1e-5)
    assert np.isfinite(a).all() and np.allclose(a[:, 0], 0)


def test_capture_with_the_lifter_body(tiny_model, tmp_path, cli):
    """`anima capture --body-3d lifter` on a real gesture clip: the body comes from the lifter, hands stay
    attached to the wrists; a missing checkpoint is one clear line."""
    from anima.io.sequence import read_sequence

    path = tiny_model[2]
    clip = asset("gesture-video/pats-crops/oliver1_gt.mp4")
    r = cli(
        "capture",
        clip,
        "--out",
        tmp_path / "c",
        "--max-frames",
        "12",
        "--no-render",
        "--quiet",
        "--body-3d",
        "lifter",
        "--pose-model",
        path,
    )
    assert r.returncode == 0, r.stderr
    seq = read_sequence(tmp_path / "c" / "capture.npz")
    assert "pose lifter" in seq.meta["skeleton"]["tracker"]
    J = seq.body_joints_raw
    ok = np.isfinite(J[:, :13]).all((1, 2))
    assert ok.sum() >= 10
    hand_ok = ok & np.isfinite(J[:, 13]).all(-1)
    if hand_ok.any():  # left-hand wrist joint sits on the body's left wrist
        np.testing.assert_allclose(J[hand_ok, 13], J[hand_ok, 9], atol=1e-6)
    r = cli(
        "capture",
        clip,
        "--out",
        tmp_path / "d",
        "--max-frames",
        "5",
        "--no-render",
        "--quiet",
        "--body-3d",
        "lifter",
        "--pose-model",
        tmp_path / "none.pt",
    )
    assert r.returncode == 2 and "anima train pose" in r.stderr and "Traceback" not in r.stderr


def test_wild_evidence_is_mediapipe_2d_with_masks(tmp_path):
    w = pdata.wild_evidence(tmp_path, every=3, max_frames_per_video=6)
    assert len(w["uv"]) > 20 and w["uv"].shape[1:] == (K, 2)
    assert ((w["conf"] >= 0) & (w["conf"] <= 1)).all()
    assert len(w["videos"]) >= 20


def test_frames_without_a_person_stay_empty(tiny_model):
    """A frame where MediaPipe found no person gives NaN joints, not a made-up pose; a person half out of
    frame (legs not visible) still gets a full 17-joint estimate."""
    from anima.pose3d.infer import lift_frames

    h = pdata.load_h36m(("S1",), every=2000)
    mp_px = np.full((3, 33, 2), np.nan)
    vis = np.zeros((3, 33))
    # frames 0 and 2: a person placed at MediaPipe's indices from a real projected H3.6M pose
    from anima.pose3d.joints import _MP

    for f in (0, 2):
        mp_px[f] = 0.0  # MediaPipe always returns all 33 landmarks for a found person
        for name, j in _MP.items():
            src = {"nose": 9, "l_eye": 10, "r_eye": 10, "l_ear": 10, "r_ear": 10, "mouth_l": 9, "mouth_r": 9}
            k = src.get(name, None)
            if k is None:
                from anima.pose3d.joints import H36M_NAMES

                k = H36M_NAMES.index(name)
            mp_px[f, j] = h.uv[f, k]
            vis[f, j] = 0.9
    vis[2, [25, 26, 27, 28]] = 0.1  # frame 2: knees and ankles out of frame
    out = lift_frames(tiny_model[0], mp_px, vis)
    assert np.isnan(out[1]).all()
    assert np.isfinite(out[0]).all() and np.isfinite(out[2]).all()
