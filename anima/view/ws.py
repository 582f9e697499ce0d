"""The smallest WebSocket server anima needs (RFC 6455, text frames from the server, no extensions): the live
page's feed. :class:`Broadcaster` keeps the connected pages; each gets its own writer thread and a queue of at
most :data:`QUEUE` messages, the oldest dropped first, so a slow or stalled browser never holds the tracking
loop back and memory never grows with it."""

from __future__ import annotations

import base64
import collections
import hashlib
import socket
import struct
import threading
import time

GUID = "258EAFA5-E914-47DA-95CA-C5AB0DC85B11"
QUEUE = 4
MAX_CLIENTS = 8
PING_S = 5.0
"""The server pings every page this often; a page that sends nothing (browsers answer a ping with a pong) for
:data:`IDLE_PINGS` pings, or does not read what it is sent for as long, is closed and its slot freed."""
IDLE_PINGS = 4
MAX_CLIENT_FRAME = 1 << 16  # what a page may send (it sends nothing but pings and a close)


def accept_key(key: str) -> str:
    """``Sec-WebSocket-Accept`` for a request's ``Sec-WebSocket-Key``."""
    return base64.b64encode(hashlib.sha1((key + GUID).encode("ascii")).digest()).decode("ascii")


def text_frame(payload: str, opcode: int = 0x1) -> bytes:
    """One unmasked, final frame (a server's frames are never masked): text, or with ``opcode`` 0x9 a ping."""
    data = payload.encode("utf-8")
    n = len(data)
    b0 = 0x80 | opcode
    if n < 126:
        head = struct.pack("!BB", b0, n)
    elif n < 1 << 16:
        head = struct.pack("!BBH", b0, 126, n)
    else:
        head = struct.pack("!BBQ", b0, 127, n)
    return head + data


PING = text_frame("", 0x9)


def _read_exact(sock: socket.socket, n: int) -> bytes | None:
    buf = b""
    while len(buf) < n:
        chunk = sock.recv(n - len(buf))
        if not chunk:
            return None
        buf += chunk
    return buf


def read_client_frames(sock: socket.socket) -> None:
    """Read (and drop) what a page sends until it closes or sends something out of bounds."""
    while True:
        head = _read_exact(sock, 2)
        if head is None:
            return
        opcode, n = head[0] & 0x0F, head[1] & 0x7F
        if n == 126:
            ext = _read_exact(sock, 2)
            n = struct.unpack("!H", ext)[0] if ext else 0
        elif n == 127:
            ext = _read_exact(sock, 8)
            n = struct.unpack("!Q", ext)[0] if ext else 0
        if n > MAX_CLIENT_FRAME or not head[1] & 0x80:  # too large, or unmasked: not a browser
            return
        if _read_exact(sock, 4 + n) is None or opcode == 0x8:
            return


class _Client:
    def __init__(self, sock: socket.socket, on_gone):
        self.sock, self.on_gone = sock, on_gone
        self.queue: collections.deque = collections.deque(maxlen=QUEUE)
        self.ready = threading.Condition()
        self.alive = True
        self.dropped = 0
        threading.Thread(target=self._write, daemon=True).start()

    def put(self, frame: bytes) -> None:
        with self.ready:
            if len(self.queue) == self.queue.maxlen:
                self.dropped += 1
            self.queue.append(frame)
            self.ready.notify()

    def _write(self) -> None:
        last_ping = time.monotonic()
        try:
            while self.alive:
                with self.ready:
                    while not self.queue and self.alive and time.monotonic() - last_ping < PING_S:
                        self.ready.wait(0.5)
                    frame = self.queue.popleft() if self.queue else None
                if time.monotonic() - last_ping >= PING_S:
                    last_ping = time.monotonic()
                    self.sock.sendall(PING)
                if frame is not None:
                    self.sock.sendall(frame)
        except OSError:  # gone, or not reading for PING_S * IDLE_PINGS: the slot is freed
            pass
        self.close()

    def close(self) -> None:
        if self.alive:
            self.alive = False
            try:
                self.sock.close()
            except OSError:
                pass
            self.on_gone(self)


class Broadcaster:
    """The pages connected to ``/TOKEN/live``; :meth:`send` queues a message for each."""

    def __init__(self):
        self.clients: set[_Client] = set()
        self.lock = threading.Lock()
        self.connections = 0
        self.pending = 0

    def reserve(self) -> bool:
        """Hold a slot for a page about to be upgraded (before the 101 answer); False when all are taken."""
        with self.lock:
            if len(self.clients) + self.pending >= MAX_CLIENTS:
                return False
            self.pending += 1
            return True

    def attach(self, sock: socket.socket) -> bool:
        """Serve one upgraded connection (its slot reserved by :meth:`reserve`) until it closes or goes idle
        (called on the server's request thread)."""
        with self.lock:
            self.pending = max(0, self.pending - 1)
            c = _Client(sock, self._gone)
            self.clients.add(c)
            self.connections += 1
        try:
            sock.settimeout(PING_S * IDLE_PINGS)  # reads (pongs) and writes alike: a silent page times out
            read_client_frames(sock)
        except OSError:
            pass
        c.close()
        return True

    def _gone(self, c: _Client) -> None:
        with self.lock:
            self.clients.discard(c)

    def send(self, message: str) -> int:
        """Queue ``message`` for every page; returns how many got it."""
        frame = text_frame(message)
        with self.lock:
            clients = list(self.clients)
        for c in clients:
            c.put(frame)
        return len(clients)

    def close(self) -> None:
        with self.lock:
            clients = list(self.clients)
        for c in clients:
            c.close()
