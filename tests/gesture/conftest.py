"""A dataset built once from real clips for the gesture tests: three PATS gesture clips (body, hands and
speech) and one StyleTalk talking head whose speech ships as a separate WAV (face-only windows)."""

import pytest

from anima.io.assets import asset

CLIPS = [
    "gesture-video/pats-crops/oliver1_gt.mp4",
    "gesture-video/pats-crops/oliver3_gt.mp4",
    "gesture-video/pats-crops/seth3_gt.mp4",
    "styletalk-samples/samples/source_video/video/feifeili_clip3.mp4",
]


@pytest.fixture(scope="session")
def ds(tmp_path_factory, cli):
    out = tmp_path_factory.mktemp("gds") / "ds"
    r = cli("dataset", "build", *[asset(c) for c in CLIPS], "--out", out, "--min-len", "2", "--quiet", "--json")
    assert r.returncode == 0, r.stderr[-2000:]
    return out


@pytest.fixture(scope="session")
def db(ds):
    from anima.gesture.database import from_dataset

    return from_dataset(ds, None)
