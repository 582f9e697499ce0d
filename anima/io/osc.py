"""Open Sound Control 1.0 packets (what the VMC protocol sends over UDP): messages of strings, 32-bit integers
and 32-bit floats, and bundles of messages. One writer (:func:`message`, :func:`bundle`) and one reader
(:func:`parse`, for tests and tools); big-endian, every part padded to 4 bytes, as the specification says
(opensoundcontrol.stanford.edu/spec-1_0)."""

from __future__ import annotations

import struct

import numpy as np

_BUNDLE = b"#bundle\0"
IMMEDIATELY = 1  # the OSC time tag meaning "now"


def _pad(b: bytes) -> bytes:
    return b + b"\0" * (4 - len(b) % 4)


def _string(s: str) -> bytes:
    return _pad(s.encode("ascii"))


def message(address: str, *args) -> bytes:
    """One OSC message: ``address`` and its arguments (``str`` -> ``s``, ``int`` -> ``i``, ``float`` -> ``f``;
    a bool is refused, being neither)."""
    tags, data = ",", b""
    for a in args:
        if isinstance(a, bool):
            raise TypeError("OSC has no bool argument here: send an int")
        if isinstance(a, str):
            tags += "s"
            data += _string(a)
        elif isinstance(a, int):
            tags += "i"
            data += struct.pack(">i", a)
        else:
            tags += "f"
            data += struct.pack(">f", float(a))
    return _string(address) + _string(tags) + data


class FloatMessages:
    """Messages whose address and leading arguments never change and whose last ``n`` arguments are floats:
    each head encoded once by :func:`message`, the floats of all of them packed per call in one numpy pass
    (a VMC frame's bones and blend values at a fraction of :func:`message`'s cost; the same bytes)."""

    def __init__(self, heads: list[tuple], n: int):
        if n < 1:
            raise ValueError("FloatMessages needs at least one float argument")
        self.n = n
        self.heads = [message(*h, *[0.0] * n)[: -4 * n] for h in heads]

    def encode(self, values) -> list[bytes]:
        """``values [len(heads), n]`` -> the encoded messages, in the heads' order."""
        k = 4 * self.n
        b = np.asarray(values, np.float64).reshape(len(self.heads), self.n).astype(">f4").tobytes()
        return [h + b[i * k : (i + 1) * k] for i, h in enumerate(self.heads)]


def bundle(messages: list[bytes], timetag: int = IMMEDIATELY) -> bytes:
    """An OSC bundle of encoded ``messages`` (each prefixed by its size)."""
    return _BUNDLE + struct.pack(">Q", timetag) + b"".join(struct.pack(">i", len(m)) + m for m in messages)


def _read_string(data: bytes, i: int) -> tuple[str, int]:
    end = data.index(b"\0", i)
    return data[i:end].decode("ascii"), (end // 4 + 1) * 4


def parse(data: bytes) -> list[tuple[str, list]]:
    """Every message of a packet (a message or a bundle, nested bundles flattened) as ``(address, args)``;
    ``ValueError`` for what is not OSC."""
    if data.startswith(_BUNDLE):
        out, i = [], 16
        while i < len(data):
            (n,) = struct.unpack(">i", data[i : i + 4])
            if n <= 0 or i + 4 + n > len(data):
                raise ValueError("an OSC bundle element runs past the packet")
            out += parse(data[i + 4 : i + 4 + n])
            i += 4 + n
        return out
    address, i = _read_string(data, 0)
    if not address.startswith("/"):
        raise ValueError(f"not an OSC address: {address[:40]!r}")
    tags, i = _read_string(data, i)
    if not tags.startswith(","):
        raise ValueError("no OSC type tags")
    args: list = []
    for t in tags[1:]:
        if t == "s":
            s, i = _read_string(data, i)
            args.append(s)
        elif t in "if":
            args.append(struct.unpack(">i" if t == "i" else ">f", data[i : i + 4])[0])
            i += 4
        else:
            raise ValueError(f"OSC type {t!r} is not one anima reads")
    return [(address, args)]
