"""Fixtures of the studio's tests: the real clips they send."""

from pathlib import Path

import pytest
from studio_client import CLIP, SHORT

from anima.io.assets import asset


@pytest.fixture(scope="module")
def clip() -> bytes:
    return asset(CLIP).read_bytes()


@pytest.fixture(scope="module")
def short_clip() -> Path:
    return asset(SHORT)
