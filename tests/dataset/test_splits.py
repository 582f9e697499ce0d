"""Splits by source, independent of where the data sits: the same videos under two folders get the
same splits; on the shared data no source or recording sits on two sides, and the test side is large enough."""

import collections
import shutil
from pathlib import Path

from anima.dataset import splits
from anima.dataset.build import expand_videos
from anima.io.assets import asset, data_root

SOME = [
    "emotion-clips/crema-d/1001_DFA_ANG_XX.flv",
    "emotion-clips/crema-d/1001_DFA_HAP_XX.flv",
    "styletalk-samples/samples/source_video/video/Obama_clip1.mp4",
    "styletalk-samples/samples/style_clips/video/Obama_clip3.mp4",
    "videoretalking-examples/examples/face/3.mp4",
    "liveportrait-examples/assets/examples/driving/d19.mp4",
]


def _copy(dst_root, rels):
    for r in rels:
        d = dst_root / r
        d.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(asset(r), d)
    return [dst_root / r for r in rels]


def test_the_same_videos_under_two_folders_get_the_same_splits(tmp_path):
    a = _copy(tmp_path / "one" / "data", SOME)
    b = _copy(tmp_path / "elsewhere" / "deeper" / "copy", SOME)
    ta = splits.table(a, tmp_path / "one" / "data")
    tb = splits.table(b, tmp_path / "elsewhere" / "deeper" / "copy")
    ref = splits.table([asset(r) for r in SOME])
    strip = lambda t: [(r["key_path"], r["source"], r["group"], r["split"]) for r in t.values()]
    assert strip(ta) == strip(tb) == strip(ref)
    # outside any data root the key is <folder>/<file>: moving the folder changes nothing either
    c = _copy(tmp_path / "x", ["videoretalking-examples/examples/face/3.mp4"])
    d = _copy(tmp_path / "y" / "z", ["videoretalking-examples/examples/face/3.mp4"])
    assert strip(splits.table(c, tmp_path / "nowhere")) == strip(splits.table(d, tmp_path / "nowhere2"))
    assert splits.key_path(c[0], tmp_path / "nowhere") == "face/3.mp4"
    # one actor's clips share a source; a byte-identical copy joins its original's group whatever its name
    assert len({r["source"] for r in ta.values() if "crema-d" in r["key_path"]}) == 1
    e = tmp_path / "copies" / "renamed_take.mp4"
    e.parent.mkdir()
    shutil.copyfile(asset(SOME[4]), e)
    t = splits.table([asset(SOME[4]), e])
    assert len({r["group"] for r in t.values()}) == 1 and len({r["source"] for r in t.values()}) == 2


def test_no_source_or_recording_on_two_sides_of_the_shared_data_and_a_test_side_worth_reporting(shared_split_table):
    videos = expand_videos([str(data_root())])
    t = shared_split_table
    assert sorted(t) == sorted(str(v.resolve()) for v in videos)
    sides = collections.defaultdict(set)
    for r in t.values():
        sides[r["source"]].add(r["split"])
        sides["group " + r["group"]].add(r["split"])
    assert all(len(s) == 1 for s in sides.values()), {k: v for k, v in sides.items() if len(v) > 1}
    n = collections.Counter(r["split"] for r in t.values())
    test_groups = {r["group"] for r in t.values() if r["split"] == "test"}
    assert n["test"] >= 0.15 * len(videos) and len(test_groups) >= 6, (n, test_groups)
    assert n["val"] >= 5 and n["train"] >= 0.6 * len(videos), n
    # the declared source table is complete: content and thumbnail grouping merge nothing beyond it, so a build
    # of any subset of the shared data gives each video the split the full build gives it
    assert all(r["group"] == r["source"] for r in t.values()), [r for r in t.values() if r["group"] != r["source"]]
    assert all(splits.split_for(p) == r["split"] for p, r in t.items())
    # the cases an audit found on two sides: one CREMA-D actor, Obama in two corpora, one StyleTalk recording,
    # one interview re-cropped in another corpus
    by = {r["key_path"]: r for r in t.values()}
    for group in (
        ["emotion-clips/crema-d/1001_DFA_ANG_XX.flv", "emotion-clips/crema-d/1001_DFA_SAD_XX.flv"],
        ["talking-heads-extra/uncrop_Obama.mp4", "styletalk-samples/samples/source_video/video/Obama_clip1.mp4"],
        [
            "styletalk-samples/samples/style_clips/video/furious_talk2_clip1.mp4",
            "styletalk-samples/samples/style_clips/video/furious_talk2_clip7.mp4",
        ],
        [
            "talking-heads-extra/expression_source.mp4",
            "styletalk-samples/samples/style_clips/video/happyenglish_clip1.mp4",
        ],
        ["talking-heads-extra/pose_source1.mp4", "videoretalking-examples/examples/face/3.mp4"],
    ):
        assert len({by[k]["source"] for k in group}) == 1, group


def test_one_recording_under_two_names_is_found_by_its_face_crops(tmp_path):
    """An interview and its re-cropped copy in another corpus (the audit's pair), renamed and moved
    outside any data root so no declared rule or file hash can tie them: the face crops group them, the row
    says why and the build's report says so; another speaker stays apart."""
    from anima.dataset.build import content_groups

    a = _copy(tmp_path / "interviews", ["talking-heads-extra/pose_source1.mp4"])[0].rename(tmp_path / "anchor.mp4")
    b = _copy(tmp_path / "other", ["videoretalking-examples/examples/face/3.mp4"])[0]
    c = _copy(tmp_path / "more", ["gesture-video/pats-crops/oliver1_gt.mp4"])[0]
    t = splits.table([a, b, c], tmp_path / "nowhere")
    ra, rb, rc = (t[str(p.resolve())] for p in (a, b, c))
    assert ra["source"] != rb["source"] and ra["group"] == rb["group"] and ra["split"] == rb["split"]
    assert "face crops" in ra["grouped_with"][rb["source"]] and rc["group"] == rc["source"] and not rc["grouped_with"]
    lines = content_groups([a, b, c], t)
    assert len(lines) == 2 and all("one recording" in line for line in lines), lines
    fa, fb, fc = (splits.face_hashes(p) for p in (a, b, c))
    assert len(fa) >= 10 and splits.same_recording(fa, fb) and not splits.same_recording(fa, fc)


def _cut(src, dst, seconds=4.0):
    """The first ``seconds`` of a video, its streams copied (small files, the same bytes for every copy)."""
    import subprocess

    from anima.io.video import FFMPEG

    dst.parent.mkdir(parents=True, exist_ok=True)
    cmd = [FFMPEG, "-v", "error", "-y", "-i", str(src), "-t", str(seconds), "-c", "copy", str(dst)]
    subprocess.run(cmd, check=True)
    return dst


def test_videos_outside_the_data_root_land_by_content_not_by_their_folders_name(tmp_path):
    """The same three talking clips (their first 4 s) copied into folders ``a/`` and ``b/c/`` (outside the data
    root) and split twice: each clip lands on the same side both times. Names still decide what belongs together
    (the folder a speaker hint), the side a group lands on is its first video's content (by file name): before,
    the folder's name was in the key and moved andrew_clip_1 from train to val, reagan_clip1 from val to test.
    Another take of a speaker added later joins its group and moves nothing."""
    from anima.io.outdir import sha256

    names = ("andrew_clip_1", "reagan_clip1", "Obama_clip1", "andrew_clip_2")
    cut = {n: _cut(asset(f"styletalk-samples/samples/source_video/video/{n}.mp4"), tmp_path / "cut" / f"{n}.mp4")
           for n in names}  # fmt: skip
    assert all(p.stat().st_size < 150_000 for p in cut.values())

    def build(folder, which):
        folder.mkdir(parents=True)
        paths = [shutil.copyfile(cut[n], folder / f"{n}.mp4") for n in which]
        return {Path(p).stem: r for p, r in splits.table(paths, tmp_path / "nowhere").items()}

    a, bc = build(tmp_path / "a", names[:3]), build(tmp_path / "b" / "c", names[:3])
    assert {n: r["split"] for n, r in a.items()} == {n: r["split"] for n, r in bc.items()}
    assert a["andrew_clip_1"]["group"] == "a:andrew" and bc["andrew_clip_1"]["group"] == "c:andrew"
    for n, r in a.items():  # the side is the content's: a hash of the clip's sha256, no name in it
        assert r["split"] == splits.split_of_group(f"content:{sha256(cut[n])}"), (n, r)
    # a later take of the same speaker in the folder: one group by name, the group keeps its first video's side
    d = build(tmp_path / "speaker_x", names)
    assert d["andrew_clip_2"]["group"] == d["andrew_clip_1"]["group"] == "speaker_x:andrew"
    assert {n: r["split"] for n, r in d.items()} == {n: a[n]["split"] for n in names[:3]} | {
        "andrew_clip_2": a["andrew_clip_1"]["split"]
    }
