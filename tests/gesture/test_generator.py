"""The §4.4 speech-to-gesture generator and its baselines, FGD, the lip keypoint error, keyword-triggered
databases and the dataset's face-only windows, on the dataset built from real clips (conftest)."""

import json
import subprocess

import numpy as np
import pytest

from anima.io.assets import asset
from anima.io.video import FFMPEG

SPEECH = "gesture-video/pats-crops/oliver2_gt.mp4"


@pytest.fixture(scope="module")
def windows(ds):
    from anima.dataset.windows import read_windows

    return read_windows(str(ds))


@pytest.fixture(scope="module")
def wav(tmp_path_factory):
    p = tmp_path_factory.mktemp("gen") / "s.wav"
    subprocess.run(
        [FFMPEG, "-v", "error", "-y", "-i", str(asset(SPEECH)), "-t", "5", "-vn", "-ar", "22050", str(p)], check=True
    )
    return p


def test_dataset_keeps_face_only_windows_with_the_paired_wav(ds, windows):
    from anima.dataset.build import paired_audio

    video = asset("styletalk-samples/samples/source_video/video/feifeili_clip3.mp4")
    assert paired_audio(video).name == "feifeili_clip3.wav"  # the video has no audio track
    face_only = [s for s, h in zip(windows.source, windows.has_body) if not h]
    assert face_only and all("styletalk" in s for s in face_only)
    i = windows.source.index(face_only[0])
    assert np.isnan(windows.body[i]).all() and np.isfinite(windows.face[i]).all()
    assert windows.face[i][:, :53].std(0).max() > 0.02  # the mouth moves while she speaks
    assert windows.has_body.sum() >= 6


def test_short_gaps_are_interpolated_long_ones_kept_missing():
    from anima.dataset.pairs import fill_short_gaps

    x = np.arange(12, dtype=np.float64)[:, None].repeat(2, 1)
    x[3:5, 0] = np.nan  # 2 frames: filled
    x[6:11, 1] = np.nan  # 5 frames: too long
    x[0, 1] = np.nan  # at the start: nothing to interpolate from
    y = fill_short_gaps(x, 3)
    np.testing.assert_allclose(y[:, 0], np.arange(12))
    assert np.isnan(y[6:11, 1]).all() and np.isnan(y[0, 1])


def test_parts_round_trip(windows):
    from anima.gesture.generator import join_parts, split_parts

    i = int(np.flatnonzero(windows.has_body)[0])
    parts = split_parts(windows.body[i], windows.face[i])
    assert {k: v.shape[-1] for k, v in parts.items()} == {"face": 53, "body": 42, "hands": 126}
    J, face = join_parts(parts)
    np.testing.assert_array_equal(J.reshape(64, 165), windows.body[i])
    np.testing.assert_array_equal(face, windows.face[i])


@pytest.mark.parametrize("kind", ["adversarial", "regression", "lstm"])
def test_generator_trains_and_generates_any_length(windows, kind, tmp_path):
    from anima.gesture.generator import (
        GeneratorConfig,
        GeneratorTrainConfig,
        load_generator,
        save_generator,
        train_generator,
    )

    gen, info = train_generator(
        windows.speech, windows.body, windows.face, GeneratorConfig(kind=kind), GeneratorTrainConfig(steps=60, batch=8)
    )
    w = info["loss_weights"]
    assert all(v > 0 for v in w.values()) and info["body_windows"] < info["windows"]
    for part in ("face", "body", "hands"):  # each term starts near 1 (the mean pose) and goes down
        log = info["log"][part]
        assert np.mean(log[-10:]) < np.mean(log[:5])
    if kind == "adversarial":
        assert len(info["log"]["disc"]) == 60 and np.isfinite(info["log"]["disc"]).all()
    J, face = gen.generate(windows.speech[0][:37])  # fully convolutional: any length
    assert J.shape == (37, 55, 3) and face.shape == (37, 56) and np.isfinite(J).all()
    assert (face[:, :53] >= 0).all() and (face[:, :53] <= 1).all()
    from anima.core.skeleton import bone_lengths

    L = bone_lengths(J)[:, 1:]  # the output keeps the training data's skeleton: no bone changes length
    np.testing.assert_allclose(L, np.broadcast_to(gen.stats["bone_lengths"][1:], L.shape), atol=1e-5)
    again = load_generator(save_generator(tmp_path / "g.pt", gen, info))
    np.testing.assert_allclose(again.generate(windows.speech[1])[0], gen.generate(windows.speech[1])[0], atol=1e-6)


def test_moglow_flow_inverts_and_its_log_determinant_is_the_jacobians():
    import dataclasses

    import torch

    from anima.gesture.generator import GeneratorConfig
    from anima.gesture.moglow import MoGlow

    torch.manual_seed(0)
    cfg = dataclasses.replace(GeneratorConfig(kind="moglow"), flow_dim=6, flow_steps=3, flow_hidden=16)
    net = MoGlow(cfg, {"a": 4, "b": 5}, 3, np.zeros(9, np.float32), np.eye(9, 6, dtype=np.float32))
    net.train()
    net._flow(torch.randn(50, 6), torch.randn(50, 16))  # activation norms initialise on a first batch
    for p in net.parameters():  # couplings start as the identity: move them
        p.data += 0.1 * torch.randn_like(p)
    x, c = torch.randn(4, 6, dtype=torch.float64), torch.randn(4, 16, dtype=torch.float64)
    net = net.double()
    z, logdet = net._flow(x, c)
    torch.testing.assert_close(net._inverse(z, c), x)
    for k in range(4):  # log |det dz/dx| per sample, against autograd's Jacobian
        J = torch.autograd.functional.jacobian(lambda v: net._flow(v[None], c[k : k + 1])[0][0], x[k])
        torch.testing.assert_close(logdet[k], torch.linalg.slogdet(J)[1])


def test_moglow_baseline_learns_the_likelihood_of_real_motion_and_samples_by_seed(windows, tmp_path):
    from anima.gesture.generator import (
        GeneratorConfig,
        GeneratorTrainConfig,
        load_generator,
        save_generator,
        train_generator,
    )

    gen, info = train_generator(
        windows.speech,
        windows.body,
        windows.face,
        GeneratorConfig(kind="moglow"),
        GeneratorTrainConfig(steps=40, batch=8),
    )
    nll = info["log"]["nll"]
    assert np.mean(nll[-5:]) < np.mean(nll[:5]) - 0.1  # nats per dimension
    assert info["body_windows"] < info["windows"] and 0.5 < info["pca_variance_kept"] <= 1.0
    J, face = gen.generate(windows.speech[0][:37])
    assert J.shape == (37, 55, 3) and face.shape == (37, 56) and np.isfinite(J).all()
    again = load_generator(save_generator(tmp_path / "m.pt", gen, info))
    np.testing.assert_allclose(again.generate(windows.speech[1])[0], gen.generate(windows.speech[1])[0], atol=1e-5)
    other = gen.generate(windows.speech[2])[0][:37]
    assert np.abs(other - J).mean() > 1e-4  # other speech, other motion


def test_frechet_distance_and_lip_error_maths():
    from anima.eval.gesture.fgd import frechet_distance
    from anima.eval.gesture.metrics import lip_error_mm, mouth_opening_mm

    rng = np.random.default_rng(0)
    a = rng.normal(size=(4000, 3))
    assert frechet_distance(a, a) == pytest.approx(0, abs=1e-6)
    # equal covariances: the distance is the squared distance of the means
    assert frechet_distance(a, a + [2.0, 0, 0]) == pytest.approx(4.0, rel=1e-6)
    # N(0, I) vs N(0, 4I) in 3-d: 3 * (1 + 4 - 2 * 2) = 3
    assert frechet_distance(a, 2 * rng.normal(size=(4000, 3))) == pytest.approx(3.0, rel=0.1)
    # one window (no covariance) or a diverged model's NaN output: NaN, not an exception ending the row
    assert np.isnan(frechet_distance(a[:1], a)) and np.isnan(frechet_distance(a, np.full((10, 3), np.nan)))
    f = np.zeros((5, 56))
    assert lip_error_mm(f, f) == 0
    jaw = f.copy()
    from anima.facemodel.ict import load_face_model

    jaw[:, load_face_model().expr_names.index("jawOpen")] = 1.0
    assert 2 < lip_error_mm(jaw, f) < 30  # an open jaw moves the lips by millimetres to centimetres
    assert mouth_opening_mm(jaw).mean() > mouth_opening_mm(f).mean() + 5


def test_fgd_separates_captured_from_shuffled_motion(db):
    from anima.eval.gesture.fgd import train_fgd

    G = db.G.reshape(db.M, 64, 165)
    fgd = train_fgd(G, steps=150)
    rng = np.random.default_rng(0)
    noisy = G + rng.normal(0, 0.05, G.shape).astype(np.float32)  # 5 cm jitter on every joint
    assert fgd.distance(G, noisy) > fgd.distance(G, G) + 1e-3


def test_keyword_database_takes_over_while_the_word_is_spoken(ds, wav):
    from dataclasses import replace

    from anima.gesture.database import from_dataset
    from anima.gesture.keywords import parse_keyword
    from anima.gesture.run import SEED_SEARCH, synthesize

    db = from_dataset(ds, None)
    videos = sorted({s for s, _ in db.source})
    kw_rows = [i for i, (s, _) in enumerate(db.source) if s == videos[0]]
    from anima.gesture.knn import MatchDB

    kw_db = MatchDB(db.F[kw_rows], db.P[kw_rows], db.G[kw_rows], [db.source[i] for i in kw_rows], db.S[kw_rows])
    rest = [i for i in range(db.M) if i not in kw_rows]
    main = MatchDB(db.F[rest], db.P[rest], db.G[rest], [db.source[i] for i in rest], db.S[rest])
    J, info = synthesize(str(wav), main, replace(SEED_SEARCH, keyword=["yes@1.0-2.5s"]), keyword_dbs={"yes": kw_db})
    used = info["database_per_step"]
    step_t = np.arange(len(used)) * 8 / 15
    assert all((u == "yes") == (1.0 <= t < 2.5) for u, t in zip(used, step_t))
    for (m, _), u in zip(info["picks"], used):  # union layout: the standard windows first, then the keyword's
        assert (m >= main.M) == (u == "yes")
    with pytest.raises(Exception, match="no database"):
        synthesize(str(wav), main, replace(SEED_SEARCH, keyword=["no@0-1s"]), keyword_dbs={"yes": kw_db})
    with pytest.raises(Exception, match="WORD@START-END"):
        parse_keyword("yes at 3s")


def test_generator_commands(ds, wav, tmp_path, cli):
    ck = tmp_path / "gen.pt"
    r = cli(
        "train",
        "gesture",
        "--db",
        str(ds),
        "--all-splits",
        "--model",
        "generator",
        "--steps",
        "20",
        "--out",
        str(ck),
        "--quiet",
        "--json",
    )
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["kind"] == "adversarial" and ck.is_file()
    out = tmp_path / "g"
    r = cli("gesture", str(wav), "--generator", str(ck), "--out", str(out), "--no-render", "--json")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    n = info["frames"]
    assert abs(n - 149) <= 2 and info["model"] == "adversarial"  # 5 s: 75 frames at the model's 15 fps, written at 30
    from anima.io.sequence import read_sequence

    seq = read_sequence(out / "gesture.npz")  # one tracked sequence: the generator's face and body
    assert seq.expression.shape == (n, 53) and seq.body_joints.shape == (n, 55, 3) and seq.tracked.all()
    assert (out / "arkit.csv").read_text().startswith("Timecode")
    flow = tmp_path / "moglow.pt"  # the MoGlow-style baseline through the same two commands
    r = cli("train", "gesture", "--db", str(ds), "--model", "moglow", "--steps", "10", "--out", str(flow), "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["kind"] == "moglow"
    r = cli("gesture", str(wav), "--generator", str(flow), "--out", str(tmp_path / "m"), "--no-render", "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["model"] == "moglow" and abs(json.loads(r.stdout)["frames"] - 149) <= 2
    r = cli(
        "gesture", str(wav), "--generator", str(ck), "--out", str(tmp_path / "h"), "--control", "left_wrist_height>=p85"
    )
    assert r.returncode == 2 and "k-NN search" in r.stderr
    r = cli("gesture", str(wav), "--db", str(ds), "--generator", str(ck), "--out", str(tmp_path / "i"))
    assert r.returncode == 2 and "not both" in r.stderr
    r = cli("gesture", str(wav), "--db", str(ds), "--out", str(tmp_path / "j"), "--keyword", "yes@1-2s")
    assert r.returncode == 2 and "keyword-db" in r.stderr and "Traceback" not in r.stderr
