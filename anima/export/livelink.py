"""``anima livelink SEQ --to HOST:PORT``: a sequence (capture, gesture, text2face) played into Unreal's Live
Link as an iPhone running Live Link Face would send it: one UDP packet per frame at the sequence's own rate
(:mod:`anima.io.livelink`), the same 61 values as ``arkit.csv`` (ARKit weights clamped to 0..1, head yaw,
pitch and roll in radians, the eyes 0)."""

from __future__ import annotations

import time
import uuid
from pathlib import Path

import numpy as np

from anima.core.contract import EXPR_NAMES
from anima.core.rotations import matrix_to_euler, rotvec_to_matrix
from anima.errors import InputError
from anima.export.avatar import character_face
from anima.io.arkit import HEAD_COLUMNS, LIVE_LINK_COLUMNS, ict_to_arkit
from anima.io.livelink import pack
from anima.io.sequence import TrackedSequence, read_sequence
from anima.io.udp import parse_address, udp_socket


def livelink_rows(expression: np.ndarray, expr_names, rotation: np.ndarray, tracked: np.ndarray) -> np.ndarray:
    """``[F, 61]`` Live Link Face values: the ARKit weights of ``expression [F, 53]`` clamped to 0..1 and the
    head's yaw, pitch, roll from ``rotation [F, 3]`` (axis-angle), as ``arkit.csv``; frames not ``tracked``
    send 0, the eyes 0."""
    ark = np.clip(ict_to_arkit(np.asarray(expression, np.float64), list(expr_names)), 0.0, 1.0)
    tracked = np.asarray(tracked, bool)
    head = np.zeros((len(ark), len(HEAD_COLUMNS)))
    head[:, :3] = matrix_to_euler(rotvec_to_matrix(np.asarray(rotation, np.float64)))
    assert ark.shape[1] == len(LIVE_LINK_COLUMNS)
    return np.where(tracked[:, None], np.concatenate([ark, head], 1), 0.0)


def livelink_values(seq: TrackedSequence) -> np.ndarray:
    """``[F, 61]``: a sequence's Live Link Face values (:func:`livelink_rows`)."""
    return livelink_rows(character_face(seq), list(EXPR_NAMES), seq.rotation, seq.tracked)


class Sender:
    """Live Link Face packets to ``(host, port)`` under ``subject`` (one device id per subject, so Unreal keeps
    one source per subject)."""

    def __init__(self, target: tuple[str, int], subject: str = "anima"):
        self.target, self.subject = target, subject
        self.device = str(uuid.uuid5(uuid.NAMESPACE_URL, f"anima:{subject}"))
        self.sock = udp_socket(target[0])

    def send(self, index: int, fps: float, row: np.ndarray) -> None:
        """Frame ``index`` of a ``fps`` stream (the frame time in whole frames at the rounded rate)."""
        rate = int(round(fps))
        t = index / fps * rate
        self.sock.sendto(pack(self.device, self.subject, int(t), t - int(t), rate, row), self.target)

    def close(self) -> None:
        self.sock.close()


def parse_target(to: str, flag: str = "--to") -> tuple[str, int]:
    """``HOST:PORT`` (an IPv4 address, ``[IPv6]`` or a host name; port 1-65535) -> (host, port); InputError else
    (Live Link Face's port is 11111)."""
    return parse_address(to, flag, "127.0.0.1:11111 (Live Link Face's port)")


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
    seq = read_sequence(sequence)  # the landmarks too: the face the character shows
    if not seq.tracked.any():
        raise InputError(f"no frame of {sequence} has a face: Live Link Face carries a face")
    values = livelink_values(seq)
    out = Sender((host, port), subject)
    fps = int(round(seq.fps))
    sent, t0 = 0, time.perf_counter()
    try:
        for k in range(loops):
            for i in range(seq.n_frames):
                delay = t0 + (k * seq.n_frames + i) / seq.fps - time.perf_counter()
                if delay > 0:
                    time.sleep(delay)
                out.send(i, seq.fps, values[i])
                sent += 1
                if progress and sent % max(1, fps) == 0:
                    print(f"\ranima livelink: {sent} frames to {host}:{port}", end="", flush=True)
    except OSError as e:
        raise InputError(f"--to {to}: cannot send ({e.strerror or e})") from None
    finally:
        out.close()
        if progress and sent >= fps:
            print(flush=True)
    wall = time.perf_counter() - t0
    return {"to": f"{host}:{port}", "subject": subject, "device_id": "$" + out.device, "packets": sent,
            "seconds": round(wall, 3), "packets_per_s": round(sent / max(wall, 1e-9), 2), "fps": seq.fps}  # fmt: skip
