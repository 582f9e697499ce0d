"""Text -> facial motion (seed 000 ch. 6-7): the encoder interface, the FaceFormer pieces, the exact
vertex-offset loss, the cached sampler, the shipped checkpoint, training on a dataset built from real clips,
and the command with its bad inputs."""

import json
import warnings

import numpy as np
import pytest
import torch

from anima.errors import AssetNotFound, InputError, SchemaError
from anima.io.assets import asset

CLIPS = ["liveportrait-examples/assets/examples/driving/d0.mp4", "liveportrait-examples/assets/examples/driving/d6.mp4"]


@pytest.fixture(scope="module")
def encoder():
    from anima.text2face.encoders import get_encoder

    return get_encoder("minilm")


# ---- encoders ---------------------------------------------------------------------------------------


def test_minilm_shape_determinism_and_any_language(encoder):
    texts = ["a woman smiles, then blinks", "una mujer sonríe y luego parpadea", "女人微笑"]
    a, b = encoder.encode(texts), encoder.encode(texts)
    assert a.shape == (3, 384) and a.dtype == np.float32
    np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(np.linalg.norm(a, axis=1), 1, atol=1e-5)
    assert np.isfinite(a).all() and not np.allclose(a[0], a[1])
    # related sentences are closer than unrelated ones
    c = encoder.encode(["a man smiles and then blinks", "the stock market fell sharply today"])
    assert c[0] @ a[0] > c[1] @ a[0] + 0.3


def test_clip_encoder_shape_and_determinism_or_a_clear_error():
    from anima.text2face.encoders import OpenClipEncoder

    try:
        enc = OpenClipEncoder()
    except AssetNotFound as e:
        assert "minilm" in str(e)  # tells the user what to use instead
        pytest.skip(f"CLIP unavailable here: {e}")
    e1, e2 = enc.encode(["a person smiles"]), enc.encode(["a person smiles"])
    assert e1.shape == (1, 512)
    np.testing.assert_array_equal(e1, e2)


def test_prompts_empty_refused_long_truncated(encoder):
    from anima.text2face.encoders import clean_prompt

    for bad in ["", "   ", None]:
        with pytest.raises(InputError, match="empty"):
            clean_prompt(bad, encoder)
    long = " ".join(["the person smiles and then blinks"] * 80)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        short = clean_prompt(long, encoder)
    assert any("truncated" in str(x.message) for x in w)
    assert encoder.n_tokens(short) <= encoder.max_tokens


# ---- model maths --------------------------------------------------------------------------------------


def test_temporal_and_alignment_biases_and_periodic_encoding():
    from anima.text2face.model import alignment_bias, periodic_positional_encoding, temporal_bias

    B = temporal_bias(4, 15, 40)
    assert B.shape == (4, 40, 40)
    assert torch.isinf(B[:, 3, 4:]).all() and torch.isfinite(B[:, 3, :4]).all()  # causal
    assert (B[:, 20, 6:21] == 0).all() and (B[:, 20, 5] < 0).all()  # same period: no penalty
    assert B[0, 39, 0] < B[3, 39, 0]  # steeper slope on head 0
    A = alignment_bias(5, 7)
    assert (A.diagonal() == 0).all() and torch.isinf(A[0, 1:]).all()
    pe = periodic_positional_encoding(32, 15, 60)
    torch.testing.assert_close(pe[:15], pe[15:30])


def _tiny(**over):
    from anima.text2face.model import Text2Face, preset

    torch.manual_seed(0)
    m = Text2Face(preset("small", d_m=64, d_t=8, mlp_hidden=32, max_len=60, n_layers=2, **over))
    for p in m.out.parameters():  # the output layer starts at zero; give it values for the tests
        torch.nn.init.normal_(p, std=0.1)
    return m.eval()


def test_cached_sampler_equals_uncached_and_teacher_forcing_is_causal():
    m = _tiny()
    e, c = torch.randn(2, 384), torch.randn(2, 64)
    a = m.sample(e, c, 40, cached=True)
    b = m.sample(e, c, 40, cached=False)
    torch.testing.assert_close(a, b, atol=1e-5, rtol=1e-4)
    # teacher forcing on the sampled sequence reproduces it (same inputs at every step)
    with torch.no_grad():
        tf, _ = m(e, c, a)
    torch.testing.assert_close(tf, a, atol=1e-5, rtol=1e-4)
    # frame t of the prediction does not depend on frames >= t of the input
    x = torch.randn(2, 40, 56)
    y = x.clone()
    y[:, 20:] += 1
    with torch.no_grad():
        p1, _ = m(e, c, x)
        p2, _ = m(e, c, y)
    torch.testing.assert_close(p1[:, :21], p2[:, :21])
    assert not torch.allclose(p1[:, 21:], p2[:, 21:])
    with pytest.raises(ValueError, match="trained range"):
        m.sample(e, c, 61)


def test_vq_straight_through_reaches_the_encoder_and_codebook_learns_from_vq_only():
    m = _tiny().train()
    e, c, x = torch.randn(4, 384), torch.randn(4, 64), torch.randn(4, 30, 56)
    pred, vq = m(e, c, x)
    (pred - x).pow(2).mean().backward(retain_graph=True)
    assert m.guide.enc[0].weight.grad.abs().sum() > 0  # reconstruction gradient passes the quantiser
    assert m.guide.codebook.weight.grad is None or m.guide.codebook.weight.grad.abs().sum() == 0
    vq.backward()
    assert m.guide.codebook.weight.grad.abs().sum() > 0


def test_gram_loss_equals_explicit_z_normalised_vertex_offset_mse():
    from anima.text2face.data import FaceGeometry
    from anima.text2face.train import rec_loss

    geom = FaceGeometry()
    rng = np.random.default_rng(0)
    expr = rng.random((500, 53)) ** 3
    G = geom.gram(expr)
    # explicit: offsets of every face vertex coordinate, z-normalised with the same per-coordinate std
    O = expr @ geom.B
    sd = O.std(0)
    sd = np.maximum(sd, 0.05 * np.median(sd[sd > 0]))
    std = np.ones(56, np.float32)
    std[:53] = 1.0
    p, t = rng.random((1, 3, 56)).astype(np.float32), rng.random((1, 3, 56)).astype(np.float32)
    p[..., 53:] = t[..., 53:]
    explicit = (((p[0, :, :53] - t[0, :, :53]) @ geom.B / sd) ** 2).mean()
    got = rec_loss(
        torch.from_numpy(p), torch.from_numpy(t), torch.ones(1, 3), torch.from_numpy(std), torch.from_numpy(G), 1.0
    )
    assert float(got) == pytest.approx(explicit, rel=2e-3)


# ---- the shipped checkpoint ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def shipped():
    from anima.text2face.generate import Generator, default_checkpoint

    return Generator(default_checkpoint())


def test_shipped_checkpoint_is_small_and_carries_its_manifest(shipped):
    p = shipped.path
    assert p.stat().st_size < 8e6
    man = json.loads(p.with_suffix(".json").read_text())
    assert man["command"].startswith("python tools/ship_text2face.py") and len(man["data_fingerprint"]) == 16
    # trained at the step count the validation windows chose (recorded with their MAE per count)
    chosen = man["steps_chosen"]
    val = {int(k): v for k, v in chosen["validation_mae_mm"].items()}
    assert man["steps"] == chosen["value"] == min(val, key=val.get) and "validation" in chosen["chosen_on"]
    assert man["heldout_metrics"]["mae_mm"]["mean"] > 0 and man["train_wall_s"] < 1800
    import hashlib

    assert hashlib.sha256(p.read_bytes()).hexdigest() == man["sha256"]


def test_the_shipped_checkpoint_never_saw_a_validation_or_test_video(shipped, shared_split_table):
    """Its manifest lists the videos it trained on by key path, checkable on any copy of the data:
    every one is in the training split of the current rule, and the rule it was trained under is this one."""
    from anima.dataset import splits

    man = json.loads(shipped.path.with_suffix(".json").read_text())
    # the split-deciding parts of the rule (grouping by face crops can only move videos, which
    # the table below checks)
    same = ("salt", "test", "val", "near_bits", "module")
    assert {k: man["split_rule"][k] for k in same} == {k: splits.rule()[k] for k in same}
    assert len(man["train_videos"]) > 20
    table = {r["key_path"]: r["split"] for r in shared_split_table.values()}
    seen = [v for v in man["train_videos"] if table[v] != "train"]
    assert not seen, seen


def test_shipped_model_generates_seeded_valid_motion(shipped):
    a = shipped.generate(["a woman smiles, then blinks"], 90, seed=0)
    b = shipped.generate(["a woman smiles, then blinks"], 90, seed=0)
    c = shipped.generate(["a woman smiles, then blinks"], 90, seed=1)
    assert a.shape == (1, 90, 56) and np.isfinite(a).all()
    assert a[..., :53].min() >= 0 and a[..., :53].max() <= 1
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    assert a[0, :, :53].std(0).max() > 0.01  # it moves
    with pytest.raises(InputError, match="trained range"):
        shipped.generate(["a person smiles"], 10_000)


def test_shipped_model_follows_the_prompt(shipped):
    """The dataset's detectors on generated motion: a smile prompt smiles more than a neutral one."""
    from anima.dataset.attributes import _mean
    from anima.export.framing import generated_sequence

    smile = shipped.generate(["The person smiles for a long time"] * 5, 90, seed=3)
    neutral = shipped.generate(["The person keeps a neutral face for a long time"] * 5, 90, seed=3)
    s = [_mean(generated_sequence(30.0, face=m), ["mouthSmile_L", "mouthSmile_R"]).mean() for m in smile]
    n = [_mean(generated_sequence(30.0, face=m), ["mouthSmile_L", "mouthSmile_R"]).mean() for m in neutral]
    assert np.mean(s) > np.mean(n) + 0.05, (s, n)


def test_checkpoint_of_another_version_is_refused(tmp_path, shipped):
    from anima.text2face.train import load_checkpoint

    obj = torch.load(shipped.path, weights_only=True)
    obj["version"] = 99
    torch.save(obj, tmp_path / "v99.pt")
    with pytest.raises(SchemaError, match="version 99"):
        load_checkpoint(tmp_path / "v99.pt")
    (tmp_path / "junk.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(SchemaError):
        load_checkpoint(tmp_path / "junk.pt")


def test_smf_baseline_treats_a_padded_sequence_as_it_would_one_alone_and_samples_by_seed():
    from anima.text2face.diffusion import SMF, SMFConfig

    torch.manual_seed(0)
    m = SMF(SMFConfig(channels=(32, 64, 64), d_in=16, solver_steps=4, max_len=60)).eval()
    for p in m.parameters():  # the residual blocks' last convolutions start at zero: move every path
        p.data += 0.02 * torch.randn_like(p)
    x, t, e = torch.randn(2, 45, 56), torch.tensor([10, 500]), torch.randn(2, 384)
    pad = torch.zeros(2, 45, dtype=torch.bool)
    pad[1, 37:] = True
    y = m(x, t, e, torch.ones(2), pad)
    alone = m(x[1:, :37], t[1:], e[1:], torch.ones(1))  # 37 frames: not a multiple of the U-Net's 4
    torch.testing.assert_close(alone[0], y[1, :37], atol=1e-5, rtol=1e-4)
    x2 = x.clone()
    x2[1, 37:] = 100.0  # what lies in the padding does not matter
    torch.testing.assert_close(m(x2, t, e, torch.ones(2), pad)[1, :37], y[1, :37])
    assert not torch.allclose(m(x, t, e, torch.zeros(2), pad), y)  # the text reaches the output
    g = lambda s: torch.Generator().manual_seed(s)
    a, b, c = m.sample(e, 40, g(1)), m.sample(e, 40, g(1)), m.sample(e, 40, g(2))
    assert a.shape == (2, 40, 56) and torch.isfinite(a).all()
    torch.testing.assert_close(a, b)
    assert not torch.allclose(a, c)
    with pytest.raises(ValueError, match="trained range"):
        m.sample(e, 61)


# ---- training on real clips, and the command ------------------------------------------------------------


@pytest.fixture(scope="module")
def ds(tmp_path_factory, cli):
    out = tmp_path_factory.mktemp("t2fds") / "ds"
    r = cli(
        "dataset",
        "build",
        *[asset(c) for c in CLIPS],
        "--out",
        out,
        "--min-len",
        "2",
        "--max-len",
        "6",
        "--workers",
        "2",
        "--quiet",
        "--json",
    )
    assert r.returncode == 0, r.stderr[-2000:]
    return out


def test_training_learns_resumes_exactly_and_carries_its_config(ds, tmp_path):
    from anima.text2face.train import TrainConfig, load_checkpoint, train

    cfg = TrainConfig(
        preset="small",
        model={"d_m": 64, "d_t": 8, "mlp_hidden": 32},
        steps=60,
        ckpt_every=30,
        per_clip=8,
        min_len=30,
        max_len=180,
        lr=1e-3,
        batch=4,
    )
    full = train(ds, tmp_path / "a", cfg, progress=False)
    losses = full["info"]["losses"]
    assert np.mean(losses[-10:]) < np.mean(losses[:10])
    import dataclasses

    train(ds, tmp_path / "b", dataclasses.replace(cfg, steps=30), progress=False)
    resumed = train(ds, tmp_path / "b", cfg, progress=False)  # extends the 30-step run to 60
    for (k, v), w in zip(full["model"].state_dict().items(), resumed["model"].state_dict().values()):
        torch.testing.assert_close(v, w, msg=k)
    ck = load_checkpoint(tmp_path / "a" / "checkpoint.pt")
    assert ck["model_config"]["d_m"] == 64 and ck["train_config"]["steps"] == 60 and ck["step"] == 60
    with pytest.raises(InputError, match="another configuration"):
        train(ds, tmp_path / "a", dataclasses.replace(cfg, lr=1e-2), progress=False)


def test_steps_are_chosen_on_validation_windows_from_snapshots_of_one_run(ds, tmp_path):
    """The StableMoFusion-style baseline trained on real clips: one run keeps a snapshot at each step count
    of the grid, each snapshot is the model a run of that length gives, and the choice is the snapshot with
    the lowest validation MAE, recorded with every candidate's score."""
    import dataclasses

    from anima.eval.text2face.run import choose_steps, model_method, validation_mae
    from anima.text2face.data import FaceGeometry, eval_items
    from anima.text2face.encoders import encode_cached
    from anima.text2face.train import TrainConfig, load_checkpoint, prepare, train

    cfg = TrainConfig(
        kind="smf",
        model={"channels": [32, 64], "d_in": 16, "solver_steps": 3},
        per_clip=8,
        min_len=30,
        max_len=180,
        lr=1e-3,
        batch=4,
    )
    prepared = prepare(ds, cfg)
    enc = prepared[5]
    # windows of the real clips, marked as one validation video's and one test video's
    items = [
        dataclasses.replace(it, split=("val", "test")[k % 2], video=f"v{k % 2}")
        for k, it in enumerate(eval_items(prepared[0])[:6])
    ]
    E = encode_cached(enc, [t for it in items for t in it.texts]).reshape(len(items), 3, -1)
    geom = FaceGeometry()
    path, rec = choose_steps(ds, tmp_path, "smf", cfg, (12, 6), items, E, geom, 2, prepared, False, "test")
    assert rec["grid"] == [6, 12] and set(rec["validation_mae_mm"]) == {"6", "12"}
    assert set(rec["validation_over_videos"]) == {"6", "12"} and rec["spread"]["training_runs_per_step"] == 1
    assert rec["value"] == min((6, 12), key=lambda n: rec["validation_mae_mm"][str(n)])
    assert path.name == f"step_{rec['value']}.pt" and "3 windows of 1 videos" in rec["chosen_on"]
    again = validation_mae(model_method("smf", path), items, E, geom, 2)
    assert again == pytest.approx(rec["validation_mae_mm"][str(rec["value"])], abs=1e-4)
    plain = train(ds, tmp_path / "plain", dataclasses.replace(cfg, steps=6), progress=False, prepared=prepared)
    snap = load_checkpoint(tmp_path / "steps" / "smf" / "step_6.pt")
    assert snap["kind"] == "smf" and snap["step"] == 6
    for k, v in plain["model"].state_dict().items():
        torch.testing.assert_close(snap["state"][k], v, msg=k)


def test_text2face_command_writes_its_files_and_refuses_bad_input(tmp_path, cli):
    from anima.io.sequence import read_sequence

    out = tmp_path / "gen"
    r = cli(
        "text2face", "a woman smiles, then blinks", "--out", str(out), "--length", "45", "--method", "model", "--json"
    )
    assert r.returncode == 0, r.stderr[-2000:]
    info = json.loads(r.stdout)
    for f in ("motion.npz", "face.mp4", "arkit.csv", "face.glb", "info.json"):
        assert (out / f).stat().st_size > 0, f
    seq = read_sequence(out / "motion.npz")
    assert seq.n_frames == 45 and seq.fps == 30 and info["frames"] == 45
    assert len((out / "arkit.csv").read_text().splitlines()) == 46
    for args, code, msg in [
        (("",), 2, "empty"),
        (("a person smiles", "--method", "model", "--length", "5000"), 2, "trained range"),
        (("a person smiles", "--checkpoint", str(tmp_path / "none.pt")), 2, "not found"),
    ]:
        r = cli("text2face", *args, "--out", str(tmp_path / "bad"), "--no-video")
        assert r.returncode == code and msg in r.stderr and "Traceback" not in r.stderr, r.stderr


def test_held_out_errors_get_intervals_over_videos_per_split():
    """Per split, a mean per-window error with a 95 % interval that resamples whole videos (and the counts);
    a split with one video has nothing to resample."""
    from anima.eval.text2face.run import over_videos
    from anima.text2face.data import Item

    rng = np.random.default_rng(0)
    items, x = [], []
    videos = [("a", "val", 2.0), ("b", "val", 3.0), ("c", "test", 2.5), ("d", "test", 4.0), ("e", "test", 1.0)]
    for v, split, level in videos:
        for _ in range(4):
            items.append(Item(np.zeros((2, 56)), "", [], v, [], v, split))
            x.append(level + 0.01 * rng.standard_normal())
    r = over_videos(np.array(x), items)
    assert set(r) == {"val", "test", "all"}
    assert (r["val"]["videos"], r["val"]["windows"], r["test"]["videos"], r["all"]["windows"]) == (2, 8, 3, 20)
    lo, hi = r["test"]["ci95_over_videos"]
    assert lo < r["test"]["mean"] < hi and lo < 1.6 and hi > 3.3  # the spread between videos, not within
    one = over_videos(np.array(x[:4]), items[:4])["val"]
    assert one["ci95_over_videos"][0] == one["ci95_over_videos"][1] == pytest.approx(one["mean"], abs=1e-4)
    # each video's own mean, and the lowest and highest of them
    assert set(r["test"]["per_video"]) == {"c", "d", "e"}
    assert r["test"]["min_video"] == pytest.approx(1.0, abs=0.02)
    assert r["test"]["max_video"] == pytest.approx(4.0, abs=0.02)


def test_the_text2face_row_states_its_mae_over_videos_and_the_step_choices_spread():
    """The headline MAE of the tables is the mean over the test windows with its interval over test videos and
    the per-video range, not the sampling repetitions' spread; a step choice made on one training run says its
    spread beside it: the grid's range, and which step counts its interval over validation videos cannot tell
    apart from it."""
    from anima.eval.text2face.run import _row, _spread, step_spread

    over = {
        "test": {"mean": 3.37, "ci95_over_videos": [2.79, 4.05], "min_video": 1.9, "max_video": 5.2},
        "val": {"mean": 2.28, "ci95_over_videos": [2.05, 2.6]},
    }
    r = {
        "mae_mm": {"mean": 3.368, "ci95": 0.008},
        "mae_mm_over_videos": over,
        "rmse_mm": {"mean": 4.6, "ci95": 0.01},
        "diversity_mm": {"mean": 1.8, "ci95": 0.07},
        "r_precision": [0.02, 0.06, 0.08],
    }
    row = _row("ours", r)
    assert row.split(" | ")[1] == "3.37 [2.79, 4.05] (1.90-5.20)" and "0.008" not in row
    choice = {
        "value": 1000,
        "validation_mae_mm": {"250": 2.5, "500": 3.09, "1000": 2.29, "2000": 3.07},
        "validation_over_videos": {"1000": {"ci95_over_videos": [2.05, 2.6]}},
    }
    sp = step_spread(choice)
    assert sp["validation_mae_range_mm"] == [2.29, 3.09] and sp["steps_inside_chosen_interval"] == [250, 1000]
    assert "2.29-3.09" in _spread(choice) and "inside it: 250 steps" in _spread(choice)
    assert _spread({"value": 250, "validation_mae_mm": {"250": 2.5}}) == "validation MAE 2.50-2.50 over the grid"


def test_headline_metrics_are_on_the_test_windows_and_validation_is_apart():
    """MAE, RMSE and Diversity in the headline come from the test windows only; the validation
    windows (which chose the steps) are reported apart. A method exact on test and off on validation shows it."""
    from anima.eval.text2face.run import EVAL_LEN, Method, score
    from anima.text2face.data import FaceGeometry, Item

    rng = np.random.default_rng(0)
    items = []
    for k in range(8):
        m = np.zeros((EVAL_LEN, 56), np.float32)
        m[:, :53] = rng.uniform(0, 0.5, 53)
        items.append(Item(m, "", [], f"v{k % 4}", [], f"v{k % 4}", "test" if k % 4 < 2 else "val"))
    real = np.stack([it.motion for it in items])
    test = np.array([it.split == "test" for it in items])

    def exact_on_test(E, n, seed):
        out = real.copy()
        out[~test, :, :53] = 0.0
        return out

    r = score(Method("probe", exact_on_test), items, np.zeros((8, 1, 4)), FaceGeometry(), 2, False)
    assert r["mae_mm"]["mean"] == 0 and r["rmse_mm"]["mean"] == 0
    assert r["validation"]["mae_mm"]["mean"] > 0.1
    assert r["mae_mm_over_videos"]["test"]["mean"] == 0 and r["mae_mm_over_videos"]["val"]["mean"] > 0.1


# ---- the timeline method: prompts read as events, made from captured segments ------------------


def test_prompt_parser_reads_order_counts_intensity_side_and_reports_unknown_words():
    from anima.text2face.prompt import parse

    p = parse("She smiles slightly, then blinks twice")
    assert [(e.attribute, e.count, e.clause) for e in p.events] == [("smile", 1, 0), ("blink", 2, 1)]
    assert p.events[0].intensity < 1.0 and not p.unknown
    p = parse("he raises his left eyebrow while talking")
    assert {e.attribute for e in p.events} == {"raise eyebrows", "talk"} and p.n_clauses == 1
    assert p.events[0].side == "left"
    p = parse("xyzzy blorf")
    assert not p.events and p.unknown == ["xyzzy", "blorf"] and any("neutral" in n for n in p.notes)
    p = parse("eyes closed while winking")  # cannot co-occur: the wink follows
    assert [e.attribute for e in p.events] == ["close eyes", "blink"] and p.n_clauses == 2 and p.notes
    # negation excludes the event it governs (and says so); quantities before the noun count
    p = parse("He talks without smiling.")
    assert [e.attribute for e in p.events] == ["talk"] and p.excluded == ["smile ('smiling')"] and p.notes
    p = parse("She doesn't blink at all.")
    assert not p.events and p.excluded and not p.unknown
    for text, n in (("A couple of quick blinks.", 2), ("a few nods", 3), ("several blinks", 4), ("two winks", 2),
                    ("she smiles a couple of times", 2), ("he blinks a few times", 3)):  # fmt: skip
        p = parse(text)
        assert [e.count for e in p.events] == [n] and not p.unknown, text


def test_prompt_parser_agrees_with_every_annotated_prompt_of_the_suite():
    """The 114 prompts of the suite: the parser finds each prompt's events in its clauses with its counts."""
    from anima.eval.text2face.prompts import load_suite
    from anima.text2face.prompt import parse

    rows = load_suite()
    assert len(rows) >= 100
    for r in rows:
        p = parse(r["prompt"])
        got = [sorted((e.attribute, e.count) for e in p.events if e.clause == c) for c in range(p.n_clauses)]
        want = [sorted((e["attribute"], e["count"]) for e in c) for c in r["clauses"]]
        if r.get("emotion"):
            want = [[("surprise" if r["emotion"] == "surprised" else r["emotion"], 1)]]
        if r["kind"] == "neutral":
            want = [[("neutral", 1)]]
        assert got == want, r["prompt"]


def test_paraphrase_outside_the_lexicon_goes_through_the_sentence_encoder(encoder):
    from anima.text2face.prompt import parse

    p = parse("her eyelids flicker shut for an instant", encoder)
    assert [e.attribute for e in p.events] == ["blink"] and p.paraphrased[0]["as"] == "blink"


def test_expression_names_of_the_contract_are_the_face_models(face_model):
    from anima.core.contract import EXPR_NAMES

    assert list(EXPR_NAMES) == list(face_model.expr_names)


def test_the_timeline_library_holds_only_training_videos(ds):
    """The prompt suites' timeline method and retrieval draw on the dataset's training clips only (no
    statistic of a held-out video enters a method it is judged by): by default the library is the training
    split, and asking for a split with no clip is refused."""
    from anima.dataset.windows import read_clips
    from anima.errors import InputError
    from anima.text2face.compose import Library

    clips = read_clips(ds)
    train = [c.clip_id for c in clips if c.split == "train"]
    assert train and Library.from_dataset(ds).sources == train
    empty = {"train", "val", "test"} - {c.split for c in clips}
    for side in empty:
        with pytest.raises(InputError):
            Library.from_dataset(ds, splits=(side,))


def test_timeline_method_on_real_clips_follows_order_and_counts(ds):
    """Segments from the captured d0/d6 clips: "smiles, then blinks twice" reads back with the detectors as a
    smile followed by two blinks; other prompts and other seeds give other motion; a prompt too long for the
    clip is refused with the length it needs; nothing recognised gives the still, neutral face."""
    from anima.text2face.compose import Library, compose, detect_motion
    from anima.text2face.prompt import parse

    lib = Library.from_dataset(ds, splits=("train", "val", "test"))
    assert lib.counts["smile"] > 0 and lib.counts["blink"] > 0
    m, rec = compose(parse("she smiles, then blinks twice"), lib, 120, seed=0)
    assert m.shape == (120, 56) and np.isfinite(m).all() and m[:, :53].min() >= 0 and m[:, :53].max() <= 1
    ev = detect_motion(m)
    smiles = [s for a, s, _ in ev if a == "smile"]
    blinks = [s for a, s, _ in ev if a == "blink"]
    assert rec["all_found"] and smiles and len(blinks) == 2 and min(smiles) < min(blinks), ev
    assert rec["events"][0]["from"][0]["clip"] in lib.sources
    m2, _ = compose(parse("she smiles, then blinks twice"), lib, 120, seed=0)
    np.testing.assert_array_equal(m, m2)  # seeded
    m3, _ = compose(parse("a person blinks"), lib, 120, seed=0)
    assert np.abs(m - m3).max() > 0.1
    long = parse("she blinks five times, then smiles, then blinks five times")
    with pytest.raises(InputError, match="at least"):
        compose(long, lib, 40)
    # with no length asked, the clip grows to hold every event (3 s at least)
    m4, rec = compose(long, lib, None, seed=0)
    assert len(m4) > 90 and rec["length"] == "fitted to the events" and rec["all_found"], rec["detected"]
    assert len(compose(parse("a person blinks"), lib, None)[0]) == 90
    still, rec = compose(parse("xyzzy"), lib, 60)
    assert np.ptp(still, axis=0).max() == 0 and rec["events"] == []


def test_text2face_timeline_command_and_its_refusals(ds, tmp_path, cli):
    out = tmp_path / "tl"
    r = cli("text2face", "a woman smiles, then blinks", "--db", ds, "--out", out, "--no-video", "--json")
    assert r.returncode == 0, r.stderr[-2000:]
    info = json.loads((out / "info.json").read_text())
    assert info["method"] == "timeline" and [e["attribute"] for e in info["understood"]] == ["smile", "blink"]
    assert (out / "motion.npz").stat().st_size > 0 and (out / "arkit.csv").stat().st_size > 0
    r = cli("text2face", "qwerty", "--db", ds, "--out", tmp_path / "q", "--no-video")
    assert r.returncode == 0 and "not understood: qwerty" in r.stderr
    for args, msg in [
        (("a person smiles", "--with-builtin"), "give --db too"),
        (("a person smiles", "--method", "model", "--db", str(ds)), "--db and --library are for the timeline"),
        (("a person smiles", "--length", "20000"), "at most 18000"),
        (("a person nods five times", "--db", str(ds), "--length", "30"), "at least"),
        (("a person smiles", "--db", str(tmp_path / "nods")), "no dataset"),
    ]:
        r = cli("text2face", *args, "--out", str(tmp_path / "bad"), "--no-video")
        assert r.returncode == 2 and msg in r.stderr and "Traceback" not in r.stderr, r.stderr


def test_prompt_suite_scores_follow_their_definitions():
    """The scorer on hand-made motions: a blink where one is asked is a hit, a smile where none is asked a
    false alarm, and two prompts with the same motion are counted as such."""
    from anima.eval.text2face.prompts import score_runs

    rows = [
        {"prompt": "blink", "kind": "single", "clauses": [[{"attribute": "blink", "count": 1}]]},
        {"prompt": "smile", "kind": "single", "clauses": [[{"attribute": "smile", "count": 1}]]},
        {"prompt": "neutral", "kind": "neutral", "clauses": []},
    ]
    still = np.zeros((90, 56), np.float32)
    blink = still.copy()
    blink[40:45, 10:12] = 1.0  # eyeBlink_L, eyeBlink_R
    runs = {0: [blink], 1: [still], 2: [still]}
    r = score_runs(rows, runs, {})
    assert r["per_attribute"]["blink"]["recall"] == 1.0 and r["per_attribute"]["smile"]["recall"] == 0.0
    assert r["per_attribute"]["blink"]["false_alarm"] == 0.0
    assert r["distinct"]["pairs"] == 3 and r["distinct"]["same_motion_pairs"] == 1


def test_a_bad_prompt_suite_is_refused_in_one_line(tmp_path, ds, cli):
    row = {"prompt": "a person smiles", "seconds": 3, "kind": "single", "clauses": [[{"attribute": "smile"}]]}
    cases = [
        ("missing.json", None, "not found"),
        ("garbage.json", "garbage{", "not valid JSON"),
        ("clauses.json", {"prompts": [row | {"clauses": 5}]}, "clauses"),
        ("count.json", {"prompts": [row | {"clauses": [[{"attribute": "smile", "count": "x"}]]}]}, "count"),
        ("attr.json", {"prompts": [row | {"clauses": [[{"attribute": "dance"}]]}]}, "unknown attribute"),
        ("seconds.json", {"prompts": [{k: v for k, v in row.items() if k != "seconds"}]}, "seconds"),
    ]
    for name, content, msg in cases:
        f = tmp_path / name
        if content is not None:
            f.write_text(content if isinstance(content, str) else json.dumps(content))
        r = cli("eval", "text2face", ds, "--prompts", f)
        assert r.returncode == 2 and msg in r.stderr and "Traceback" not in r.stderr, (name, r.stderr)
