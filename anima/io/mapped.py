"""Memory-mapped caches of arrays a command would otherwise recompute or inflate on every start: one
folder of ``.npy`` files under ``$ANIMA_HOME/cache/<kind>/<key>/``, made once and atomically (written aside,
then renamed into place, a ``complete`` marker inside), read back with ``np.load(mmap_mode="r")`` so only the
pages used are read. The key must change with everything the arrays depend on."""

from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from anima.io.assets import user_dir


def cache_key(*parts) -> str:
    """A short key from anything printable (paths, sizes, times, versions)."""
    return hashlib.sha1("|".join(str(p) for p in parts).encode()).hexdigest()[:16]


def file_stamp(path: str | os.PathLike) -> str:
    """A file's resolved path, size and modification time: changes when the file does."""
    p = Path(path)
    st = p.stat()
    return f"{p.resolve()}|{st.st_size}|{st.st_mtime_ns}"


def mapped_arrays(kind: str, key: str, make: Callable[[], dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """The arrays ``make()`` returns, from the cache ``kind/key`` when it is there (memory-mapped, read-only),
    else made now and cached for the next call. Arrays must not hold Python objects. A cache that cannot be
    written (no space, read-only home) is skipped: the arrays are returned all the same."""
    folder = user_dir("cache", kind, key)
    if (folder / "complete").is_file():
        try:
            return {f.stem: np.load(f, mmap_mode="r", allow_pickle=False) for f in folder.glob("*.npy")}
        except (OSError, ValueError):
            pass  # damaged: made again below
    arrays = make()
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=".tmp-", dir=folder.parent))
        try:
            for k, v in arrays.items():
                np.save(tmp / f"{k}.npy", np.asarray(v), allow_pickle=False)
            (tmp / "complete").write_text(key)
            if folder.exists():  # a damaged earlier copy
                shutil.rmtree(folder, ignore_errors=True)
            os.replace(tmp, folder)
        except OSError:  # another process made it first, or the disk is full
            shutil.rmtree(tmp, ignore_errors=True)
    except OSError:
        pass
    return arrays
