"""Atomic file writes: every artifact writer goes through :func:`atomic_path`."""
from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_path(path: str | Path, suffix: str = ".tmp"):
    """Yield a temporary sibling of ``path`` to write; when the block succeeds it replaces ``path`` in one
    rename, so a reader (or a killed run) never sees a half-written file; when it fails it is removed.
    ``suffix`` keeps writers that add an extension happy (``np.savez`` needs ``.npz``)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + suffix)
    try:
        yield tmp
        tmp.replace(path)
    finally:
        if tmp.exists():
            tmp.unlink()
