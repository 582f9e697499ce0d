"""``anima view``: the page of a result, served on 127.0.0.1 (a free port) or written as files (``--static``).

The server is the standard library's, with byte ranges (browsers seek in a video by asking for a range; a
server without them leaves videos unseekable). What it will and will not do:

* it serves only the page's own folder (a temporary copy made by :func:`anima.view.export.build_view`): plain
  file names, regular files, nothing through a symlink, no sub-folders;
* every URL carries a random per-run token (``http://127.0.0.1:PORT/TOKEN/index.html``): another site cannot
  guess the address of ``view-data.js`` to include it as a script, and ``Cross-Origin-Resource-Policy:
  same-origin`` tells the browser not to hand it to another origin anyway;
* it answers only ``Host: 127.0.0.1:PORT`` or ``localhost:PORT`` (a DNS-rebinding page names its own host);
* a malformed request (a NUL, a bad escape, a Range of thousands of digits, an absolute-form target such as
  ``GET http://other.host/TOKEN/...``) is answered 400, never a traceback;
* a request must arrive whole (its line and headers; the server reads no body: GET and HEAD only) within
  :data:`REQUEST_S` of the connection opening or of the previous answer, however slowly it trickles in (an idle
  connection is closed at the same limit). What the server sends has no such limit: a slow reader of a long
  video is served for as long as it keeps reading (a client that reads nothing for :data:`IDLE_TIMEOUT_S` is
  closed), and the live page's WebSocket lives as long as the page answers its pings;
* at most :data:`MAX_CONNECTIONS` connections at once: one more closes the connection that has waited longest for
  a request (idle, or a request still arriving), or, when every one is busy answering, is answered 503;
* the live page's WebSocket takes at most :data:`anima.view.ws.MAX_CLIENTS` pages: one more is answered 503
  before the upgrade, and a page that stops answering the server's pings loses its slot
  (:data:`anima.view.ws.PING_S`).
"""

from __future__ import annotations

import errno
import io
import mimetypes
import os
import re
import secrets
import shutil
import socket
import stat
import sys
import tempfile
import threading
import time
import webbrowser
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import unquote, urlsplit

from anima.errors import InputError
from anima.io.outdir import OutputFolder, check_out_dir
from anima.view.export import build_view, check_avatar, detect
from anima.view.ws import accept_key

HOST = "127.0.0.1"
IDLE_TIMEOUT_S = 20
"""A client that reads nothing of what it is sent for this long is closed."""
REQUEST_S = 10.0
"""The longest a request (its line and headers) may take to arrive, in all."""
MAX_CONNECTIONS = 32
"""Connections served at once (the live page's WebSocket included)."""
_BUSY = b"HTTP/1.1 503 Service Unavailable\r\nContent-Length: 0\r\nRetry-After: 1\r\nConnection: close\r\n\r\n"
_RANGE = re.compile(r"bytes=(\d{0,18})-(\d{0,18})$")
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,200}$")
_TYPES = {".js": "text/javascript; charset=utf-8", ".html": "text/html; charset=utf-8", ".wav": "audio/wav"}


class _RequestReader(io.RawIOBase):
    """A connection's bytes for the request parser, every read bounded by what is left until ``deadline`` (when
    set): a request that trickles in a byte at a time still ends at the deadline."""

    def __init__(self, sock, idle: float):
        self.sock, self.idle = sock, idle
        self.deadline: float | None = None

    def readable(self) -> bool:
        return True

    def readinto(self, b) -> int:
        if self.deadline is not None:
            left = self.deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError("the request did not arrive in time")
            self.sock.settimeout(min(left, self.idle))
        return self.sock.recv_into(b)


class FileHandler(BaseHTTPRequestHandler):
    """GET/HEAD of the files of one flat folder under ``/TOKEN/``, with ``Range`` (HTTP 206), no caching. ``anima
    studio`` extends it (its API beside the files): :meth:`send_file` sends any file the subclass resolved."""

    root: Path
    token: str
    hosts: frozenset
    live = None  # a Broadcaster (anima live): /TOKEN/live upgrades to its WebSocket
    timeout = IDLE_TIMEOUT_S
    server_version = "anima-view"
    sys_version = ""

    def log_message(self, format, *args):
        pass

    def setup(self):
        super().setup()
        self.rfile.close()  # the socket's own file: replaced by one that keeps the request's deadline
        self.reader = _RequestReader(self.connection, self.timeout)
        self.rfile = io.BufferedReader(self.reader)

    def handle_one_request(self):
        """One request, which must arrive whole within :data:`REQUEST_S`; its answer is not limited."""
        self.reader.deadline = time.monotonic() + REQUEST_S
        self.server.waiting(self.connection, True)
        super().handle_one_request()

    def parse_request(self) -> bool:
        try:
            return super().parse_request()  # reads the headers
        finally:
            self.reader.deadline = None
            self.connection.settimeout(self.timeout)
            self.server.waiting(self.connection, False)

    def _refuse(self, status: HTTPStatus, head_only: bool = False) -> None:
        body = f"{status.value} {status.phrase}\n".encode()
        self.send_response(status)
        self.send_header("Content-Type", "text/plain; charset=utf-8")
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        if not head_only:
            self.wfile.write(body)

    def _file(self) -> tuple[Path | None, HTTPStatus]:
        """The file a request names, or why not."""
        if self.headers.get("Host", "") not in self.hosts:
            return None, HTTPStatus.MISDIRECTED_REQUEST
        try:
            raw = urlsplit(self.path).path
            path = unquote(raw, errors="strict")
        except (ValueError, UnicodeDecodeError):
            return None, HTTPStatus.BAD_REQUEST
        if "\x00" in path or "\\" in path:
            return None, HTTPStatus.BAD_REQUEST
        prefix = f"/{self.token}/"
        if not path.startswith(prefix):
            return None, HTTPStatus.NOT_FOUND
        name = path[len(prefix) :] or "index.html"
        if not _NAME.match(name) or ".." in name:
            return None, HTTPStatus.NOT_FOUND
        p = self.root / name
        try:
            st = os.lstat(p)
        except OSError:
            return None, HTTPStatus.NOT_FOUND
        if not stat.S_ISREG(st.st_mode):
            return None, HTTPStatus.NOT_FOUND
        return p, HTTPStatus.OK

    def do_HEAD(self):
        if not self.path.startswith("/"):  # an absolute-form target (a proxy's request): not for this server
            return self._refuse(HTTPStatus.BAD_REQUEST, head_only=True)
        self._serve(head_only=True)

    def do_GET(self):
        if not self.path.startswith("/"):
            return self._refuse(HTTPStatus.BAD_REQUEST)
        if self.live is not None and urlsplit(self.path).path == f"/{self.token}/live":
            return self._websocket()
        self._serve(head_only=False)

    def _websocket(self) -> None:
        """``/TOKEN/live`` (``anima live``): the upgrade to a WebSocket, for this page's own origin only."""
        origins = {f"http://{h}" for h in self.hosts}
        key = self.headers.get("Sec-WebSocket-Key", "")
        if (
            self.headers.get("Host", "") not in self.hosts
            or self.headers.get("Origin", "") not in origins
            or self.headers.get("Upgrade", "").lower() != "websocket"
            or not key
            or len(key) > 64
        ):
            return self._refuse(HTTPStatus.FORBIDDEN)
        if not self.live.reserve():  # every slot taken: refused now, not accepted and starved
            return self._refuse(HTTPStatus.SERVICE_UNAVAILABLE)
        self.send_response(HTTPStatus.SWITCHING_PROTOCOLS)
        self.send_header("Upgrade", "websocket")
        self.send_header("Connection", "Upgrade")
        self.send_header("Sec-WebSocket-Accept", accept_key(key))
        self.end_headers()
        self.wfile.flush()
        self.close_connection = True
        self.live.attach(self.connection)

    def _serve(self, head_only: bool) -> None:
        p, status = self._file()
        if p is None:
            return self._refuse(status, head_only)
        return self.send_file(p, head_only)

    def send_file(self, p: Path, head_only: bool = False) -> None:
        """Answer with the file ``p`` (resolved and checked by the caller), or the part a ``Range`` asks for."""
        try:
            fh = open(p, "rb")
        except OSError:
            return self._refuse(HTTPStatus.NOT_FOUND, head_only)
        with fh:
            size = os.fstat(fh.fileno()).st_size
            start, end = 0, size - 1
            rng = self.headers.get("Range", "").strip()
            m = _RANGE.match(rng) if rng else None
            if rng and (m is None or m.groups() == ("", "")):
                return self._refuse(HTTPStatus.BAD_REQUEST, head_only)
            if m:
                a, b = m.groups()
                if a == "":  # the last b bytes
                    start, end = max(0, size - int(b)), size - 1
                else:
                    start, end = int(a), min(size - 1, int(b) if b else size - 1)
                if start >= size or start > end:
                    self.send_response(HTTPStatus.REQUESTED_RANGE_NOT_SATISFIABLE)
                    self.send_header("Content-Range", f"bytes */{size}")
                    self.send_header("Content-Length", "0")
                    self.end_headers()
                    return None
                self.send_response(HTTPStatus.PARTIAL_CONTENT)
                self.send_header("Content-Range", f"bytes {start}-{end}/{size}")
            else:
                self.send_response(HTTPStatus.OK)
            ctype = _TYPES.get(p.suffix.lower()) or mimetypes.guess_type(p.name)[0] or "application/octet-stream"
            self.send_header("Content-Type", ctype)
            self.send_header("Content-Length", str(max(0, end - start + 1)))
            self.send_header("Accept-Ranges", "bytes")
            self.send_header("Cache-Control", "no-store")
            self.send_header("X-Content-Type-Options", "nosniff")
            self.send_header("Cross-Origin-Resource-Policy", "same-origin")
            self.send_header("Referrer-Policy", "no-referrer")
            self.end_headers()
            if head_only:
                return None
            fh.seek(start)
            left = end - start + 1
            try:
                while left > 0:
                    block = fh.read(min(left, 1 << 16))
                    if not block:
                        break
                    self.wfile.write(block)
                    left -= len(block)
            except (BrokenPipeError, ConnectionResetError):  # the browser moved on (a seek): not an error
                pass
        return None


class _Server(ThreadingHTTPServer):
    """One thread per connection, at most :data:`MAX_CONNECTIONS` of them: one more closes the connection that
    has waited longest for its request (an idle keep-alive, or a request still arriving), so that connections
    held open without a request never lock the page out; when every connection is busy answering, it is
    answered 503."""

    daemon_threads = True
    max_connections = MAX_CONNECTIONS

    def __init__(self, *args, **kw):
        self.lock = threading.Lock()
        self.open: dict = {}  # socket -> since when it waits for a request (None: it is being answered)
        super().__init__(*args, **kw)

    def waiting(self, sock, wait: bool) -> None:
        with self.lock:
            if sock in self.open:
                self.open[sock] = time.monotonic() if wait else None

    def process_request(self, request, client_address):
        with self.lock:
            full = len(self.open) >= self.max_connections
            if full:
                idle = [(t, s) for s, t in self.open.items() if t is not None]
                if idle:
                    oldest = min(idle, key=lambda x: x[0])[1]
                    del self.open[oldest]
                    try:
                        oldest.shutdown(socket.SHUT_RDWR)  # its thread's read ends; the thread closes it
                    except OSError:
                        pass
                    full = False
            if not full:
                self.open[request] = time.monotonic()
        if full:
            try:
                request.setblocking(False)
                request.send(_BUSY)
            except OSError:
                pass
            return self.shutdown_request(request)
        return super().process_request(request, client_address)

    def shutdown_request(self, request):
        with self.lock:
            self.open.pop(request, None)
        super().shutdown_request(request)

    def handle_error(self, request, client_address):
        """A request that failed in a way the handler did not answer (a dropped connection): no traceback."""


def open_server(
    root: Path, port: int | None, token: str | None = None, live=None, handler: type | None = None
) -> tuple[ThreadingHTTPServer, str | None]:
    """A server of ``root`` on 127.0.0.1: ``port``, or a free one (and a note) when that one is taken. Its
    files are under ``/TOKEN/`` (``server.token``); with ``live`` (a :class:`anima.view.ws.Broadcaster`),
    ``/TOKEN/live`` is its WebSocket. ``handler``: a subclass of :class:`FileHandler` to answer instead."""
    token = token or secrets.token_urlsafe(18)
    attrs = {"root": Path(root), "token": token, "hosts": frozenset(), "live": live}
    handler = type("Handler", (handler or FileHandler,), attrs)
    note = None
    try:
        server = _Server((HOST, port or 0), handler)
    except OSError as e:
        if port is None or e.errno not in (errno.EADDRINUSE, errno.EACCES):
            raise InputError(f"cannot serve on {HOST}: {e.strerror or e}") from None
        server = _Server((HOST, 0), handler)
        note = f"port {port} is in use; serving on port {server.server_address[1]} instead"
    bound = server.server_address[1]
    handler.hosts = frozenset({f"{HOST}:{bound}", f"localhost:{bound}"})
    server.token = token
    return server, note


def serve_until_stopped(server, url: str, browser: bool) -> None:
    """Open ``url`` in a browser (when asked and there is a screen), then serve until Ctrl-C."""
    has_screen = sys.platform != "linux" or os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    if browser and has_screen:
        threading.Thread(target=webbrowser.open, args=(url,), daemon=True).start()
    try:
        server.serve_forever(poll_interval=0.2)
    except KeyboardInterrupt:
        pass


def page_url(server) -> str:
    return f"http://{HOST}:{server.server_address[1]}/{server.token}/index.html"


def write_static(
    folder: str | Path, out: str | Path, command: str | None = None, avatar: str | None = None, motion: str = "auto"
) -> dict:
    """``anima view DIR --static OUT``: the page as files (open ``OUT/index.html`` from disk). ``OUT`` follows
    the result-folder rule (new, empty, or anima's own); only the page's own files are written and listed."""
    kind = detect(Path(folder))  # refuse a folder that holds no result before touching OUT
    check_avatar(avatar, kind, motion)
    check_out_dir(out, "--static", inputs=[folder, avatar])
    with OutputFolder(out, kind="view", command=command, inputs=[folder, avatar], flag="--static") as od:
        data = build_view(folder, od.path, avatar, motion)
        for name in data["written"]:
            od.file(name)
        od.info = {"kind": kind, "source": str(folder)}
    return {"kind": kind, "page": str(Path(out) / "index.html"), "notes": data["notes"]}


def serve(
    folder: str | Path,
    port: int | None = None,
    browser: bool = True,
    announce=print,
    avatar: str | None = None,
    motion: str = "auto",
) -> int:
    """``anima view DIR``: build the page into a temporary folder and serve it until Ctrl-C / SIGTERM."""
    kind = detect(Path(folder))
    check_avatar(avatar, kind, motion)
    if port is not None and not 1 <= port <= 65535:
        raise InputError(f"--port {port}: expected 1 to 65535")
    root = Path(tempfile.mkdtemp(prefix="anima-view-"))
    server = None
    try:
        data = build_view(folder, root, avatar, motion)
        server, note = open_server(root, port)
        url = page_url(server)
        for n in ([note] if note else []) + data["notes"]:
            print(f"anima: note: {n}", file=sys.stderr)
        announce(f"anima view: {kind} {folder} at {url}  (Ctrl-C to stop)")
        sys.stdout.flush()
        serve_until_stopped(server, url, browser)
    except KeyboardInterrupt:
        pass
    finally:
        if server is not None:
            server.server_close()
        shutil.rmtree(root, ignore_errors=True)
    return 0
