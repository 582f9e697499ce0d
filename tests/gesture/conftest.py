"""The gesture tests share the session's real-clip dataset (``gesture_ds`` in tests/conftest.py)."""

import pytest


@pytest.fixture(scope="session")
def ds(gesture_ds):
    return gesture_ds


@pytest.fixture(scope="session")
def db(gesture_db):
    return gesture_db
