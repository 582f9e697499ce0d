"""``anima view``: the page of a result, served on 127.0.0.1 (a free port) or written as files (``--static``).

The server is the standard library's, with byte ranges (browsers seek in a video by asking for a range; a
server without them leaves videos unseekable), serving only the page's own folder."""

from __future__ import annotations

import errno
import os
import re
import shutil
import sys
import tempfile
import threading
import webbrowser
from functools import partial
from http import HTTPStatus
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

from anima.errors import InputError
from anima.io.outdir import OutputFolder, check_out_dir
from anima.view.export import build_view, detect

HOST = "127.0.0.1"
_RANGE = re.compile(r"bytes=(\d*)-(\d*)$")


class _Handler(SimpleHTTPRequestHandler):
    """Static files of one folder, with ``Range`` requests (HTTP 206) and no caching."""

    def log_message(self, format, *args):
        pass

    def end_headers(self):
        self.send_header("Cache-Control", "no-store")
        self.send_header("Accept-Ranges", "bytes")
        super().end_headers()

    def send_head(self):
        m = _RANGE.match(self.headers.get("Range", "").strip())
        path = Path(self.translate_path(self.path))
        if not m or not path.is_file():
            return super().send_head()
        size = path.stat().st_size
        a, b = m.groups()
        if a == "":  # the last b bytes
            start, end = max(0, size - int(b or 0)), size - 1
        else:
            start, end = int(a), min(size - 1, int(b) if b else size - 1)
        if start >= size or start > end:
            self.send_response(HTTPStatus.REQUESTED_RANGE_NOT_SATISFIABLE)
            self.send_header("Content-Range", f"bytes */{size}")
            self.end_headers()
            return None
        fh = open(path, "rb")
        fh.seek(start)
        self.send_response(HTTPStatus.PARTIAL_CONTENT)
        self.send_header("Content-Type", self.guess_type(str(path)))
        self.send_header("Content-Range", f"bytes {start}-{end}/{size}")
        self.send_header("Content-Length", str(end - start + 1))
        self.end_headers()
        self._left = end - start + 1
        return fh

    def copyfile(self, source, outputfile):
        left = getattr(self, "_left", None)
        if left is None:
            return super().copyfile(source, outputfile)
        try:
            while left > 0:
                block = source.read(min(left, 1 << 16))
                if not block:
                    break
                outputfile.write(block)
                left -= len(block)
        except (BrokenPipeError, ConnectionResetError):  # the browser moved on (a seek): not an error
            pass


def open_server(root: Path, port: int | None) -> tuple[ThreadingHTTPServer, str | None]:
    """A server of ``root`` on 127.0.0.1: ``port``, or a free one (and a note) when that one is taken."""
    handler = partial(_Handler, directory=str(root))
    note = None
    try:
        server = ThreadingHTTPServer((HOST, port or 0), handler)
    except OSError as e:
        if port is None or e.errno not in (errno.EADDRINUSE, errno.EACCES):
            raise InputError(f"cannot serve on {HOST}: {e.strerror or e}") from None
        server = ThreadingHTTPServer((HOST, 0), handler)
        note = f"port {port} is in use; serving on port {server.server_address[1]} instead"
    server.daemon_threads = True
    return server, note


def write_static(folder: str | Path, out: str | Path, command: str | None = None) -> dict:
    """``anima view DIR --static OUT``: the page as files (open ``OUT/index.html`` from disk)."""
    kind = detect(Path(folder))  # refuse a folder that holds no result before touching OUT
    check_out_dir(out, "--static")
    with OutputFolder(out, kind="view", command=command) as od:
        data = build_view(folder, od.path)
        for p in sorted(od.path.iterdir()):
            if p.is_file() and not p.name.startswith("."):
                od.add(p.name)
        od.info = {"kind": kind, "source": str(folder)}
    return {"kind": kind, "page": str(Path(out) / "index.html"), "notes": data["notes"]}


def serve(folder: str | Path, port: int | None = None, browser: bool = True, announce=print) -> int:
    """``anima view DIR``: build the page into a temporary folder and serve it until Ctrl-C / SIGTERM."""
    kind = detect(Path(folder))
    if port is not None and not 1 <= port <= 65535:
        raise InputError(f"--port {port}: expected 1 to 65535")
    root = Path(tempfile.mkdtemp(prefix="anima-view-"))
    server = None
    try:
        data = build_view(folder, root)
        server, note = open_server(root, port)
        url = f"http://{HOST}:{server.server_address[1]}/index.html"
        for n in ([note] if note else []) + data["notes"]:
            print(f"anima: note: {n}", file=sys.stderr)
        announce(f"anima view: {kind} {folder} at {url}  (Ctrl-C to stop)")
        sys.stdout.flush()
        has_screen = sys.platform != "linux" or os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
        if browser and has_screen:
            threading.Thread(target=webbrowser.open, args=(url,), daemon=True).start()
        server.serve_forever(poll_interval=0.2)
    except KeyboardInterrupt:
        pass
    finally:
        if server is not None:
            server.server_close()
        shutil.rmtree(root, ignore_errors=True)
    return 0
