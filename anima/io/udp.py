"""UDP targets given on the command line (``--to``, ``--livelink``, ``--vmc``: ``HOST:PORT``), parsed with the
standard library and refused in one line before any work: an IPv4 address, an IPv6 address in brackets
(``[::1]:39539``), or a host name of RFC 1123 labels that resolves; a port of ASCII digits from 1 to 65535.

An address packets cannot be sent to is refused too (:func:`unsendable`): the unspecified address (``0.0.0.0``,
``::``: a listening side's "every interface", no one's address), a broadcast address (``255.255.255.255``, or a
network's own broadcast address where this machine's routes say so), a multicast group, an IPv4 address of
``0.0.0.0/8`` or ``240.0.0.0/4``, and whatever this machine's routes refuse to reach (an IPv6 link-local address
without its interface, a network with no route). Two outputs of one command on the same resolved address and port
are refused (:func:`distinct_targets`): one receiver would get both streams."""

from __future__ import annotations

import ipaddress
import re
import socket
from urllib.parse import urlsplit

from anima.errors import InputError

_LABEL = re.compile(r"[A-Za-z0-9](?:[A-Za-z0-9-]{0,61}[A-Za-z0-9])?$")
_THIS_NETWORK = ipaddress.ip_network("0.0.0.0/8")


def parse_address(text: str, flag: str = "--to", example: str = "127.0.0.1:11111") -> tuple[str, int]:
    """``HOST:PORT`` -> ``(host, port)``; :class:`InputError` naming ``flag`` for anything else, and for an
    address packets cannot be sent to (:func:`unsendable`)."""
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
    except ValueError:
        if text.startswith("[") or len(host) > 253 or not all(_LABEL.match(x) for x in host.rstrip(".").split(".")):
            raise bad from None
    for addr in resolve(host, port, flag, text):
        why = unsendable(addr)
        if why:
            raise InputError(f"{flag} {text!r}: packets cannot be sent to {addr[0]} ({why}); give the receiver's "
                             f"own address, e.g. {example}")  # fmt: skip
    return host, port


def resolve(host: str, port: int, flag: str = "--to", text: str | None = None) -> list[tuple]:
    """The socket addresses (``(ip, port)``, or ``(ip, port, flow, scope)`` for IPv6) ``host`` is sent to by
    :func:`udp_socket`'s socket (IPv4 for a host name, as the socket is); :class:`InputError` when there is
    none."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    try:
        infos = socket.getaddrinfo(host, port, family, socket.SOCK_DGRAM)
    except (OSError, UnicodeError):
        infos = []
    addrs = list(dict.fromkeys(i[4] for i in infos))
    if not addrs:
        try:
            other = family == socket.AF_INET and socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)
        except (OSError, UnicodeError):
            other = False
        raise InputError(f"{flag} {text or host!r}: cannot resolve {host}" + (" to an IPv4 address" if other else ""))
    return addrs


def unsendable(addr: tuple) -> str | None:
    """Why UDP packets cannot be sent to the socket address ``addr`` (:func:`resolve`), or None: what the address
    itself says (``ipaddress``), then what this machine's routes say (a UDP ``connect``, which sends nothing)."""
    a = ipaddress.ip_address(addr[0].split("%")[0])
    v4 = a if a.version == 4 else a.ipv4_mapped
    if a.is_unspecified or (v4 is not None and v4.is_unspecified):
        return "the unspecified address: a listening side's 'every interface', no one's address"
    if v4 is not None and v4 in _THIS_NETWORK:
        return "an address of 0.0.0.0/8, no one's address"
    if v4 is not None and v4 == ipaddress.IPv4Address("255.255.255.255"):
        return "the broadcast address"
    if a.is_multicast or (v4 is not None and v4.is_multicast):
        return "a multicast group, not a receiver"
    if v4 is not None and v4.is_reserved:
        return "a reserved address (240.0.0.0/4)"
    with socket.socket(socket.AF_INET6 if a.version == 6 else socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.connect(addr)
        except PermissionError:
            return "a broadcast address"
        except OSError as e:
            return f"this machine cannot send there: {e.strerror or e}"
    return None


def distinct_targets(targets: dict[str, tuple[str, int]]) -> None:
    """Refuse two outputs (``{flag: (host, port)}``, parsed) that resolve to one address and port."""
    seen: dict[tuple[str, int], str] = {}
    for flag, (host, port) in targets.items():
        for addr in resolve(host, port, flag):
            a = ipaddress.ip_address(addr[0].split("%")[0])
            ip = str(getattr(a, "ipv4_mapped", None) or a)  # [::ffff:127.0.0.1] is 127.0.0.1
            other = seen.setdefault((ip, port), flag)
            if other != flag:
                raise InputError(
                    f"{other} and {flag} both send to {ip}:{port}: one receiver would get both streams; give each "
                    "output its own port (Live Link Face listens on 11111, VMC receivers on 39539)"
                )


def udp_socket(host: str) -> socket.socket:
    """A UDP socket of the address family of ``host``."""
    return socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_DGRAM)
