"""Atomic file writes: every file anima writes goes through :func:`atomic_path` (or the helpers below).

A writer gets a temporary sibling of the target with a unique name (process id + random token, so two
writers of one path never share a temporary file), writes it, and on success the file is flushed to disk
(fsync) and renamed over the target in one step; the folder entry is fsynced too. A reader, or a run killed
at any moment, sees either the previous complete file or the new complete file, never a partial one. On
failure the temporary file is removed and the target is left as it was.
"""

from __future__ import annotations

import json
import os
import secrets
from contextlib import contextmanager
from pathlib import Path

TMP_MARK = ".anima-tmp-"


def temp_sibling(path: str | os.PathLike) -> Path:
    """A unique temporary name in the target's folder that keeps the target's extension (writers such as
    ``np.savez`` and ffmpeg pick the format from it): ``.<name>.anima-tmp-<pid>-<token><ext>``."""
    path = Path(path)
    return path.with_name(f".{path.stem}{TMP_MARK}{os.getpid()}-{secrets.token_hex(4)}{path.suffix}")


def fsync_file(path: str | os.PathLike) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def fsync_dir(folder: str | os.PathLike) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:  # some file systems cannot sync a directory
        pass
    finally:
        os.close(fd)


def commit(tmp: str | os.PathLike, path: str | os.PathLike) -> Path:
    """fsync ``tmp`` and rename it over ``path`` (same folder)."""
    fsync_file(tmp)
    os.replace(tmp, path)
    fsync_dir(Path(path).parent)
    return Path(path)


@contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None):
    """Yield a unique temporary sibling of ``path`` to write; when the block succeeds it replaces ``path``
    (fsync + rename); when it fails it is removed. ``suffix`` is accepted for old callers and ignored: the
    temporary name always ends with the target's own extension."""
    del suffix
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temp_sibling(path)
    try:
        yield tmp
        if not tmp.exists():
            raise FileNotFoundError(f"the writer of {path} wrote nothing")
        commit(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
    return Path(path)


def write_text(path: str | os.PathLike, text: str) -> Path:
    return write_bytes(path, text.encode("utf-8"))


def copy_file(src: str | os.PathLike, dst: str | os.PathLike, keep_mode: bool = False) -> Path:
    """Copy ``src`` to ``dst`` atomically; ``keep_mode``: with ``src``'s permission bits (a user's file copied
    into a result keeps its privacy; files anima made get the usual 0644 under the umask)."""
    import shutil

    with atomic_path(dst) as tmp:
        shutil.copyfile(src, tmp)
        if keep_mode:
            shutil.copymode(src, tmp)
    return Path(dst)


def write_npz(path: str | os.PathLike, compressed: bool = True, **arrays) -> Path:
    """Arrays as an ``.npz`` at ``path`` (any name: numpy writes into an open file, so it adds no ``.npz`` to
    the name), atomically."""
    import numpy as np

    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        (np.savez_compressed if compressed else np.savez)(fh, **arrays)
    return Path(path)


def write_json(path: str | os.PathLike, obj, indent: int | None = 2) -> Path:
    return write_text(path, json.dumps(obj, indent=indent) + "\n")


def remove_stale_temps(folder: str | os.PathLike) -> int:
    """Remove temporary files a killed writer left in ``folder`` (never a complete artifact)."""
    n = 0
    for p in Path(folder).glob(f".*{TMP_MARK}*"):
        try:
            p.unlink()
            n += 1
        except OSError:
            pass
    return n


def write_image(path: str | os.PathLike, rgb) -> Path:
    """An RGB uint8 image ``(H, W, 3)`` as PNG/JPEG (by extension), atomically."""
    import cv2
    import numpy as np

    ok, buf = cv2.imencode(Path(path).suffix or ".png", np.ascontiguousarray(np.asarray(rgb)[..., ::-1]))
    if not ok:
        raise ValueError(f"cannot encode an image as {Path(path).suffix}")
    return write_bytes(path, buf.tobytes())


def write_figure(path: str | os.PathLike, fig, **savefig_kw) -> Path:
    """A matplotlib figure, atomically (format from the extension)."""
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format=Path(path).suffix.lstrip(".") or "png", **savefig_kw)
    return write_bytes(path, buf.getvalue())
