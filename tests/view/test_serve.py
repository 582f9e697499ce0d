"""``anima view``'s server and page export under attack, without a browser: the server answers only
its own token, its own Host and plain names of regular files; malformed requests are 400s, never tracebacks;
an idle connection is closed. The export reads only regular files inside the result folder and keeps a user's
file's permission bits. (What a browser does with the page is in test_view.py.)"""

import json
import os
import shutil
import socket
import stat
import threading
import time

import numpy as np
import pytest

from anima.export.framing import generated_sequence
from anima.io.assets import asset
from anima.io.sequence import write_sequence
from anima.io.video import probe_video
from anima.view.export import build_view
from anima.view.serve import open_server

D0 = "liveportrait-examples/assets/examples/driving/d0.mp4"


def _ask(port: int, path: str, host: str | None = None, extra: str = "") -> tuple[int, bytes]:
    """(status, body) of one raw HTTP request (raw, so that nothing in between fixes the path up)."""
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        s.sendall(
            f"GET {path} HTTP/1.1\r\nHost: {host or f'127.0.0.1:{port}'}\r\n{extra}Connection: close\r\n\r\n".encode(
                "latin-1"
            )
        )
        data = b""
        while chunk := s.recv(65536):
            data += chunk
    head, _, body = data.partition(b"\r\n\r\n")
    return int(head.split(b" ", 2)[1]), body


@pytest.fixture
def server(tmp_path):
    root = tmp_path / "root"
    root.mkdir()
    (root / "index.html").write_text("<p>page</p>")
    (root / "view-data.js").write_text("window.ANIMA_VIEW = {};")
    secret = tmp_path / "id_rsa"
    secret.write_text("PRIVATE KEY")
    (root / "key.txt").symlink_to(secret)
    (root / "sub").mkdir()
    srv, _ = open_server(root, None)
    srv.RequestHandlerClass.timeout = 1.0  # idle connections, quickly
    threading.Thread(target=srv.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True).start()
    yield srv
    srv.shutdown()
    srv.server_close()


def test_server_answers_only_its_token_host_and_regular_files(server, capfd):
    port, tok = server.server_address[1], server.token
    assert _ask(port, f"/{tok}/index.html") == (200, b"<p>page</p>")
    assert _ask(port, f"/{tok}/index.html", host=f"localhost:{port}")[0] == 200
    assert _ask(port, f"/{tok}/view-data.js", host=f"evil.example:{port}")[0] == 421  # DNS rebinding
    assert _ask(port, f"/{tok}/view-data.js", host="127.0.0.1")[0] == 421  # another port's page
    assert _ask(port, "/view-data.js")[0] == 404  # no token: nothing
    wrong = tok[:-1] + ("y" if tok.endswith("x") else "x")  # one character off (never the token itself)
    assert _ask(port, f"/{wrong}/view-data.js")[0] == 404
    for path in (f"/{tok}/key.txt", f"/{tok}/../id_rsa", f"/{tok}/%2e%2e/id_rsa", f"/{tok}/sub", f"/{tok}/sub/x"):
        status, body = _ask(port, path)
        assert status == 404 and b"PRIVATE" not in body, path
    for path in (f"/{tok}/index.html%00", f"/{tok}/%ff%fe", f"/{tok}/a\\b"):
        assert _ask(port, path)[0] == 400, path
    assert _ask(port, f"/{tok}/index.html", extra=f"Range: bytes={'9' * 5000}-\r\n")[0] == 400
    assert _ask(port, f"/{tok}/index.html", extra="Range: bytes=3-6\r\n") == (206, b"page")
    out, err = capfd.readouterr()
    assert "Traceback" not in out + err


def test_server_closes_an_idle_connection(server):
    with socket.create_connection(("127.0.0.1", server.server_address[1]), timeout=10) as s:
        s.sendall(b"GET /")  # and then nothing
        assert s.recv(100) == b""  # closed by the server (after its 1-s idle timeout), not held forever


def test_the_export_reads_only_regular_files_inside_the_result(tmp_path):
    """A symlink in a result folder (an SSH key), a re-enactment record whose video lies elsewhere: not copied,
    said in a note. A user's source video is copied with its own mode (0600 stays 0600)."""
    res = tmp_path / "res"
    res.mkdir()
    secret = tmp_path / "id_rsa"
    secret.write_text("PRIVATE KEY")
    secret.chmod(0o600)
    src = tmp_path / "clip.mp4"
    shutil.copyfile(asset(D0), src)
    src.chmod(0o600)
    seq = generated_sequence(25.0, face=np.zeros((10, 56), np.float32))
    seq.meta["source"] = probe_video(src).as_dict()  # as a capture records it
    write_sequence(seq, res / "capture.npz")
    for name in ("overlay.mp4", "speech.wav", "avatar.glb", "info.json"):
        (res / name).symlink_to(secret)
    page = tmp_path / "page"
    data = build_view(res, page)
    assert not any(b"PRIVATE" in p.read_bytes() for p in page.iterdir())
    assert not (page / "overlay.mp4").exists() and not (page / "speech.wav").exists()
    assert sum("not a regular file" in n for n in data["notes"]) == 4
    assert stat.S_IMODE(os.stat(page / "source.mp4").st_mode) == 0o600
    assert stat.S_IMODE(os.stat(page / "index.html").st_mode) & 0o044  # anima's own files: readable
    # a re-enactment record pointing outside its folder
    rec = tmp_path / "re"
    rec.mkdir()
    outside = tmp_path / "private.mp4"
    shutil.copyfile(asset(D0), outside)
    record = {"schema": "anima.reenact_run", "version": 1, "actor": "a.mp4", "targets": ["t.mp4"]}
    record["result"] = {"fps": 25, "frames": 10, "output": str(outside)}
    (rec / "r.json").write_text(json.dumps(record))
    data = build_view(rec, tmp_path / "page2")
    assert data["videos"] == [] and any("not beside its record" in n for n in data["notes"])


def test_absolute_form_targets_are_refused(server):
    """``GET http://other.host/TOKEN/...`` (a proxy's form) is a 400, not the page's file."""
    port, tok = server.server_address[1], server.token
    assert _ask(port, f"http://evil.example/{tok}/index.html")[0] == 400
    assert _ask(port, f"http://127.0.0.1:{port}/{tok}/index.html")[0] == 400
    assert _ask(port, f"/{tok}/index.html")[0] == 200


def _upgrade(port: int, tok: str) -> tuple[socket.socket, int]:
    """A raw WebSocket handshake from the page's own origin: (the socket, the HTTP status)."""
    s = socket.create_connection(("127.0.0.1", port), timeout=10)
    s.sendall(
        (f"GET /{tok}/live HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nOrigin: http://127.0.0.1:{port}\r\n"
         "Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
         "Sec-WebSocket-Version: 13\r\n\r\n").encode()
    )  # fmt: skip
    head = b""
    while b"\r\n\r\n" not in head:
        chunk = s.recv(1)
        if not chunk:
            break
        head += chunk
    return s, int(head.split(b" ", 2)[1]) if head else 0


def test_websocket_slots_are_refused_when_full_and_freed_when_idle(tmp_path, monkeypatch):
    """A page beyond the limit is answered 503 before the upgrade (not accepted and starved); a page that
    answers none of the server's pings loses its slot, so idle sockets cannot lock the page out."""
    import anima.view.ws as ws

    monkeypatch.setattr(ws, "PING_S", 0.3)
    monkeypatch.setattr(ws, "MAX_CLIENTS", 3)
    (tmp_path / "index.html").write_text("<p>live</p>")
    hub = ws.Broadcaster()
    srv, _ = open_server(tmp_path, None, live=hub)
    threading.Thread(target=srv.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True).start()
    port, tok = srv.server_address[1], srv.token
    try:
        held = [_upgrade(port, tok) for _ in range(3)]
        assert [st for _, st in held] == [101] * 3
        extra, status = _upgrade(port, tok)
        assert status == 503
        extra.close()
        deadline = time.time() + 10  # the silent pages answer no ping: dropped after PING_S * IDLE_PINGS
        while time.time() < deadline and hub.clients:
            time.sleep(0.1)
        assert not hub.clients
        s, status = _upgrade(port, tok)
        assert status == 101
        for sock, _ in held + [(s, 0)]:
            sock.close()
    finally:
        srv.shutdown()
        srv.server_close()
