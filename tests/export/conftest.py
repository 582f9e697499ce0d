"""Real captures shared by the rig and retarget tests (captured once for the package)."""

import pytest

from anima.io.assets import asset

PATS = ["oliver1", "seth3", "noah1", "chem1"]


@pytest.fixture(scope="package")
def captures():
    """Four PATS clips (body, hands, face, speech), 90 frames each, captured with the real pipeline."""
    from anima.capture.config import CaptureConfig
    from anima.capture.pipeline import capture_video

    return {
        n: capture_video(
            str(asset(f"gesture-video/pats-crops/{n}_gt.mp4")), CaptureConfig(max_frames=90), progress=False
        )
        for n in PATS
    }
