"""Result folders written as one unit (``--out DIR`` of capture, text2face, gesture, ...), and the rule that
anima deletes and overwrites only what it made.

**Ownership.** A folder is anima's when it holds anima's marker (``.anima-folder``, written by anima when it
creates or first claims the folder; it lists every file anima wrote there with its sha256) and, for a finished
result, nothing the marker does not list. ``--out`` may name a new folder, an empty one, or one of anima's; a
folder that holds files anima did not write (a copied marker included), or a file anima wrote that the user
has edited since, is refused before any work (:func:`check_out_dir`). A folder whose last run did not finish
(the marker's ``running``) is anima's as a whole, so the rerun completes it. A result folder of an older anima
(a valid result or dataset manifest, no marker) is adopted, but nothing in it is deleted.

:class:`OutputFolder` is entered *before* any work starts, so a bad ``--out`` (an existing file, a read-only
folder, a user's folder) is refused at once, and:

* takes a lock (``DIR/.anima.lock``, ``flock``): a second run into the same folder is refused with a clear
  message instead of mixing two results;
* removes the previous run's ``manifest.json`` first, so while the folder is being rewritten no reader takes
  it for a complete result;
* every file is written atomically by its writer (``anima.io.atomic``);
* on success, files the previous run wrote and this run did not are removed (a reused folder keeps no stale
  output), but only names from anima's own marker, confined to the folder (no ``..``, no absolute path, no
  symlink), and only while their content is still what anima wrote (same sha256); then ``manifest.json`` is
  written **last**: the command, the anima version, and every file with its size and sha256. A folder with a
  manifest whose files match it is complete; anything else is partial (:func:`check_complete`).

Single output files (``--out FILE``) are checked by :func:`check_out_file`: never a folder, a special file
(device, pipe, socket), a link, or a path that equals, holds or lies inside one of the command's inputs; the
suffix must be the format's; an existing file is replaced only while it matches the record anima keeps
beside it (:func:`record_out_file`), or, without one, when its content shows anima wrote it
(``anima.io.owned``). Output folders follow the same input rule (:func:`check_apart`).
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import stat
import tempfile
import time
from pathlib import Path

from anima import __version__
from anima.errors import InputError, SchemaError
from anima.io import owned
from anima.io.atomic import TMP_MARK, remove_stale_temps, write_json

MANIFEST = "manifest.json"
LOCK = ".anima.lock"
MARKER = ".anima-folder"
MARKER_SCHEMA = "anima.folder"
SCHEMA = "anima.result"
VERSION = 1
LEGACY_SCHEMAS = ("anima.result", "anima.dataset")  # manifests of result folders written before the marker
_MAX_MARKER_BYTES = 16 * 2**20


def _can_create_in(folder: Path) -> bool:
    """Whether an entry can really be made in ``folder`` (tried, then removed: permissions, read-only file
    systems and pseudo file systems all answer)."""
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".anima-probe-", dir=folder))
        return True
    except OSError:
        return False


def _is_transient(name: str) -> bool:
    """anima's own lock, marker and temporary files (not a user's content)."""
    return name in (LOCK, MARKER) or (name.startswith(".") and TMP_MARK in name) or name.startswith(".anima-probe-")


def read_marker(folder: Path) -> dict | None:
    """anima's marker of ``folder`` (``{"kind": ..., "files": {name: sha256}}``), or None when there is none or
    it is not one anima wrote (unreadable, another schema, a symlink)."""
    m = folder / MARKER
    try:
        st = os.lstat(m)
    except OSError:
        return None
    if not stat.S_ISREG(st.st_mode) or st.st_size > _MAX_MARKER_BYTES:
        return None
    try:
        d = json.loads(m.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError):
        return None
    if not isinstance(d, dict) or d.get("schema") != MARKER_SCHEMA or not isinstance(d.get("files"), dict):
        return None
    d["files"] = {k: v for k, v in d["files"].items() if isinstance(k, str) and isinstance(v, str)}
    return d


def _legacy_result(folder: Path) -> bool:
    """A result or dataset folder of an anima from before the marker: a readable manifest of anima's."""
    m = folder / MANIFEST
    try:
        if not stat.S_ISREG(os.lstat(m).st_mode) or m.stat().st_size > _MAX_MARKER_BYTES:
            return False
        d = json.loads(m.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError):
        return False
    return isinstance(d, dict) and d.get("schema") in LEGACY_SCHEMAS


MANAGED_KINDS = ("dataset", "text2face_run", "text2face_work", "eval_reenact", "pose_ablation")
"""Kinds of folder a command fills and keeps by its own layout (:func:`claim_folder`: a dataset, a training
run), not as a list of files; markers written before ``contents`` was recorded are told by their kind."""


def _managed(marker: dict) -> bool:
    return marker.get("contents", "managed" if marker.get("kind") in MANAGED_KINDS else "listed") == "managed"


def _anima_manifest(folder: Path) -> bool:
    try:
        read_manifest(folder)
        return True
    except (InputError, SchemaError, OSError):
        return False


def foreign_entries(folder: Path) -> list[str]:
    """The entries of an existing ``folder`` that make it a user's rather than anima's: everything but anima's
    own lock/marker/temporary files, unless the folder carries anima's marker (or is an older anima result).
    A marker lists the files of a finished result: an entry it does not list (nor anima's manifest) is not
    anima's, so a user's folder that gained a copied marker stays the user's. A folder whose last run did not
    finish (killed, failed) may hold files its marker does not list yet, and a folder a command fills by its
    own layout (a dataset, a training run) lists none: both are anima's as a whole."""
    try:
        names = sorted(os.listdir(folder))
    except OSError:
        return []
    user = [n for n in names if not _is_transient(n)]
    if not user:
        return []
    marker = read_marker(folder)
    if marker is None:
        return [] if _legacy_result(folder) else user
    if _managed(marker) or marker.get("running"):
        return []
    listed = {n.split("/")[0] for n in marker["files"]}
    return [n for n in user if n not in listed and not (n == MANIFEST and _anima_manifest(folder))
            and not _anima_subfolder(folder / n)]  # fmt: skip


def _anima_subfolder(p: Path) -> bool:
    """A folder (not a link) inside a result that is itself one of anima's (its own marker): another command's
    result written there (``./dev demo`` puts text2face's inside the capture's), anima's, never the user's."""
    try:
        return stat.S_ISDIR(os.lstat(p).st_mode) and read_marker(p) is not None
    except OSError:
        return False


def changed_entries(folder: Path) -> list[str]:
    """The files a finished result's marker lists whose content is no longer what anima wrote (a user edited
    them): anima neither replaces nor removes them."""
    marker = read_marker(folder)
    if marker is None or _managed(marker) or marker.get("running"):
        return []
    changed = []
    for name, digest in marker["files"].items():
        p = confined(folder, name)
        try:
            if p is not None and sha256(p) != digest:
                changed.append(name)
        except OSError:
            pass
    return changed


def check_apart(path: str | os.PathLike, inputs=(), flag: str = "--out") -> None:
    """Refuse an output that equals, contains or lies inside any of the command's ``inputs`` (links resolved;
    inputs that are not paths on disk, such as a camera index or a stream URL, are skipped): a command never
    writes over, into or around what it reads."""
    try:
        out = Path(os.path.realpath(path))
    except (OSError, ValueError):
        return
    for x in inputs:
        if x is None or not isinstance(x, (str, os.PathLike)) or not os.path.lexists(x):
            continue
        try:
            src = Path(os.path.realpath(x))
        except (OSError, ValueError):
            continue
        if out == src or same_file(path, x):
            raise InputError(f"{flag} {path} is an input of this command ({x}); write the result elsewhere")
        if src.is_relative_to(out):
            raise InputError(f"{flag} {path} holds {x}, an input of this command; write the result elsewhere")
        if out.is_relative_to(src):
            raise InputError(f"{flag} {path} lies inside {x}, an input of this command; write the result elsewhere")


def holds_nothing(folder: str | os.PathLike) -> bool:
    """Whether ``folder`` holds nothing but anima's own lock, marker and temporary files (or does not exist)."""
    try:
        return all(_is_transient(n) for n in os.listdir(folder))
    except FileNotFoundError:
        return True
    except OSError:
        return False


def check_out_dir(path: str | os.PathLike, flag: str = "--out", inputs=()) -> Path:
    """Refuse, before any work, an output folder that cannot be one: an existing file or special file, a place
    where it cannot be created or written, a folder that already holds files anima did not write, or one that
    equals, holds or lies inside an input of the command (:func:`check_apart`)."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        kind = "file" if p.is_file() else "special file (device, pipe or socket)"
        raise InputError(f"{flag} {p} is an existing {kind}, not a folder")
    check_apart(p, inputs, flag)
    base = next((q for q in [p, *p.parents] if q.exists()), Path("."))
    if not base.is_dir() or not _can_create_in(base):
        raise InputError(f"{flag} {p}: cannot write in {base}")
    if p.is_dir():
        foreign = foreign_entries(p)
        if foreign:
            raise InputError(
                f"{flag} {p} already holds files anima did not write ({_shown(foreign)}); anima writes only into a "
                "new or empty folder or one it made: give another folder"
            )
        changed = changed_entries(p)
        if changed:
            raise InputError(
                f"{flag} {p}: {_shown(changed)} changed since anima wrote {'them' if len(changed) > 1 else 'it'}; "
                "anima keeps your edits: move them away or give another folder"
            )
    return p


def _shown(names: list[str]) -> str:
    return ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")


def claim_folder(path: str | os.PathLike, kind: str, flag: str = "--out", inputs=()) -> Path:
    """Check ``path`` (:func:`check_out_dir`), create it and put anima's marker in it (kept when already
    there): from now on the folder is anima's."""
    p = check_out_dir(path, flag, inputs)
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(f"{flag} {p}: cannot write there ({e.strerror or e})") from None
    if read_marker(p) is None:
        write_marker(p, kind, {}, contents="managed")
    return p


def write_marker(folder: Path, kind: str, files: dict[str, str], running: bool = False, contents: str = "listed"):
    """anima's marker: the folder's kind, the files anima wrote (``name -> sha256``), whether a run is writing
    (or was killed writing), and whether ``files`` lists the folder's contents (``listed``) or the command
    keeps its own layout (``managed``)."""
    doc = {"schema": MARKER_SCHEMA, "version": 1, "kind": kind, "contents": contents, "files": files}
    write_json(folder / MARKER, doc | ({"running": True} if running else {}), indent=None)


def confined(folder: Path, name: str) -> Path | None:
    """``folder / name`` when ``name`` is a plain relative path that stays inside ``folder`` (no ``..``, no
    absolute path, no NUL, no symlink on the way) and names a regular file; else None."""
    if not name or "\x00" in name or os.path.isabs(name) or "\\" in name:
        return None
    parts = Path(name).parts
    if any(x in ("..", ".", "") for x in parts):
        return None
    p = folder
    for i, part in enumerate(parts):
        p = p / part
        try:
            st = os.lstat(p)
        except OSError:
            return None
        last = i == len(parts) - 1
        if stat.S_ISLNK(st.st_mode) or (not last and not stat.S_ISDIR(st.st_mode)):
            return None
        if last and not stat.S_ISREG(st.st_mode):
            return None
    return p


def remove_owned(folder: Path, files: dict[str, str], keep=()) -> list[str]:
    """Remove the files anima recorded (``{name: sha256}``) that are not in ``keep``: only names confined to
    ``folder`` whose content is still what anima wrote. Returns the names removed."""
    removed = []
    for name, digest in files.items():
        if name in keep or name in (MANIFEST, MARKER, LOCK):
            continue
        p = confined(folder, name)
        if p is None:
            continue
        try:
            if sha256(p) != digest:
                continue  # changed since anima wrote it: the user's now
            p.unlink()
            removed.append(name)
        except OSError:
            pass
    return removed


def lock_folder(path: Path) -> int:
    """Create ``path`` and take its exclusive lock (``.anima.lock``, ``flock``: released by the kernel when the
    process dies, so a killed run never leaves the folder locked). A second holder is refused."""
    try:
        path.mkdir(parents=True, exist_ok=True)
        fd = os.open(path / LOCK, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)
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


def same_file(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """Whether two paths name the same file (the same inode when both exist, else the same resolved path)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        try:
            return Path(a).resolve() == Path(b).resolve()
        except (OSError, RuntimeError):
            return False


_BY_SUFFIX = object()


def check_out_file(
    path: str | os.PathLike,
    flag: str = "--out",
    inputs=(),
    suffixes: tuple[str, ...] | None = None,
    ours=_BY_SUFFIX,
    what: str | None = None,
) -> Path:
    """The one rule of a single-file output, checked before any work: refuse a folder, a special file (device,
    pipe, socket: a rename would replace the node), a path that equals, holds or lies inside one of the
    command's ``inputs``, a name without one of ``suffixes`` (when given), a place where the file cannot be
    created, and an existing file that anima did not write. ``ours(path)`` says whether an existing file is one
    of anima's of this kind, by its content (default: the check of its suffix, ``anima.io.owned.BY_SUFFIX``;
    ``None``: no existing file may be replaced)."""
    p = Path(path)
    if p.is_dir():
        raise InputError(f"{flag} {p} is a folder: give a file path")
    if p.exists() and not p.is_file():
        raise InputError(f"{flag} {p} is a special file (device, pipe or socket), not a file anima may replace")
    if suffixes is not None and p.suffix.lower() not in suffixes:
        raise InputError(f"{flag} {p}: expected a {' or '.join(suffixes)} file")
    check_apart(p, inputs, flag)
    base = next((q for q in p.parents if q.exists()), Path("."))
    if not base.is_dir() or not _can_create_in(base):
        raise InputError(f"{flag} {p}: cannot write in {base}")
    if ours is _BY_SUFFIX:
        ours = owned.BY_SUFFIX.get(p.suffix.lower())
    kind = what or (f"a {p.suffix.lower().lstrip('.')} file" if p.suffix else "a file")
    if p.exists() or p.is_symlink():
        if p.is_symlink():
            raise InputError(f"{flag} {p} is a link; anima replaces only a file it wrote: choose another path")
        if owned.read_record(p) is not None:  # anima recorded what it wrote: the whole file must still be that
            if not owned.recorded(p):
                raise InputError(f"{flag} {p} was changed since anima wrote it; anima keeps it: choose another path")
        else:
            check_replaceable(p, flag, ours or (lambda q: False), kind)
    rec = owned.record_path(p)
    if os.path.lexists(rec) and owned.read_record(p) is None:
        raise InputError(f"{flag} {p}: {rec.name} beside it is not anima's record; anima keeps it: choose another path")
    return p


def record_out_file(path: str | os.PathLike, kind: str | None = None) -> Path:
    """After a single-file output is written: its record beside it (``anima.io.owned.write_record``), so a
    later run may replace it while, and only while, it is unchanged."""
    owned.write_record(path, kind)
    return Path(path)


def check_replaceable(path: Path, flag: str, ours, what: str) -> Path:
    """Refuse an existing ``path`` that ``ours(path)`` does not recognise as anima's ``what`` (an output file
    anima would replace must be one it wrote: never a user's file that happens to carry the name)."""
    if path.exists():
        try:
            ok = bool(ours(path))
        except Exception:
            ok = False
        if not ok:
            raise InputError(f"{flag} {path} exists and is not {what} anima wrote; choose another path")
    return path


def sha256(path: str | os.PathLike) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


class OutputFolder:
    """``with OutputFolder(out, kind="capture", command=...) as od: write(od.file("capture.npz")) ...``"""

    def __init__(
        self, path: str | os.PathLike, kind: str, command: str | None = None, info: dict | None = None, inputs=(),
        flag: str = "--out",
    ):  # fmt: skip
        self.inputs, self.flag = [x for x in inputs if x is not None], flag
        self.path = check_out_dir(path, flag, self.inputs)
        self.kind, self.command = kind, command
        self.info = dict(info or {})
        self.files: list[str] = []
        self._lock_fd: int | None = None
        self._previous: dict[str, str] = {}

    def __enter__(self) -> OutputFolder:
        self._created = not self.path.exists()
        check_out_dir(self.path, self.flag, self.inputs)  # again: the folder may have changed since the start
        self._lock_fd = lock_folder(self.path)
        try:
            remove_stale_temps(self.path)
            marker = read_marker(self.path)
            self._previous = dict(marker["files"]) if marker else {}
            write_marker(self.path, self.kind, self._previous, running=True)  # until the run finishes
            old = self.path / MANIFEST
            if old.is_file() and not old.is_symlink():
                old.unlink()
        except BaseException:
            self._release(failed=True)
            raise
        return self

    def file(self, name: str) -> Path:
        """The path of an output file of this run (registered for the manifest)."""
        if name not in self.files:
            self.files.append(name)
        return self.path / name

    def journal(self, files: dict[str, str]) -> None:
        """Files written while the run goes on (``name -> sha256``, e.g. a live take's parts) are listed in
        anima's marker now, beside the previous run's files: a run killed before it finishes leaves a folder
        that is still anima's, whose partial files anima may use or remove."""
        write_marker(self.path, self.kind, self._previous | files, running=True)

    def add(self, path: str | os.PathLike) -> Path:
        p = Path(path)
        return self.file(str(p.relative_to(self.path)) if p.is_absolute() else str(p))

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            if exc_type is None:
                self._finish()
        finally:
            self._release(failed=exc_type is not None)

    def _release(self, failed: bool) -> None:
        if self._lock_fd is not None:
            unlock_folder(self._lock_fd)
            self._lock_fd = None
        if failed and self._created:  # a failed first run leaves no empty folder behind
            remove_stale_temps(self.path)
            if {p.name for p in self.path.iterdir()} <= {LOCK, MARKER}:
                for n in (LOCK, MARKER):
                    (self.path / n).unlink(missing_ok=True)
                self.path.rmdir()

    def _finish(self) -> None:
        written = {}
        for n in self.files:
            p = confined(self.path, n)
            if p is not None:
                written[n] = sha256(p)
        remove_owned(self.path, self._previous, keep=written)
        write_marker(self.path, self.kind, written)
        manifest = {
            "schema": SCHEMA,
            "version": VERSION,
            "kind": self.kind,
            "command": self.command,
            "anima_version": __version__,
            "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            "info": self.info,
            "files": {n: {"bytes": (self.path / n).stat().st_size, "sha256": h} for n, h in written.items()},
        }
        write_json(self.path / MANIFEST, manifest)


def read_manifest(folder: str | os.PathLike) -> dict:
    p = Path(folder) / MANIFEST
    if not p.is_file():
        raise InputError(f"{folder}: no {MANIFEST} (not an anima result, or a run that did not finish)")
    if p.stat().st_size > _MAX_MARKER_BYTES:
        raise SchemaError(f"{p}: {p.stat().st_size / 2**20:.0f} MB, too large for a result manifest")
    try:
        m = json.loads(p.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as e:
        raise SchemaError(f"{p}: not valid JSON ({str(e)[:120]})") from None
    if not isinstance(m, dict) or m.get("schema") != SCHEMA:
        raise SchemaError(f"{p}: not an anima result manifest")
    try:
        version = int(m.get("version", -1))
    except (TypeError, ValueError):
        raise SchemaError(f"{p}: result manifest version {m.get('version')!r} is not a number") from None
    if version > VERSION:
        raise SchemaError(f"{p}: result manifest version {m.get('version')} is newer than this anima; upgrade anima")
    if not isinstance(m.get("files", {}), dict):
        raise SchemaError(f"{p}: its files are not a table")
    return m


def check_complete(folder: str | os.PathLike, verify_hashes: bool = True) -> dict:
    """The manifest of a complete result folder; :class:`InputError` naming what is missing or changed."""
    m = read_manifest(folder)
    for name, rec in m.get("files", {}).items():
        p = confined(Path(folder), name)
        if p is None:
            raise InputError(f"{folder}: incomplete result: {name} is missing")
        if not isinstance(rec, dict):
            raise SchemaError(f"{folder}: the manifest's record of {name} is not a table")
        if p.stat().st_size != rec.get("bytes") or (verify_hashes and sha256(p) != rec.get("sha256")):
            raise InputError(f"{folder}: incomplete result: {name} differs from the manifest")
    return m
