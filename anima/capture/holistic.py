"""Moved to :mod:`anima.track` (get a tracker with ``anima.track.get``); these names stay for scripts that
import them from here."""

from anima.track.base import HolisticFrame
from anima.track.mediapipe import HolisticTracker

__all__ = ["HolisticFrame", "HolisticTracker"]
