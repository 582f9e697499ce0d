"""The gesture evaluation holds out whole speakers: no k-NN database, training set or nested choice of a setting
ever holds a window of the speaker it judges (``anima eval gesture``'s folds)."""

import numpy as np

from anima.eval.gesture.metrics import group_of, inner_validation, speaker_folds, speaker_of

PATS = "gesture-video/pats-crops/"
VIDEOS = [PATS + n for n in ("oliver1_gt.mp4", "oliver2_gt.mp4", "oliver3_gt.mp4", "seth1_gt.mp4", "seth3_gt.mp4")]
VIDEOS += [PATS + n for n in ("noah1_gt.mp4", "chem1_gt.mp4", "chem2_gt.mp4", "almaram1_gt.mp4", "angelica2_gt.mp4")]


def test_inner_validation_holds_out_whole_speakers():
    """Every outer fold's inner validation (where the refiner's smoothing and the generator's adversarial weight
    are chosen) is whole speakers of the fold's training speakers: none of the held-out fold's, none of the inner
    training's; one speaker's windows (--speaker) split by video instead."""
    fold_of = speaker_folds(VIDEOS, 3)
    for f in range(3):
        held = {v for v in VIDEOS if fold_of[v] == f}
        train = sorted(set(VIDEOS) - held)
        val = inner_validation(train)
        inner_train = set(train) - val
        assert val and inner_train
        val_speakers = {speaker_of(v) for v in val}
        assert not val_speakers & {speaker_of(v) for v in held}
        assert not val_speakers & {speaker_of(v) for v in inner_train}  # a speaker's every video on one side
        assert not {speaker_of(v) for v in inner_train} & {speaker_of(v) for v in held}
    # one training speaker: no inner split (the caller keeps its default), never a split of that speaker's videos
    olivers = VIDEOS[:3]
    assert inner_validation(olivers) == set(olivers)
    # one speaker's person-specific protocol: every third video
    assert inner_validation(olivers, by_speaker=False) == {olivers[0]}
    assert group_of(olivers[1]) == "oliver" and group_of(olivers[1], False) == olivers[1]


class _Spy:
    """Wraps a search or a training function and records what each call was given."""

    def __init__(self, fn):
        self.fn, self.calls = fn, []

    def __call__(self, *a, **kw):
        self.calls.append((a, kw))
        return self.fn(*a, **kw)


def _query_speaker(db, F) -> str:
    (i,) = [i for i in range(db.M) if np.array_equal(db.F[i], F)][:1]
    return speaker_of(db.source[i][0])


def _database_speakers(sub) -> set:
    return {speaker_of(s) for s, _ in sub.source}


def test_knn_rows_search_without_the_query_speaker(db, monkeypatch):
    """Leave-one-speaker-out: every k-NN search of a window (plain and controlled) is in a database without any
    of its speaker's videos (oliver has two videos here: leaving one video out would keep the other)."""
    import anima.eval.gesture.run as run

    spy = _Spy(run.search)
    monkeypatch.setattr(run, "search", spy)
    res, _, kept = run.knn_rows(db, (0, 1), seed_rule=False)
    assert {speaker_of(s) for s, _ in db.source} == {"oliver", "seth"}
    assert len({s for s, _ in db.source if speaker_of(s) == "oliver"}) == 2
    assert len(res["l1_cm"]) == db.M and spy.calls
    for (sub, F, *_), _ in spy.calls:
        assert _query_speaker(db, F) not in _database_speakers(sub)
    assert [h["group"] for h in kept["held_out"]] == ["oliver", "seth"]
    for h in kept["held_out"]:
        assert h["group"] not in {speaker_of(v) for v in h["database_videos"]}
    assert run.knn_protocol(len(kept["held_out"]), True).startswith("leave-one-speaker-out, 2 folds")
    # one speaker's windows (--speaker): leave-one-video-out within the speaker
    olv = db.subset([i for i, (s, _) in enumerate(db.source) if speaker_of(s) == "oliver"])
    spy.calls.clear()
    _, _, kept = run.knn_rows(olv, (0,), seed_rule=False, by_speaker=False)
    assert len(kept["held_out"]) == 2
    for (sub, F, *_), _ in spy.calls:
        (i,) = [i for i in range(olv.M) if np.array_equal(olv.F[i], F)][:1]
        assert olv.source[i][0] not in {s for s, _ in sub.source}


def test_refiner_inputs_never_search_the_held_out_or_own_speaker(db, monkeypatch):
    """A refiner fold's databases hold no held-out speaker's window, and a training pair's k-NN input is searched
    without its own window's speaker, as the held-out windows' are (no pair is left when one speaker trains)."""
    import anima.eval.gesture.learned as learned
    from anima.gesture.refine import RefinerTrainConfig

    spy = _Spy(learned.search)
    monkeypatch.setattr(learned, "search", spy)
    cfg = RefinerTrainConfig(pairs_per_window=2)
    rng = np.random.default_rng(0)
    inp = learned.fold_inputs(db, set(), (0,), [], cfg, rng, 0, True)  # every video trains: pairs both ways
    assert inp["pairs"] is not None and inp["own_group_in_pairs"] == 0
    pair_speakers = {speaker_of(db.source[i][0]) for i in inp["pairs"][3]}
    assert pair_speakers == {"oliver", "seth"}
    for (sub, F, *_), _ in spy.calls:
        assert _query_speaker(db, F) not in _database_speakers(sub)
    seth = {s for s, _ in db.source if speaker_of(s) == "seth"}
    spy.calls.clear()
    inp = learned.fold_inputs(db, seth, (0, 1), ["left_wrist_height>=p85"], cfg, rng, 0, True)
    assert inp["pairs"] is None  # oliver alone trains: no pair without oliver in its database
    assert inp["test"] and all(db.source[i][0] in seth for i in inp["test"])
    assert spy.calls and all(_database_speakers(sub) == {"oliver"} for (sub, *_), _ in spy.calls)
    assert not inp["used_videos"] & seth


def test_adversarial_weight_is_chosen_on_inner_validation_speakers(ds, db, monkeypatch):
    """The nested choice of the §4.4 generator's adversarial weight: its validation windows are whole speakers'
    (here oliver's two videos), and the generators and the FGD network it trains never see them."""
    import anima.eval.gesture.learned as learned
    from anima.dataset.windows import read_windows
    from anima.gesture.generator import GeneratorTrainConfig

    w = read_windows(ds)
    row = {w.speech[n].tobytes(): n for n in range(w.n)}
    gen_spy, fgd_spy = _Spy(learned.train_generator), _Spy(learned.train_fgd)
    monkeypatch.setattr(learned, "train_generator", gen_spy)
    monkeypatch.setattr(learned, "train_fgd", fgd_spy)
    key = {(s, round(st, 3)): n for n, (s, st) in enumerate(zip(w.source, w.start_s))}
    n_to_i = {key[(s, round(st, 3))]: i for i, (s, st) in enumerate(db.source) if (s, round(st, 3)) in key}
    tr = np.ones(w.n, bool)  # no outer fold held out: oliver and seth train, feifeili's face too
    cfg = GeneratorTrainConfig(steps=2)
    choice = learned.choose_adv_weight(w, tr, n_to_i, db, cfg, (0.1, 1.0), False, 0, fgd_steps=2)
    assert choice["validation_speakers"] == ["oliver"] and choice["validation_videos"] == 2
    assert len(gen_spy.calls) == 2 and len(fgd_spy.calls) == 1
    for (speech, *_), _ in gen_spy.calls:
        seen = {speaker_of(w.source[row[x.tobytes()]]) for x in speech}
        assert seen == {"seth", "feifeili"}  # never a window of the validation speaker
    ((G, *_), _) = fgd_spy.calls[0]
    body = {db.G[i].tobytes(): speaker_of(db.source[i][0]) for i in range(db.M)}
    assert {body[g.reshape(db.G.shape[1:]).tobytes()] for g in G} == {"seth"}
