"""Hostile uploads to ``anima studio``: huge (announced and sent), truncated (the body, and the video in it), of
the wrong type, with path-like names, malformed. Each is a failed job with one line or a 4xx; the studio answers
after each; nothing is written outside ``--root`` and the temporary folder (the studio runs with its own empty
working folder, home and temporary folder, which must hold nothing when it has stopped)."""

import json
import os
import re
import socket
import subprocess
import sys

import pytest
from studio_client import REPO, Studio, multipart

pytestmark = pytest.mark.slow
MB = "multipart/form-data; boundary=b"
ID = re.compile(r"\d{8}-\d{6}-[0-9a-f]{6}$")


@pytest.fixture(scope="module")
def hostile(tmp_path_factory):
    base = tmp_path_factory.mktemp("hostile")
    dirs = {k: base / k for k in ("cwd", "home", "tmp")}
    for d in dirs.values():
        d.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("XDG_DATA_HOME",)}
    env |= {"HOME": str(dirs["home"]), "TMPDIR": str(dirs["tmp"])}
    s = Studio(base / "root", "--max-upload-mb", "1", cwd=dirs["cwd"], env=env)
    s.dirs = dirs
    yield s
    s.stop()


def answers(s: Studio) -> None:
    status, r = s.get_json("/api/jobs")
    assert status == 200, r


def raw(s: Studio, head: str, body: bytes = b"", shut: bool = False) -> bytes:
    """Send a request as bytes on a socket (what urllib will not: a lie about the length, a body cut short)."""
    with socket.create_connection(("127.0.0.1", s.port), timeout=30) as c:
        c.sendall(head.encode() + body)
        if shut:
            c.shutdown(socket.SHUT_WR)
        out = b""
        while chunk := c.recv(65536):
            out += chunk
    return out


def status_of(response: bytes) -> int:
    return int(response.split(b" ", 2)[1])


def failed_job(s: Studio, fields: dict, files: dict, filenames: dict | None = None) -> str:
    status, r = s.submit(fields, files, filenames)
    assert status == 201 and r["state"] == "failed", r
    err = s.job(r["id"])["error"]
    assert err and "\n" not in err and len(err) < 400, err
    answers(s)
    return err


def test_huge_uploads_are_refused(hostile):
    head = (f"POST /api/jobs HTTP/1.1\r\nHost: 127.0.0.1:{hostile.port}\r\nX-Anima-Token: {hostile.token}\r\n"
            "Content-Type: multipart/form-data; boundary=xyz\r\nContent-Length: 1000000000000\r\n\r\n")  # fmt: skip
    r = raw(hostile, head)
    assert status_of(r) == 413 and b"limit" in r, r[:300]
    answers(hostile)
    # under the announced limit, over the file limit once read: refused as it streams in
    status, r = hostile.submit({"kind": "capture"}, {"file": os.urandom(1_500_000)})
    assert status == 413 and "limit" in r["error"], r
    answers(hostile)


def test_a_body_cut_short_is_a_400(hostile):
    body, ctype = multipart({"kind": "capture"}, {"file": b"\x00" * 50_000}, {})
    head = (f"POST /api/jobs HTTP/1.1\r\nHost: 127.0.0.1:{hostile.port}\r\nX-Anima-Token: {hostile.token}\r\n"
            f"Content-Type: {ctype}\r\nContent-Length: {len(body)}\r\n\r\n")  # fmt: skip
    r = raw(hostile, head, body[: len(body) // 2], shut=True)  # the connection ends halfway
    assert status_of(r) == 400 and b"ended" in r, r[:300]
    answers(hostile)


def test_wrong_and_truncated_files_are_failed_jobs(hostile, short_clip):
    video = short_clip.read_bytes()
    assert "not a video" in failed_job(hostile, {"kind": "capture"}, {"file": b"GIF89a" + os.urandom(3000)})
    assert "not a video" in failed_job(hostile, {"kind": "capture"}, {"file": video[:2000]})  # cut
    assert "not a sound" in failed_job(hostile, {"kind": "gesture"}, {"file": b"%PDF-1.4\n" + os.urandom(2000)})
    err = failed_job(hostile, {"kind": "capture"}, {"file": video, "avatar": b"not a glb at all"})
    assert "glTF" in err
    err = failed_job(hostile, {"kind": "capture"}, {"file": video, "avatar": b"glTF\x02\x00\x00\x00" + b"\x00" * 64})
    assert "avatar" in err


def test_path_like_names_are_never_used(hostile, short_clip):
    names = {"file": "../../../../outside.mp4", "avatar": "/etc/passwd"}
    failed_job(hostile, {"kind": "capture"}, {"file": b"text\n" * 10}, {"file": "../../escape.mp4"})
    status, r = hostile.submit({"kind": "capture"}, {"file": short_clip.read_bytes()}, names)
    assert status == 201 and r["state"] == "queued", r
    hostile.request("DELETE", f"/api/jobs/{r['id']}")
    hostile.wait(r["id"], 60)
    assert sorted(p.name for p in (hostile.root / r["id"]).iterdir() if p.suffix == ".mp4") == ["input.mp4"]
    status, _, body = hostile.request("POST", "/api/jobs", *multipart_with_field("../file"))
    assert status == 400 and b"field" in body
    answers(hostile)


def multipart_with_field(name: str) -> tuple[bytes, dict]:
    body = (f'--b\r\nContent-Disposition: form-data; name="{name}"; filename="x"\r\n\r\nxx\r\n--b--\r\n').encode()
    return body, {"Content-Type": MB}


@pytest.mark.parametrize(
    "body,ctype,status",
    [
        (b"kind=capture", "application/x-www-form-urlencoded", 415),
        (b"--b\r\nContent-Disposition: form-data; name=\"kind\"\r\n\r\ncapture", MB, 400),
        (b"no boundary here at all", MB, 400),
        (b"--b\r\nContent-Disposition: form-data; name=\"kind\"\r\n\r\nsing\r\n--b--\r\n", MB, 400),
        (b"--b\r\nContent-Disposition: form-data; name=\"kind\"\r\n\r\ntext2face\r\n--b\r\nContent-Disposition: "
         b"form-data; name=\"options\"\r\n\r\n{\"rm\": 1}\r\n--b--\r\n", MB, 400),
        (b"--b\r\nContent-Disposition: form-data; name=\"kind\"\r\n\r\ntext2face\r\n--b--\r\n", MB, 400),
        (b"--b\r\nContent-Disposition: form-data; name=\"kind\"\r\n\r\nretarget\r\n--b--\r\n", MB, 400),
    ],
    ids=["not-multipart", "no-end", "no-boundary", "unknown-kind", "unknown-option", "no-prompt", "no-avatar"],
)  # fmt: skip
def test_malformed_forms_are_a_4xx_with_a_reason(hostile, body, ctype, status):
    got, _, out = hostile.request("POST", "/api/jobs", body, {"Content-Type": ctype})
    assert got == status, out
    assert json.loads(out)["error"]
    answers(hostile)


def test_a_second_studio_on_the_same_root_is_refused(hostile):
    argv = [sys.executable, "-m", "anima", "studio", "--root", str(hostile.root), "--no-browser"]
    r = subprocess.run(argv, capture_output=True, text=True, timeout=60, env=os.environ | {"PYTHONPATH": str(REPO)})
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "another anima studio" in r.stderr, r.stderr
    answers(hostile)


def test_paths_that_leave_the_api_are_not_found(hostile):
    for path in ("/api/jobs/../../etc/passwd", "/api/jobs/..%2f..%2fjob.json", "/api/jobs/x/files/y", "/api/other"):
        assert hostile.request("GET", path)[0] in (400, 404), path
    answers(hostile)


def test_nothing_is_left_outside_the_root_and_every_job_folder_is_a_job(hostile):
    """Last: the studio stopped, its working folder, home and temporary folder are empty; the root holds the
    studio's marker and one folder per job listed (the uploads refused at the door left none)."""
    _, listed = hostile.get_json("/api/jobs")
    ids = {j["id"] for j in listed["jobs"]}
    hostile.stop()
    for name, d in hostile.dirs.items():
        assert list(d.iterdir()) == [], (name, list(d.rglob("*")))
    folders = {p.name for p in hostile.root.iterdir() if not p.name.startswith(".")}
    assert folders == ids and all(ID.match(n) for n in folders), (folders, ids)
    for jid in ids:
        leftovers = [p.name for p in (hostile.root / jid).iterdir() if p.name.startswith("upload-")]
        assert leftovers == [], (jid, leftovers)
    assert not list(hostile.root.parent.rglob("outside*")) and not list(hostile.root.parent.rglob("escape*"))
