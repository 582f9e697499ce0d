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


def _tree(folder):
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_anima_writes_only_into_its_own_folders(tmp_path):
    """A folder holding files anima did not write is refused (before any work); an empty or new one is
    claimed with anima's marker; an older anima result (a manifest, no marker) is adopted but nothing in it is
    deleted."""
    from anima.io.outdir import MARKER, check_out_dir, read_marker

    user = tmp_path / "mine"
    user.mkdir()
    (user / "notes.txt").write_text("my notes")
    (user / "photo.jpg").write_bytes(b"\xff\xd8")
    with pytest.raises(InputError, match="did not write .*notes.txt, photo.jpg"):
        OutputFolder(user, kind="demo")
    with pytest.raises(InputError, match="did not write"):
        check_out_dir(user, "--static")
    assert _tree(user) == {"notes.txt": b"my notes", "photo.jpg": b"\xff\xd8"}
    empty = tmp_path / "empty"
    empty.mkdir()
    with OutputFolder(empty, kind="demo") as od:
        write_json(od.file("a.json"), {})
    assert read_marker(empty)["files"].keys() == {"a.json"}
    with OutputFolder(empty, kind="demo") as od:  # a rerun replaces anima's unchanged file
        write_json(od.file("a.json"), {"again": 1})
    (empty / "mine.txt").write_text("added by the user later")  # a user's file inside an anima folder
    with pytest.raises(InputError, match="did not write .*mine.txt"):  # the folder is no longer anima's alone
        OutputFolder(empty, kind="demo")
    (empty / "mine.txt").unlink()
    with OutputFolder(empty / "nested", kind="demo") as od:  # another anima result inside this one: anima's
        write_json(od.file("n.json"), {})
    with OutputFolder(empty, kind="demo") as od:
        write_json(od.file("a.json"), {"again": 2})
    assert (empty / "nested" / "n.json").is_file()
    (empty / "a.json").write_text('{"edited": true}')  # a file anima wrote, edited by the user
    with pytest.raises(InputError, match="a.json changed since anima wrote it"):
        with OutputFolder(empty, kind="demo") as od:
            write_json(od.file("a.json"), {})
    assert (empty / "a.json").read_text() == '{"edited": true}'
    mine = tmp_path / "proj"  # a user's folder that gained anima's marker (cp -a res/. proj/)
    mine.mkdir()
    (mine / "capture.npz").write_bytes(b"the user's own")
    (mine / MARKER).write_bytes((empty / MARKER).read_bytes())
    with pytest.raises(InputError, match="did not write .*capture.npz"):
        OutputFolder(mine, kind="demo")
    assert (mine / "capture.npz").read_bytes() == b"the user's own"
    legacy = tmp_path / "legacy"  # an older anima's result: manifest, no marker; its stale list is not trusted
    legacy.mkdir()
    (legacy / "keep.txt").write_text("listed by an old manifest")
    (legacy / "manifest.json").write_text(
        json.dumps({"schema": "anima.result", "version": 1, "files": {"keep.txt": {}}})
    )
    with OutputFolder(legacy, kind="demo") as od:
        write_json(od.file("a.json"), {})
    assert (legacy / "keep.txt").exists() and (legacy / MARKER).is_file()


def test_stale_removal_stays_inside_the_folder_and_on_anima_content(tmp_path):
    """A killed run's marker or a manifest naming ``../victim.txt``, an absolute path, a path through a symlink
    or a file whose content changed since anima wrote it: nothing of those is deleted."""
    import hashlib

    from anima.io.outdir import MARKER, sha256

    out = tmp_path / "r"
    with OutputFolder(out, kind="demo") as od:
        write_json(od.file("old.json"), {"x": 1})
        write_json(od.file("edited.json"), {"x": 2})
    victim = tmp_path / "victim.txt"
    victim.write_text("outside")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "x.txt").write_text("behind a link")
    (out / "link").symlink_to(elsewhere)
    (out / "edited.json").write_text('{"mine": true}')
    digest = hashlib.sha256(b"outside").hexdigest()
    marker = json.loads((out / MARKER).read_text())
    marker["files"].update(
        {
            "../victim.txt": digest,
            str(victim): digest,
            "link/x.txt": hashlib.sha256(b"behind a link").hexdigest(),
            "old.json": sha256(out / "old.json"),
        }
    )
    marker["running"] = True  # a run killed while writing: its folder is anima's as a whole
    (out / MARKER).write_text(json.dumps(marker))
    (out / "manifest.json").write_text(
        json.dumps({"schema": "anima.result", "version": 1, "files": {"../victim.txt": {}, str(victim): {}}})
    )
    with OutputFolder(out, kind="demo") as od:
        write_json(od.file("new.json"), {})
    assert victim.read_text() == "outside" and (elsewhere / "x.txt").read_text() == "behind a link"
    assert (out / "edited.json").read_text() == '{"mine": true}'  # changed by the user: theirs now
    assert not (out / "old.json").exists()  # anima's own stale output: removed


def test_single_file_outputs_never_replace_an_input_or_a_special_file(tmp_path):
    import os

    from anima.io.outdir import check_out_file

    f = tmp_path / "take.npz"
    f.write_bytes(b"x")
    with pytest.raises(InputError, match="is an input"):
        check_out_file(f, inputs=[f])
    with pytest.raises(InputError, match="is an input"):
        check_out_file(tmp_path / "." / "take.npz", inputs=[str(f)])
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match="special file"):
        check_out_file(fifo)
    with pytest.raises(InputError, match="expected a .mp4"):
        check_out_file(tmp_path / "r.json", suffixes=(".mp4",))
