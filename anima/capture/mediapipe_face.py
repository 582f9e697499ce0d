"""Moved to :mod:`anima.track.mediapipe` (get a tracker with ``anima.track.get``); these names stay for scripts
that import them from here."""

from anima.track.mediapipe import N_LANDMARKS, FaceMeshTracker

__all__ = ["N_LANDMARKS", "FaceMeshTracker"]
