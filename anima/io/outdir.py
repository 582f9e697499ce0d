"""Result folders written as one unit (``--out DIR`` of capture, text2face, gesture, ...).

:class:`OutputFolder` is entered *before* any work starts, so a bad ``--out`` (an existing file, a
read-only folder) is refused at once, and:

* takes a lock (``DIR/.anima.lock``, ``flock``): a second run into the same folder is refused with a clear
  message instead of mixing two results;
* removes the previous run's ``manifest.json`` first, so while the folder is being rewritten no reader takes
  it for a complete result;
* every file is written atomically by its writer (``anima.io.atomic``);
* on success, files the previous run listed and this run did not write are removed (a reused folder keeps no
  stale output), then ``manifest.json`` is written **last**: the command, the anima version, and every file
  with its size and sha256. A folder with a manifest whose files match it is complete; anything else is
  partial (:func:`check_complete`).
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import tempfile
import time
from pathlib import Path

from anima import __version__
from anima.errors import InputError, SchemaError
from anima.io.atomic import remove_stale_temps, write_json

MANIFEST = "manifest.json"
LOCK = ".anima.lock"
SCHEMA = "anima.result"
VERSION = 1


def _can_create_in(folder: Path) -> bool:
    """Whether an entry can really be made in ``folder`` (tried, then removed: permissions, read-only file
    systems and pseudo file systems all answer)."""
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".anima-probe-", dir=folder))
        return True
    except OSError:
        return False


def check_out_dir(path: str | os.PathLike, flag: str = "--out") -> Path:
    """Refuse, before any work, an output folder that cannot be one: an existing file, or a place where it
    cannot be created or written."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise InputError(f"{flag} {p} is an existing file, not a folder")
    base = next((q for q in [p, *p.parents] if q.exists()), Path("."))
    if not base.is_dir() or not _can_create_in(base):
        raise InputError(f"{flag} {p}: cannot write in {base}")
    return p


def lock_folder(path: Path) -> int:
    """Create ``path`` and take its exclusive lock (``.anima.lock``, ``flock``: released by the kernel when the
    process dies, so a killed run never leaves the folder locked). A second holder is refused."""
    try:
        path.mkdir(parents=True, exist_ok=True)
        fd = os.open(path / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as e:
        raise InputError(f"--out {path}: cannot write there ({e.strerror or e})") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        raise InputError(
            f"--out {path}: another anima run is writing into this folder; wait for it or choose another --out"
        ) from None
    return fd


def unlock_folder(fd: int) -> None:
    fcntl.flock(fd, fcntl.LOCK_UN)
    os.close(fd)


def check_out_file(path: str | os.PathLike, flag: str = "--out") -> Path:
    """Refuse, before any work, an output file path that cannot be written: a folder, or a place where the
    file cannot be created."""
    p = Path(path)
    if p.is_dir():
        raise InputError(f"{flag} {p} is a folder: give a file path")
    base = next((q for q in p.parents if q.exists()), Path("."))
    if not base.is_dir() or not _can_create_in(base):
        raise InputError(f"{flag} {p}: cannot write in {base}")
    return p


def sha256(path: str | os.PathLike) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


class OutputFolder:
    """``with OutputFolder(out, kind="capture", command=...) as od: write(od.file("capture.npz")) ...``"""

    def __init__(self, path: str | os.PathLike, kind: str, command: str | None = None, info: dict | None = None):
        self.path = check_out_dir(path)
        self.kind, self.command = kind, command
        self.info = dict(info or {})
        self.files: list[str] = []
        self._lock_fd: int | None = None
        self._previous: list[str] = []

    def __enter__(self) -> OutputFolder:
        self._created = not self.path.exists()
        self._lock_fd = lock_folder(self.path)
        remove_stale_temps(self.path)
        old = self.path / MANIFEST
        if old.is_file():
            try:
                self._previous = list(read_manifest(self.path).get("files", {}))
            except (InputError, SchemaError):
                self._previous = []
            old.unlink()
        return self

    def file(self, name: str) -> Path:
        """The path of an output file of this run (registered for the manifest)."""
        if name not in self.files:
            self.files.append(name)
        return self.path / name

    def add(self, path: str | os.PathLike) -> Path:
        p = Path(path)
        return self.file(str(p.relative_to(self.path)) if p.is_absolute() else str(p))

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            if exc_type is None:
                self._finish()
        finally:
            if self._lock_fd is not None:
                unlock_folder(self._lock_fd)
                self._lock_fd = None
            if exc_type is not None and self._created:  # a failed first run leaves no empty folder behind
                remove_stale_temps(self.path)
                if [p.name for p in self.path.iterdir()] == [LOCK]:
                    (self.path / LOCK).unlink()
                    self.path.rmdir()

    def _finish(self) -> None:
        written = [n for n in self.files if (self.path / n).is_file()]
        for name in self._previous:
            if name not in written and name != MANIFEST:
                try:
                    (self.path / name).unlink()
                except (FileNotFoundError, IsADirectoryError):
                    pass
        manifest = {
            "schema": SCHEMA,
            "version": VERSION,
            "kind": self.kind,
            "command": self.command,
            "anima_version": __version__,
            "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            "info": self.info,
            "files": {n: {"bytes": (self.path / n).stat().st_size, "sha256": sha256(self.path / n)} for n in written},
        }
        write_json(self.path / MANIFEST, manifest)


def read_manifest(folder: str | os.PathLike) -> dict:
    import json

    p = Path(folder) / MANIFEST
    if not p.is_file():
        raise InputError(f"{folder}: no {MANIFEST} (not an anima result, or a run that did not finish)")
    try:
        m = json.loads(p.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, ValueError) as e:
        raise SchemaError(f"{p}: not valid JSON ({e})") from None
    if not isinstance(m, dict) or m.get("schema") != SCHEMA:
        raise SchemaError(f"{p}: not an anima result manifest")
    if int(m.get("version", -1)) > VERSION:
        raise SchemaError(f"{p}: result manifest version {m.get('version')} is newer than this anima; upgrade anima")
    return m


def check_complete(folder: str | os.PathLike, verify_hashes: bool = True) -> dict:
    """The manifest of a complete result folder; :class:`InputError` naming what is missing or changed."""
    m = read_manifest(folder)
    for name, rec in m.get("files", {}).items():
        p = Path(folder) / name
        if not p.is_file():
            raise InputError(f"{folder}: incomplete result: {name} is missing")
        if p.stat().st_size != rec.get("bytes") or (verify_hashes and sha256(p) != rec.get("sha256")):
            raise InputError(f"{folder}: incomplete result: {name} differs from the manifest")
    return m
