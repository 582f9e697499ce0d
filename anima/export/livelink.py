"""``anima livelink SEQ --to HOST:PORT``: a sequence (capture, gesture, text2face) played into Unreal's Live
Link as an iPhone running Live Link Face would send it: one UDP packet per frame at the sequence's own rate
(:mod:`anima.io.livelink`), the same 61 values as ``arkit.csv`` (ARKit weights clamped to 0..1, head yaw,
pitch and roll in radians, the eyes 0)."""

from __future__ import annotations

import ipaddress
import socket
import time
import uuid
from pathlib import Path

import numpy as np

from anima.core.rotations import matrix_to_euler
from anima.errors import InputError
from anima.io.arkit import HEAD_COLUMNS, LIVE_LINK_COLUMNS, ict_to_arkit
from anima.io.livelink import pack
from anima.io.sequence import TrackedSequence, read_sequence


def livelink_values(seq: TrackedSequence) -> np.ndarray:
    """``[F, 61]``: the ARKit weights (0 where no face) and the head's yaw, pitch, roll, as ``arkit.csv``."""
    ark = np.clip(ict_to_arkit(np.asarray(seq.expression), list(seq.expr_names)), 0.0, 1.0)
    ark = ark * seq.tracked[:, None]
    head = np.zeros((seq.n_frames, len(HEAD_COLUMNS)))
    head[:, :3] = matrix_to_euler(seq.rotation_matrices())
    head[~seq.tracked] = 0.0
    assert ark.shape[1] == len(LIVE_LINK_COLUMNS)
    return np.concatenate([ark, head], 1)


def parse_target(to: str) -> tuple[str, int]:
    """``HOST:PORT`` (an IPv4/IPv6 address or a host name; port 1-65535) -> (host, port); InputError else."""
    host, sep, port = str(to).rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise InputError(f"--to {to!r}: expected HOST:PORT, e.g. 127.0.0.1:11111 (Live Link Face's port)")
    try:
        ipaddress.ip_address(host)
    except ValueError:
        try:
            socket.getaddrinfo(host, int(port), type=socket.SOCK_DGRAM)
        except OSError:
            raise InputError(f"--to {to!r}: cannot resolve {host}") from None
    return host, int(port)


def send(
    sequence: str | Path,
    to: str,
    subject: str = "anima",
    loops: int = 1,
    progress: bool = True,
) -> dict:
    """Send the sequence ``loops`` times, paced at its frame rate; returns what was sent (packets, seconds,
    packets per second)."""
    host, port = parse_target(to)
    if not subject or len(subject.encode()) > 256:
        raise InputError("--subject: a name of 1 to 256 bytes (Unreal lists the source under it)")
    if not 1 <= loops <= 10_000:
        raise InputError("--loops: 1 to 10000")
    seq = read_sequence(sequence, landmarks=False)
    if not seq.tracked.any():
        raise InputError(f"no frame of {sequence} has a face: Live Link Face carries a face")
    values = livelink_values(seq)
    device = str(uuid.uuid5(uuid.NAMESPACE_URL, f"anima:{subject}"))
    fps = int(round(seq.fps))
    sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_DGRAM)
    sent, t0 = 0, time.perf_counter()
    try:
        for k in range(loops):
            for i in range(seq.n_frames):
                due = t0 + (k * seq.n_frames + i) / seq.fps
                delay = due - time.perf_counter()
                if delay > 0:
                    time.sleep(delay)
                t = i / seq.fps * fps
                sock.sendto(pack(device, subject, int(t), t - int(t), fps, values[i]), (host, port))
                sent += 1
                if progress and sent % max(1, fps) == 0:
                    print(f"\ranima livelink: {sent} frames to {host}:{port}", end="", flush=True)
    except OSError as e:
        raise InputError(f"--to {to}: cannot send ({e.strerror or e})") from None
    finally:
        sock.close()
        if progress and sent >= fps:
            print(flush=True)
    wall = time.perf_counter() - t0
    return {"to": f"{host}:{port}", "subject": subject, "device_id": "$" + device, "packets": sent,
            "seconds": round(wall, 3), "packets_per_s": round(sent / max(wall, 1e-9), 2), "fps": seq.fps}  # fmt: skip
