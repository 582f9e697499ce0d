"""Trackers (MediaPipe), face-model fitting, smoothing and quality flags; ``capture_video`` runs them all."""
