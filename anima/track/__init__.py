"""Trackers: the models that find faces, bodies and hands in frames. Every other part of anima gets its tracker
here (:func:`get`), never from a tracker library itself.

:data:`TRACKERS` is the table of trackers by name (the ``--tracker`` option of ``anima capture`` and ``anima
live``); each implements :class:`anima.track.base.Tracker`. Today it holds ``mediapipe``
(:mod:`anima.track.mediapipe`). docs/architecture.md says how to add one.
"""

from __future__ import annotations

from anima.errors import InputError
from anima.track.base import FaceBox, Hand, HolisticFrame, Model, PoseFrame, Tracker
from anima.track.mediapipe import MediaPipe

DEFAULT = "mediapipe"
TRACKERS: dict[str, Tracker] = {"mediapipe": MediaPipe()}


def get(name: str = DEFAULT) -> Tracker:
    """The tracker named ``name`` (a key of :data:`TRACKERS`); an unknown name is an :class:`InputError`."""
    try:
        return TRACKERS[name]
    except KeyError:
        raise InputError(f"unknown tracker {name!r}: use {', '.join(TRACKERS)}") from None


__all__ = ["DEFAULT", "TRACKERS", "FaceBox", "Hand", "HolisticFrame", "Model", "PoseFrame", "Tracker", "get"]
