"""The one checkpoint format: every model's checkpoint round-trips, and no file a user passes can run code.

A crafted checkpoint (a pickle whose loading would create a file) goes through every command that reads a
checkpoint; each refuses it with one line and exit code 4, and the file is never created."""

import os
import shutil

import numpy as np
import pytest
import torch

from anima.errors import CheckpointError, InputError
from anima.io.assets import asset
from anima.io.checkpoint import load_checkpoint, save_checkpoint
from anima.text2face.generate import SHIPPED

SPEECH = "videoretalking-examples/examples/audio/1.wav"


class _Evil:
    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


@pytest.fixture()
def evil(tmp_path):
    marker = tmp_path / "pwned"
    path = tmp_path / "evil.pt"
    torch.save(
        {
            "format": "anima.checkpoint",
            "envelope": 1,
            "kind": "pose_lifter",
            "version": 2,
            "meta": "{}",
            "tensors": {"state": {"w": _Evil(marker)}},
        },
        path,
    )
    return path, marker


def test_round_trip_and_errors(tmp_path):
    net = torch.nn.Linear(3, 2)
    p = save_checkpoint(
        tmp_path / "a.pt",
        "demo",
        3,
        {"width": 3, "tuple": (1, 2)},
        {"state": net.state_dict()},
        {"loss": np.float32(0.5), "nan": float("nan")},
    )
    ck = load_checkpoint(p, "demo", 3)
    assert ck.config == {"width": 3, "tuple": [1, 2]} and ck.info == {"loss": 0.5, "nan": None}
    assert torch.equal(ck.state["weight"], net.weight.detach())
    with pytest.raises(CheckpointError, match="'demo' checkpoint, expected 'other'"):
        load_checkpoint(p, "other", 3)
    with pytest.raises(CheckpointError, match="version 3, this anima reads 4"):
        load_checkpoint(p, "demo", 4)
    with pytest.raises(InputError, match="not found"):
        load_checkpoint(tmp_path / "missing.pt", "demo", 3)
    (tmp_path / "cut.pt").write_bytes(p.read_bytes()[: p.stat().st_size // 2])
    with pytest.raises(CheckpointError):
        load_checkpoint(tmp_path / "cut.pt", "demo", 3)
    assert not list(tmp_path.glob(".*anima-tmp*"))  # the writer left no temporary file


def test_a_crafted_pickle_runs_nothing(evil):
    path, marker = evil
    with pytest.raises(CheckpointError, match="would run code"):
        load_checkpoint(path, "pose_lifter", 2)
    assert not marker.exists()


@pytest.mark.parametrize(
    "how",
    ["capture", "eval_pose", "train_pose", "default_lifter", "refiner", "generator", "text2face", "eval_text2face"],
)
def test_every_command_refuses_a_crafted_checkpoint(evil, tmp_path, cli, how, d0_path):
    path, marker = evil
    env = dict(os.environ)
    speech = str(asset(SPEECH))
    args = {
        "capture": ["capture", d0_path, "--out", tmp_path / "c", "--body-3d", "lifter", "--pose-model", path],
        "eval_pose": ["eval", "pose", "--model", path, "--json"],
        "train_pose": ["train", "pose", "--out", path, "--steps", "1", "--quiet"],
        "default_lifter": ["eval", "pose", "--json"],
        "refiner": ["gesture", speech, "--db", tmp_path / "nodb", "--refiner", path, "--out", tmp_path / "g"],
        "generator": ["gesture", speech, "--generator", path, "--out", tmp_path / "g"],
        "text2face": ["text2face", "a woman smiles", "--checkpoint", path, "--out", tmp_path / "t"],
        "eval_text2face": ["eval", "text2face", tmp_path / "ds", "--checkpoint", path, "--work", tmp_path / "w"],
    }[how]
    (tmp_path / "ds").mkdir()  # a dataset folder (its shards are read after the checkpoint)
    (tmp_path / "ds" / "manifest.json").write_text('{"schema": "anima.dataset", "version": 1}')
    if how == "default_lifter":
        home = tmp_path / "home"
        (home / "models").mkdir(parents=True)
        shutil.copy(path, home / "models" / "pose_lifter.pt")
        env["ANIMA_HOME"] = str(home)
    r = cli(*args, env=env, timeout=300)
    assert r.returncode == 4, r.stderr
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("anima: error:"), r.stderr
    assert not marker.exists()


def test_a_checkpoint_of_another_kind_version_or_cut_short(tmp_path, cli):
    other = save_checkpoint(tmp_path / "ref.pt", "gesture_refiner", 2, {}, {"state": {}})
    old = torch.load(SHIPPED, weights_only=True)
    old["version"] = 99
    torch.save(old, tmp_path / "v99.pt")
    (tmp_path / "cut.pt").write_bytes(SHIPPED.read_bytes()[:100_000])
    for ck, msg in (
        (other, "'gesture_refiner' checkpoint"),
        (tmp_path / "v99.pt", "version 99"),
        (tmp_path / "cut.pt", "not a loadable"),
    ):
        r = cli("text2face", "a woman smiles", "--checkpoint", ck, "--out", tmp_path / "o", "--no-video")
        assert r.returncode == 4 and msg in r.stderr and r.stderr.count("\n") == 1, r.stderr
