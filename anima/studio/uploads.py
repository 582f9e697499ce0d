"""What a person sends the studio: a ``multipart/form-data`` body read as a stream (files written straight to
disk under names the studio chooses, never the upload's own; every part and the whole bounded), and the check of
each file's real content before a job is made of it: a video or a speech file must be one ffmpeg reads, an avatar
a glTF binary (``.glb``) or a VRM that anima's glTF reader accepts. The name and the type a browser gives are not
trusted: the suffix a file gets is the one its content shows."""

from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

from anima.errors import AnimaError, InputError
from anima.io.atomic import commit, temp_sibling
from anima.io.gltf_read import read_gltf
from anima.io.video import FFMPEG, probe_video

FILE_FIELDS = ("file", "avatar")
TEXT_FIELDS = ("kind", "prompt", "source", "options")
MAX_TEXT = 16_384
"""The longest a text field may be (a prompt is at most 2,000 characters)."""
MAX_PARTS = 16
MAX_HEADER = 8_192
CHUNK = 1 << 16
_BOUNDARY = re.compile(r'boundary="?([A-Za-z0-9\'()+_,./:=? -]{1,70})"?(?:;|$)')
_DISPOSITION = re.compile(r'form-data;\s*name="([a-z_]{1,32})"(;\s*filename="[^"\r\n]*")?\s*$', re.I)


class UploadError(Exception):
    """A request body the studio refuses before any job is made: ``status`` (HTTP) and a one-line reason."""

    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status = status


def boundary_of(content_type: str) -> bytes:
    if not content_type.lower().startswith("multipart/form-data"):
        fields = ", ".join(TEXT_FIELDS + FILE_FIELDS)
        raise UploadError(415, f"send the job as multipart/form-data (fields: {fields})")
    m = _BOUNDARY.search(content_type)
    if not m:
        raise UploadError(400, "multipart/form-data without a boundary")
    return m.group(1).strip().encode()


class Body:
    """At most ``length`` bytes of ``rfile``: reading past them, or a body that ends early, is an error."""

    def __init__(self, rfile, length: int):
        self.rfile, self.left = rfile, length

    def read(self, n: int) -> bytes:
        n = min(n, self.left)
        if n <= 0:
            raise UploadError(400, "the form ends before its closing boundary")
        try:
            data = self.rfile.read1(n) if hasattr(self.rfile, "read1") else self.rfile.read(n)
        except (OSError, TimeoutError):
            data = b""
        if not data:
            raise UploadError(400, "the upload ended before its announced length (connection closed or timed out)")
        self.left -= len(data)
        return data

    def drain(self, most: int) -> None:
        """Read and drop what is left of a refused body (up to ``most`` bytes), so that the client, still sending,
        reads the answer instead of a reset connection."""
        if self.left > most:
            return
        try:
            while self.left > 0:
                self.read(CHUNK)
        except (UploadError, OSError):
            pass


def read_form(body: Body, content_type: str, folder: Path, max_file: int) -> dict:
    """Parse a multipart ``body``: text fields (``kind``, ``prompt``, ``source``, ``options``) as
    strings; file fields (``file``, ``avatar``) written to ``folder/upload-<field>`` (the studio's names) and given
    as their paths, each at most ``max_file`` bytes. Anything else (an unknown or repeated field, a part without
    a name, a body that is not well formed or ends early) is an :class:`UploadError`."""
    delim = b"\r\n--" + boundary_of(content_type)
    buf = b"\r\n"
    out: dict = {}
    # the preamble, up to the first delimiter
    while True:
        i = buf.find(delim)
        if i >= 0:
            buf = buf[i + len(delim) :]
            break
        if len(buf) > MAX_HEADER:
            raise UploadError(400, "no multipart boundary where the body begins")
        buf += body.read(CHUNK)
    for _ in range(MAX_PARTS + 1):
        while len(buf) < 2:
            buf += body.read(CHUNK)
        if buf[:2] == b"--":
            return out
        if buf[:2] != b"\r\n":
            raise UploadError(400, "a multipart boundary not followed by a line break")
        buf = buf[2:]
        while b"\r\n\r\n" not in buf:
            if len(buf) > MAX_HEADER:
                raise UploadError(400, "a multipart part's headers are too long")
            buf += body.read(CHUNK)
        head, buf = buf.split(b"\r\n\r\n", 1)
        name, is_file = _part_name(head)
        if name in out:
            raise UploadError(400, f"the field {name} is sent twice")
        if name in FILE_FIELDS:
            if not is_file:
                raise UploadError(400, f"the field {name} must be a file")
            dest = folder / f"upload-{name}"
            buf = _stream(body, buf, delim, dest, max_file, name)
            out[name] = dest
        else:
            parts = []
            size = 0

            def keep(block: bytes):
                nonlocal size
                size += len(block)
                if size > MAX_TEXT:
                    raise UploadError(413, f"the field {name} is over {MAX_TEXT:,} bytes")
                parts.append(block)

            buf = _until(body, buf, delim, keep)
            try:
                out[name] = b"".join(parts).decode("utf-8")
            except UnicodeDecodeError:
                raise UploadError(400, f"the field {name} is not UTF-8 text") from None
    raise UploadError(400, f"more than {MAX_PARTS} parts in one upload")


def _part_name(head: bytes) -> tuple[str, bool]:
    try:
        lines = head.decode("utf-8").split("\r\n")
    except UnicodeDecodeError:
        raise UploadError(400, "a multipart part's headers are not UTF-8") from None
    for line in lines:
        key, _, value = line.partition(":")
        if key.strip().lower() == "content-disposition":
            m = _DISPOSITION.match(value.strip())
            if not m:
                raise UploadError(400, "a multipart part without a plain field name")
            name = m.group(1).lower()
            if name not in FILE_FIELDS + TEXT_FIELDS:
                raise UploadError(400, f"unknown field {name!r} (fields: {', '.join(TEXT_FIELDS + FILE_FIELDS)})")
            return name, m.group(2) is not None
    raise UploadError(400, "a multipart part without Content-Disposition")


def _until(body: Body, buf: bytes, delim: bytes, sink) -> bytes:
    """Feed ``sink`` the part's bytes up to the next delimiter; returns what follows the delimiter."""
    keep = len(delim) - 1
    while True:
        i = buf.find(delim)
        if i >= 0:
            sink(buf[:i])
            return buf[i + len(delim) :]
        if len(buf) > keep:
            sink(buf[:-keep])
            buf = buf[-keep:]
        buf += body.read(CHUNK)


def _stream(body: Body, buf: bytes, delim: bytes, dest: Path, max_file: int, name: str) -> bytes:
    tmp = temp_sibling(dest)
    size = 0
    try:
        with open(tmp, "xb") as fh:

            def write(block: bytes):
                nonlocal size
                size += len(block)
                if size > max_file:
                    raise UploadError(413, f"the {name} is over the upload limit of {max_file / 2**20:,.0f} MB "
                                           "(anima studio --max-upload-mb)")  # fmt: skip
                fh.write(block)

            rest = _until(body, buf, delim, write)
        if size == 0:
            raise UploadError(400, f"the {name} is empty")
        commit(tmp, dest)
        return rest
    finally:
        if tmp.exists():
            tmp.unlink()


# --- what a file really is -------------------------------------------------------------------------------------


def _head(path: Path, n: int = 64) -> bytes:
    with open(path, "rb") as fh:
        return fh.read(n)


def container_suffix(head: bytes, audio: bool = False) -> str | None:
    """The suffix of a media container by its first bytes (None: not one the studio names)."""
    if head[4:8] == b"ftyp":
        return ".mov" if head[8:12] == b"qt  " else (".m4a" if audio and head[8:11] == b"M4A" else ".mp4")
    if head[:4] == b"\x1aE\xdf\xa3":
        return ".webm" if b"webm" in head else ".mkv"
    if head[:4] == b"RIFF" and head[8:12] == b"WAVE":
        return ".wav"
    if head[:4] == b"RIFF" and head[8:12] == b"AVI ":
        return ".avi"
    if head[:4] == b"fLaC":
        return ".flac"
    if head[:4] == b"OggS":
        return ".ogg"
    if head[:3] == b"ID3" or (len(head) > 1 and head[0] == 0xFF and head[1] & 0xE0 == 0xE0):
        return ".mp3"
    if head[:4] == b"FLV\x01":
        return ".flv"
    return None


def one_line(e: BaseException) -> str:
    text = " ".join(str(e).split())
    return text if len(text) <= 300 else text[:297] + "..."


def _renamed(path: Path, name: str) -> Path:
    dest = path.with_name(name)
    os.replace(path, dest)
    return dest


def check_video(path: Path) -> tuple[Path, dict]:
    """The uploaded video renamed ``input<suffix>`` (its container's), with what ffmpeg read of it; else
    :class:`InputError` (one line, without the studio's own file names)."""
    suffix = container_suffix(_head(path))
    try:
        info = probe_video(path)
    except AnimaError as e:
        why = _plain(e, path)
        if why.startswith("not a readable video"):  # ffmpeg's own words, without the file's name
            why = why.rsplit("(", 1)[-1].rstrip(")").removeprefix("the file: ")
        raise InputError(f"the file is not a video anima can read ({why})") from None
    if info.n_frames < 1:
        raise InputError("the video holds no frames")
    return _renamed(path, f"input{suffix or '.video'}"), {"fps": info.fps, "frames": info.n_frames,
                                                         "seconds": round(info.duration, 2)}  # fmt: skip


def check_speech(path: Path) -> Path:
    """The uploaded speech (or a video with a sound track) renamed ``speech<suffix>`` when ffmpeg decodes an audio
    stream from it; else :class:`InputError`."""
    cmd = [FFMPEG, "-hide_banner", "-nostdin", "-v", "error", "-i", str(path), "-map", "0:a:0", "-t", "1"]
    cmd += ["-f", "null", "-"]
    try:
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired) as e:
        raise InputError(f"the speech file could not be read ({type(e).__name__})") from None
    if r.returncode != 0:
        last = (r.stderr.strip().splitlines() or ["no audio stream"])[-1].replace(str(path), "the file")
        raise InputError(f"the file is not a sound anima can read (no audio stream ffmpeg decodes: {last[:160]})")
    return _renamed(path, f"speech{container_suffix(_head(path), audio=True) or '.audio'}")


def check_avatar(path: Path) -> Path:
    """The uploaded avatar renamed ``avatar.vrm`` (a glTF binary with VRM) or ``avatar.glb`` when anima's glTF
    reader takes it; else :class:`InputError`."""
    if _head(path, 4) != b"glTF":
        raise InputError("the avatar is not a glTF binary: upload a .vrm (VRM 1.0) or a skinned .glb")
    glb = _renamed(path, "avatar.glb")
    try:
        g = read_gltf(glb)
    except AnimaError as e:
        glb.unlink(missing_ok=True)
        raise InputError(f"the avatar cannot be read: {_plain(e, glb)}") from None
    return _renamed(glb, "avatar.vrm") if g.vrm is not None else glb


def _plain(e: BaseException, path: Path) -> str:
    """An error's line without the studio's paths (the person sent a file, not a path)."""
    text = one_line(e)
    for p in (str(path), str(path.resolve())):
        text = text.replace(p, "the file")
    return text
