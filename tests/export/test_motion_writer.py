"""The one motion writer renders its videos side by side: every video is made and identical to a serial
render of the same real capture, and a failing render neither stops the others nor leaves a file behind."""

import threading

import numpy as np
import pytest

from anima.export.motion import run_renders
from anima.io.assets import asset
from anima.io.video import read_video

D0 = "liveportrait-examples/assets/examples/driving/d0.mp4"


@pytest.fixture(scope="module")
def seq(tmp_path_factory):
    from anima.capture.config import CaptureConfig
    from anima.capture.pipeline import capture_video

    return capture_video(str(asset(D0)), CaptureConfig(max_frames=24), progress=False)


def test_parallel_renders_equal_serial_ones(seq, tmp_path):
    from anima.render.videos import render_videos

    src = str(asset(D0))
    threads = set()

    def job(name):
        def call():
            threads.add(threading.get_ident())
            render_videos(seq, src, tmp_path / f"{name}_o.mp4", tmp_path / f"{name}_m.mp4", progress=False)

        return call

    run_renders([({"a": tmp_path / "a_o.mp4"}, job("a")), ({"b": tmp_path / "b_o.mp4"}, job("b"))])
    assert len(threads) == 2  # really on two threads
    run_renders([({"s": tmp_path / "s_o.mp4"}, job("s"))])  # one job: serial, in this thread
    s, _ = read_video(tmp_path / "s_o.mp4")
    for name in ("a", "b"):
        v, _ = read_video(tmp_path / f"{name}_o.mp4")
        assert v.shape == s.shape == (24, 512, 512, 3) and np.array_equal(v, s)


def test_a_failing_render_does_not_stop_the_others(seq, tmp_path):
    from anima.io.video import VideoWriter

    def good():
        with VideoWriter(tmp_path / "good.mp4", 25, (64, 64)) as w:
            for i in range(10):
                w.write(np.full((64, 64, 3), 10 * i, np.uint8))

    def bad():
        with VideoWriter(tmp_path / "bad.mp4", 25, (64, 64)) as w:
            w.write(np.zeros((64, 64, 3), np.uint8))
            raise RuntimeError("render failed")

    with pytest.raises(RuntimeError, match="render failed"):
        run_renders([({"b": tmp_path / "bad.mp4"}, bad), ({"g": tmp_path / "good.mp4"}, good)])
    assert len(read_video(tmp_path / "good.mp4")[0]) == 10
    assert not (tmp_path / "bad.mp4").exists() and [p.name for p in tmp_path.iterdir()] == ["good.mp4"]


def test_ordered_map_keeps_order_bounds_work_ahead_and_raises():
    import time

    from anima.render.parallel import ordered_map

    started = []

    def slow_square(i):
        started.append(i)
        time.sleep(0.01 * ((7 * i) % 3))  # finish out of order
        return i * i

    gen = ordered_map(slow_square, range(40), workers=2, ahead=2)
    first = [next(gen) for _ in range(3)]
    assert first == [0, 1, 4] and len(started) <= 3 + 2 * 2  # never more than 4 frames ahead
    assert first + list(gen) == [i * i for i in range(40)]

    def boom(i):
        if i == 5:
            raise ValueError("frame 5")
        return i

    got = []
    with pytest.raises(ValueError, match="frame 5"):
        for x in ordered_map(boom, range(100), workers=2):
            got.append(x)
    assert got == [0, 1, 2, 3, 4]


def test_a_minute_of_motion_makes_an_avatar_of_at_most_20_mb(tmp_path):
    """A 1-minute sequence at 30 fps (body and face) as avatar.glb: at most 20 MB (the mesh and the
    sparse morph targets are written once; the animation grows with the frames)."""
    from anima.export.avatar import write_avatar
    from anima.export.framing import generated_sequence

    rng = np.random.default_rng(0)
    F = 1800
    from anima.core.contract import JOINT_NAMES
    from anima.core.rig import idle_body
    from anima.facemodel.character import load_character

    body = idle_body(F, load_character().joints, 30.0)
    body = np.where(np.isfinite(body), body, 0.0) + rng.normal(0, 0.002, body.shape)
    body[:, JOINT_NAMES.index("pelvis")] = 0.0
    face = np.concatenate([rng.random((F, 53)) * 0.3, rng.normal(0, 0.05, (F, 3))], 1).astype(np.float32)
    seq = generated_sequence(30.0, face=face, body=body.astype(np.float32))
    info = write_avatar(seq, tmp_path / "avatar.glb")
    size = (tmp_path / "avatar.glb").stat().st_size
    assert info["frames"] == F and size <= 20e6, size / 1e6


def test_one_output_set_puts_the_sequence_on_the_character_once(seq, tmp_path, monkeypatch):
    """``avatar.glb``, ``body.bvh`` and ``avatar.mp4`` (written on their own threads) share one
    :class:`OnCharacter`: the character's motion and face are made once per output set, and the files are what
    each writer makes alone."""
    import anima.export.avatar as avatar
    from anima.export.formats import export_bvh
    from anima.export.motion import write_motion_outputs
    from anima.io.outdir import OutputFolder

    calls = {"motion": 0, "face": 0}
    real = {"motion": avatar.character_motion, "face": avatar.character_face}

    def counted(key):
        def call(s):
            calls[key] += 1
            return real[key](s)

        return call

    monkeypatch.setattr(avatar, "character_motion", counted("motion"))
    monkeypatch.setattr(avatar, "character_face", counted("face"))
    with OutputFolder(tmp_path / "out", kind="capture") as od:
        files = write_motion_outputs(seq, od, source_video=str(asset(D0)), progress=False)
    assert {"avatar", "avatar_video"} <= set(files)
    assert calls == {"motion": 1, "face": 1}  # three writers (two with a body), one of each

    monkeypatch.undo()  # each writer alone, as `anima export` runs it
    alone = tmp_path / "alone"
    alone.mkdir()
    avatar.write_avatar(seq, alone / "avatar.glb")
    assert (alone / "avatar.glb").read_bytes() == (tmp_path / "out" / "avatar.glb").read_bytes()
    if seq.body_joints is not None:
        export_bvh(seq, alone / "body.bvh")
        assert (alone / "body.bvh").read_bytes() == (tmp_path / "out" / "body.bvh").read_bytes()
    avatar.render_avatar_preview(seq, alone / "avatar.mp4")
    a, _ = read_video(alone / "avatar.mp4")
    b, _ = read_video(tmp_path / "out" / "avatar.mp4")
    assert a.shape == b.shape and np.array_equal(a, b)
