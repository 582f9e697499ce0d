"""Atomic writes and result folders: no torn file, no shared temporary name, no mixed or stale results."""

import json
import threading

import numpy as np
import pytest

from anima.errors import InputError
from anima.io.atomic import TMP_MARK, write_bytes, write_json
from anima.io.outdir import OutputFolder, check_complete, read_manifest


def test_two_writers_of_one_path_never_corrupt_it(tmp_path):
    """Concurrent writers each write whole files: every read-back is one writer's complete content."""
    target = tmp_path / "x.json"
    payloads = [json.dumps({"writer": w, "data": [w] * 20_000}) for w in range(2)]
    errors, reads = [], []
    write_bytes(target, payloads[0].encode())
    done = threading.Event()

    def writer(w):
        for _ in range(60):
            try:
                write_bytes(target, payloads[w].encode())
            except Exception as e:
                errors.append(e)

    def reader():
        while not done.is_set():
            reads.append(target.read_text())

    ts = [threading.Thread(target=writer, args=(w,)) for w in range(2)]
    rd = threading.Thread(target=reader)
    rd.start()
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    done.set()
    rd.join()
    assert not errors
    assert all(r in payloads for r in reads) and reads
    assert not list(tmp_path.glob(f".*{TMP_MARK}*"))


def test_a_failed_write_leaves_the_previous_file(tmp_path):
    p = write_json(tmp_path / "a.json", {"v": 1})
    with pytest.raises(TypeError):
        write_json(p, {"v": object()})
    assert json.loads(p.read_text()) == {"v": 1} and not list(tmp_path.glob(f".*{TMP_MARK}*"))


def test_video_writer_abort_keeps_the_old_video(tmp_path):
    from anima.io.video import VideoWriter, probe_video

    p = tmp_path / "v.mp4"
    with VideoWriter(p, 10, (64, 64)) as vw:
        for _ in range(10):
            vw.write(np.zeros((64, 64, 3), np.uint8))
    with pytest.raises(RuntimeError), VideoWriter(p, 10, (64, 64)) as vw:
        vw.write(np.zeros((64, 64, 3), np.uint8))
        raise RuntimeError("render failed")
    assert probe_video(p).n_frames == 10 and not list(tmp_path.glob(f".*{TMP_MARK}*"))


def test_result_folder_manifest_lock_and_stale_files(tmp_path):
    out = tmp_path / "r"
    with OutputFolder(out, kind="demo", command="anima demo") as od:
        write_json(od.file("a.json"), {"x": 1})
        write_json(od.file("b.json"), {"x": 2})
        assert not (out / "manifest.json").exists()  # written last
        with pytest.raises(InputError, match="another anima run"), OutputFolder(out, kind="demo"):
            pass
    m = check_complete(out)
    assert set(m["files"]) == {"a.json", "b.json"} and m["command"] == "anima demo"
    with OutputFolder(out, kind="demo") as od:  # a rerun that writes only a.json
        assert not (out / "manifest.json").exists()  # the folder is partial while it runs
        write_json(od.file("a.json"), {"x": 3})
    assert not (out / "b.json").exists() and set(read_manifest(out)["files"]) == {"a.json"}
    (out / "a.json").write_text("{}")  # changed behind the manifest's back
    with pytest.raises(InputError, match="differs"):
        check_complete(out)


def test_a_failed_first_run_leaves_no_folder(tmp_path):
    out = tmp_path / "new"
    with pytest.raises(RuntimeError), OutputFolder(out, kind="demo"):
        raise RuntimeError("capture failed")
    assert not out.exists()


def test_out_paths_are_checked_before_work(tmp_path):
    from anima.io.outdir import check_out_dir, check_out_file

    f = tmp_path / "file.txt"
    f.write_text("x")
    with pytest.raises(InputError, match="existing file"):
        OutputFolder(f, kind="demo")
    with pytest.raises(InputError, match="cannot write"):
        check_out_dir("/proc/anima-out")
    with pytest.raises(InputError, match="is a folder"):
        check_out_file(tmp_path)
    with pytest.raises(InputError, match="cannot write"):
        check_out_file("/proc/anima/x.npz")
    assert check_out_file(tmp_path / "deeper" / "x.npz") == tmp_path / "deeper" / "x.npz"
    assert not (tmp_path / "deeper").exists()  # checking creates nothing
