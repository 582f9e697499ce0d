"""Where each tracked frame goes (``anima live``): the page's WebSocket always, and the optional outputs of
:data:`SINKS` (a table: config field -> the sink it makes): Live Link Face packets to Unreal (``--livelink``)
and VMC protocol bundles to VTuber apps (``--vmc``). A sink's ``send`` never stops the take: a receiver that
goes away costs its packets (counted in ``unsent``), not the tracking. Adding an output is one class and one
entry of the table."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from anima.core import rig
from anima.core.contract import EXPR_NAMES
from anima.export.livelink import Sender, livelink_rows, parse_target
from anima.export.vmc import VmcSender, blend_values, parse_vmc
from anima.export.vrm import arkit_weights
from anima.io.udp import distinct_targets
from anima.live.take import LiveFrame


class LiveLinkSink:
    """The face as Live Link Face packets (``--livelink HOST:PORT``)."""

    name = "livelink"

    def __init__(self, target: tuple[str, int], rest: np.ndarray):
        self.out = Sender(target)
        self.sent = self.unsent = 0

    def send(self, f: LiveFrame, fps: float) -> None:
        try:
            self.out.send(f.index, fps, livelink_rows(f.shown[None], EXPR_NAMES, f.rotation[None], [f.face])[0])
            self.sent += 1
        except OSError:
            self.unsent += 1

    def close(self) -> None:
        self.out.close()

    def report(self) -> dict:
        return {"packets_sent": self.sent, "unsent": self.unsent}


class VmcSink:
    """Every frame as one VMC bundle (``--vmc HOST:PORT``): the humanoid bones, the hips where the legs stand
    them (:meth:`anima.live.tracker.LiveTracker.standing_root`), the ARKit blend values and the VRM presets
    (:mod:`anima.export.vmc`)."""

    name = "vmc"

    def __init__(self, target: tuple[str, int], rest: np.ndarray):
        self.out = VmcSender(target, rest)
        self.hips = rest[rig.HIPS]

    def send(self, f: LiveFrame, fps: float) -> None:
        arkit = arkit_weights(f.shown[None], list(EXPR_NAMES)) * float(f.face)
        hips = self.hips if f.root is None else f.root
        self.out.send(f.local, hips, blend_values(arkit)[0], f.face or f.body is not None)

    def close(self) -> None:
        self.out.close()

    def report(self) -> dict:
        return {"bundles_sent": self.out.sent, "unsent": self.out.unsent}


SINKS: dict[str, tuple[Callable[[str, str], tuple[str, int]], type]] = {
    "livelink": (parse_target, LiveLinkSink),
    "vmc": (parse_vmc, VmcSink),
}
"""Config field -> (its address parser, its sink). Addresses are parsed before tracking starts."""


def check_sinks(cfg) -> dict[str, tuple[str, int]]:
    """The optional outputs a config asks for, their addresses parsed (one line, exit 2, for a bad one, one that
    cannot be sent to, or two outputs on one address and port: :mod:`anima.io.udp`)."""
    asked = [k for k in SINKS if getattr(cfg, k, None) is not None]
    targets = {k: SINKS[k][0](getattr(cfg, k), f"--{k}") for k in asked}
    distinct_targets({f"--{k}": t for k, t in targets.items()})
    return targets


def open_sinks(targets: dict[str, tuple[str, int]], rest: np.ndarray) -> list:
    return [SINKS[k][1](t, rest) for k, t in targets.items()]
