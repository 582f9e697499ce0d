"""UDP targets given on the command line (``--to``, ``--livelink``, ``--vmc``: ``HOST:PORT``), parsed with the
standard library and refused in one line before any work: an IPv4 address, an IPv6 address in brackets
(``[::1]:39539``), or a host name of RFC 1123 labels that resolves; a port of ASCII digits from 1 to 65535."""

from __future__ import annotations

import ipaddress
import re
import socket
from urllib.parse import urlsplit

from anima.errors import InputError

_LABEL = re.compile(r"[A-Za-z0-9](?:[A-Za-z0-9-]{0,61}[A-Za-z0-9])?$")


def parse_address(text: str, flag: str = "--to", example: str = "127.0.0.1:11111") -> tuple[str, int]:
    """``HOST:PORT`` -> ``(host, port)``; :class:`InputError` naming ``flag`` for anything else."""
    bad = InputError(f"{flag} {str(text)[:80]!r}: expected HOST:PORT, e.g. {example}")
    text = str(text)
    if not text or len(text) > 300 or not text.isprintable() or any(c in text for c in "/?#@ "):
        raise bad
    try:
        parts = urlsplit("//" + text)
        host, port = parts.hostname, parts.port
    except ValueError:
        raise bad from None
    if not host or port is None or not 1 <= port <= 65535:
        raise bad
    try:
        ipaddress.ip_address(host)
        return host, port
    except ValueError:
        pass
    if text.startswith("[") or len(host) > 253 or not all(_LABEL.match(x) for x in host.rstrip(".").split(".")):
        raise bad
    try:
        socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)
    except (OSError, UnicodeError):
        raise InputError(f"{flag} {text!r}: cannot resolve {host}") from None
    return host, port


def udp_socket(host: str) -> socket.socket:
    """A UDP socket of the address family of ``host``."""
    return socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_DGRAM)
