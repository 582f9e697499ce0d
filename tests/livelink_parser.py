"""A Live Link Face parser on 127.0.0.1 for the tests of ``anima livelink`` and ``anima live --livelink``."""

import socket
import threading
import time

from anima.io.livelink import unpack


class LiveLinkParser:
    """A Live Link Face parser on 127.0.0.1 (a free port): ``with LiveLinkParser() as rx:`` then ``rx.port``;
    after the block ``rx.packets`` holds ``(arrival perf_counter, fields)`` of every packet (the block ends when
    none came for ``idle_s``)."""

    def __init__(self, idle_s: float = 5.0):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(idle_s)
        self.port = self.sock.getsockname()[1]
        self.packets: list = []

    def _listen(self) -> None:
        while True:
            try:
                data = self.sock.recvfrom(4096)[0]
            except TimeoutError:
                return
            self.packets.append((time.perf_counter(), unpack(data)))

    def __enter__(self):
        self.th = threading.Thread(target=self._listen, daemon=True)
        self.th.start()
        return self

    def __exit__(self, *exc):
        self.th.join()
        self.sock.close()
