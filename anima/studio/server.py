"""``anima studio``: the page and its JSON API on 127.0.0.1, served by the viewer's server
(:mod:`anima.view.serve`: its Host checks, request deadlines, connection limit and byte ranges), with:

* a random token per run: ``/?token=T`` opens the page; every API call carries it (``X-Anima-Token`` header or
  ``?token=``), a call without it is answered 401, with another 403; a finished job's viewer page lives under
  ``/view/T/ID/`` (the viewer's own files load by relative names);
* a request from another origin (``Origin``, ``Sec-Fetch-Site``) refused 403;
* uploads bounded by ``--max-upload-mb`` (413 before a byte is read when the announced length is over it), parsed
  as a stream (:mod:`anima.studio.uploads`), checked by their content before a job is made: a file that is not
  what the job needs becomes a failed job with a one-line reason; a malformed body a 4xx;
* jobs run by anima's own commands (:mod:`anima.studio.jobs`); the viewer page of a result built by
  :func:`anima.view.export.build_view` into the system's temporary folder.
"""

from __future__ import annotations

import json
import os
import re
import secrets
import shutil
import sys
import tempfile
import threading
from http import HTTPStatus
from pathlib import Path
from urllib.parse import parse_qs, unquote, urlsplit

from anima.errors import AnimaError, InputError
from anima.io.outdir import claim_folder, confined, lock_folder, unlock_folder
from anima.studio import uploads
from anima.studio.jobs import KINDS, RETARGET_SHARE, RIGS, SEQUENCES, Jobs, dumps, remove_job
from anima.studio.uploads import UploadError
from anima.view.export import build_view
from anima.view.serve import HOST, FileHandler, open_server, serve_until_stopped

STATIC = Path(__file__).parent / "static"
DEFAULT_MAX_UPLOAD_MB = 2048
MAX_PROMPT = 2000
DRAIN = 8 * 2**20  # the rest of a refused upload read (and dropped) when it is no more than this
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,200}$")
OPTIONS = {"face_only": bool, "rig": str, "max_seconds": (int, float)}


def default_root() -> Path:
    """Where the studio keeps its jobs by default: the user's data folder (``$XDG_DATA_HOME``, else
    ``~/.local/share``; ``~/Library/Application Support`` on macOS, ``%LOCALAPPDATA%`` on Windows)/anima/studio."""
    if sys.platform == "win32":
        base = Path(os.environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
    elif sys.platform == "darwin":
        base = Path.home() / "Library" / "Application Support"
    else:
        xdg = os.environ.get("XDG_DATA_HOME", "")
        base = Path(xdg) if os.path.isabs(xdg) else Path.home() / ".local" / "share"
    return base / "anima" / "studio"


class Studio:
    """The jobs, the built viewer pages (in a temporary folder) and the rules of an upload."""

    def __init__(self, root: Path, max_upload: int):
        self.root = claim_folder(root, kind="studio", flag="--root")
        try:  # one studio per root: two would run the same queued jobs
            self.lock = lock_folder(self.root)
        except InputError:
            raise InputError(f"--root {self.root}: another anima studio is using this folder; stop it or give "
                             "another --root") from None  # fmt: skip
        self.max_upload = max_upload
        self.jobs = Jobs(self.root)
        self.views_dir = Path(tempfile.mkdtemp(prefix="anima-studio-"))
        self.views: dict[str, tuple] = {}
        self.view_lock = threading.Lock()

    def close(self) -> None:
        self.jobs.close()
        shutil.rmtree(self.views_dir, ignore_errors=True)
        unlock_folder(self.lock)

    # --- a new job -------------------------------------------------------------------------------------------

    def submit(self, body: uploads.Body, content_type: str) -> dict:
        """Read an upload into a new job's folder and make the job (failed, with the reason, when a file is not
        what the job needs); an :class:`UploadError` (and no job folder left) when the request itself is wrong."""
        jid, folder = self.jobs.reserve()
        try:
            form = uploads.read_form(body, content_type, folder, self.max_upload)
            kind, options, extra = self._fields(form)
            return self._make(jid, folder, kind, form, options, extra)
        except BaseException:
            remove_job(folder)
            raise

    def _fields(self, form: dict) -> tuple[str, dict, dict]:
        kind = (form.get("kind") or "").strip()
        if kind not in KINDS:
            raise UploadError(400, f"kind must be one of {', '.join(KINDS)}")
        try:
            options = json.loads(form.get("options") or "{}")
        except ValueError:
            raise UploadError(400, "options is not JSON") from None
        if not isinstance(options, dict):
            raise UploadError(400, "options must be a JSON object")
        for k, v in options.items():
            if k not in OPTIONS:
                raise UploadError(400, f"unknown option {k!r} (options: {', '.join(OPTIONS)})")
            if not isinstance(v, OPTIONS[k]) or (OPTIONS[k] is not bool and isinstance(v, bool)):
                raise UploadError(400, f"option {k}: wrong type")
        rig = options.setdefault("rig", "anima")
        if rig not in RIGS:
            raise UploadError(400, f"option rig: one of {', '.join(RIGS)}")
        ms = options.get("max_seconds")
        if ms is not None and not 0.2 <= ms <= 3600:
            raise UploadError(400, "option max_seconds: 0.2 to 3600")
        wants = {"capture": "file", "gesture": "file", "retarget": "avatar"}.get(kind)
        if wants and wants not in form:
            raise UploadError(400, f"a {kind} job needs the field {wants}")
        if kind in ("text2face", "retarget") and "file" in form:
            raise UploadError(400, f"a {kind} job takes no file")
        extra = {}
        if kind == "text2face":
            prompt = " ".join((form.get("prompt") or "").split())
            if not prompt:
                raise UploadError(400, "a text2face job needs a prompt (a sentence)")
            if len(prompt) > MAX_PROMPT:
                raise UploadError(400, f"the prompt is over {MAX_PROMPT} characters")
            extra["prompt"] = prompt
        if kind == "retarget":
            src = self.jobs.get((form.get("source") or "").strip())
            if src is None:
                raise UploadError(400, "a retarget job needs source: the id of a finished job")
            if src["state"] != "done" or src["kind"] not in SEQUENCES:
                raise UploadError(409, f"job {src['id']} has no finished motion to put on an avatar")
            extra["source"] = src["id"]
        return kind, options, extra

    def _make(self, jid: str, folder: Path, kind: str, form: dict, options: dict, extra: dict) -> dict:
        rig = options["rig"]
        commands, title, error, avatar = [], kind, None, None
        try:
            avatar = uploads.check_avatar(form["avatar"]) if "avatar" in form else None
            if kind == "capture":
                video, info = uploads.check_video(form["file"])
                argv = ["capture", video.name, "--out", "result", "--rig", rig]
                if options.get("face_only"):
                    argv.append("--face-only")
                if options.get("max_seconds"):
                    argv += ["--max-frames", str(max(1, int(round(options["max_seconds"] * info["fps"]))))]
                seconds = min(info["seconds"], options.get("max_seconds") or info["seconds"])
                title = f"capture of a {seconds:.1f}-s video" + (" (face)" if options.get("face_only") else "")
                commands.append({"argv": argv, "plan": "capture"})
            elif kind == "gesture":
                speech = uploads.check_speech(form["file"])
                title = "gestures for a speech file"
                commands.append({"argv": ["gesture", speech.name, "--out", "result", "--rig", rig], "plan": "gesture"})
            elif kind == "text2face":
                title = f"“{extra['prompt']}”"
                argv = ["text2face", "--out", "result", "--rig", rig, "--", extra["prompt"]]
                commands.append({"argv": argv, "plan": "text2face"})
            else:
                title = f"job {extra['source']} on your avatar"
            if avatar is not None:
                src = self.jobs.folder(extra["source"]) / "result" if kind == "retarget" else Path("result")
                out = f"retargeted{avatar.suffix}"
                commands.append({"argv": ["retarget", str(src), "--avatar", avatar.name, "--out", out],
                                 "plan": "retarget"})  # fmt: skip
            for c in commands:
                alone = len(commands) == 1
                c["share"] = 1.0 if alone else (RETARGET_SHARE if c["plan"] == "retarget" else 1 - RETARGET_SHARE)
        except AnimaError as e:
            error = uploads.one_line(e)
            commands = []
            title = f"{kind}: the file was refused"
            for f in folder.glob("upload-*"):  # a refused file is not kept
                f.unlink(missing_ok=True)
        return self.jobs.create(kind, title, commands, options, id=jid, error=error, avatar=avatar and avatar.name,
                                **extra)  # fmt: skip

    # --- the viewer page of a job ----------------------------------------------------------------------------

    def view_folder(self, job: dict) -> Path:
        """The viewer page of a finished job (built once, again when the result changed)."""
        motion = self.jobs.motion_of(job)
        if motion is None:
            raise InputError("the job whose motion this shows is gone")
        avatar = self.jobs.avatar_of(job)
        stamp = (os.stat(motion / "manifest.json").st_mtime_ns, str(avatar))
        with self.view_lock:
            have = self.views.get(job["id"])
            if have is not None and have[0] == stamp:
                return have[1]
            out = self.views_dir / job["id"]
            shutil.rmtree(out, ignore_errors=True)
            build_view(motion, out, avatar)
            self.views[job["id"]] = (stamp, out)
            return out


class StudioHandler(FileHandler):
    """The studio's requests: the page, the API, a job's files and viewer page."""

    studio: Studio
    server_version = "anima-studio"

    # --- answers ---------------------------------------------------------------------------------------------

    def _json(self, status: int, obj, head: dict | None = None) -> None:
        body = dumps(obj)
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Cross-Origin-Resource-Policy", "same-origin")
        for k, v in (head or {}).items():
            self.send_header(k, v)
        self.end_headers()
        self.wfile.write(body)

    def _error(self, status: int, message: str) -> None:
        self._json(status, {"error": message})

    # --- checks ----------------------------------------------------------------------------------------------

    def _target(self) -> tuple[str, dict] | None:
        """The request's path and query when it may be answered at all (Host, Origin, a well-formed target);
        else it has been answered."""
        if not self.path.startswith("/"):
            self._refuse(HTTPStatus.BAD_REQUEST)
            return None
        if self.headers.get("Host", "") not in self.hosts:
            self._refuse(HTTPStatus.MISDIRECTED_REQUEST)
            return None
        origin = self.headers.get("Origin")
        if origin is not None and origin not in {f"http://{h}" for h in self.hosts}:
            self._error(403, "requests from another origin are refused")
            return None
        site = self.headers.get("Sec-Fetch-Site")
        if site is not None and site not in ("same-origin", "none") and not self._navigation():
            self._error(403, "requests from another site are refused")
            return None
        try:
            parts = urlsplit(self.path)
            path = unquote(parts.path, errors="strict")
            query = parse_qs(parts.query, max_num_fields=8, strict_parsing=False)
        except (ValueError, UnicodeDecodeError):
            self._refuse(HTTPStatus.BAD_REQUEST)
            return None
        if "\x00" in path or "\\" in path:
            self._refuse(HTTPStatus.BAD_REQUEST)
            return None
        return path, query

    def _navigation(self) -> bool:
        """A top-level page load (a link opened from elsewhere: the token still decides)."""
        return self.command == "GET" and self.headers.get("Sec-Fetch-Mode") == "navigate"

    def _authorised(self, query: dict) -> bool:
        given = self.headers.get("X-Anima-Token") or (query.get("token") or [None])[0]
        if not given:
            self._error(401, "no token: open the address anima studio printed (it carries ?token=...)")
            return False
        if not secrets.compare_digest(given.encode(), self.token.encode()):
            self._error(403, "wrong token")
            return False
        return True

    # --- methods ---------------------------------------------------------------------------------------------

    def do_HEAD(self):
        self._refuse(HTTPStatus.METHOD_NOT_ALLOWED, head_only=True)

    def do_PUT(self):
        self._refuse(HTTPStatus.METHOD_NOT_ALLOWED)

    def do_GET(self):
        t = self._target()
        if t is None:
            return
        path, query = t
        try:
            self._get(path, query)
        except (BrokenPipeError, ConnectionResetError):
            pass
        except Exception as e:  # one request's trouble, never the server's
            self.close_connection = True
            try:
                self._error(500, f"{type(e).__name__}: {uploads.one_line(e)}")
            except OSError:
                pass

    def _get(self, path: str, query: dict) -> None:
        if path.startswith("/view/"):
            return self._view(path)
        if not self._authorised(query):
            return
        if path in ("/", "/index.html"):
            return self._page()
        parts = path.strip("/").split("/")
        if parts[:2] != ["api", "jobs"]:
            return self._error(404, "no such page")
        if len(parts) == 2:
            return self._json(200, {"jobs": self.studio.jobs.listing()})
        job = self.studio.jobs.get(parts[2])
        if job is None:
            return self._error(404, "no such job")
        if len(parts) == 3:
            with self.studio.jobs.lock:
                return self._json(200, self.studio.jobs.public(job))
        if len(parts) == 5 and parts[3] == "files" and _NAME.match(parts[4]):
            return self._job_file(job, parts[4])
        return self._error(404, "no such page")

    def _job_file(self, job: dict, name: str) -> None:
        jobs = self.studio.jobs
        if job["state"] != "done":
            return self._error(409, f"job {job['id']} is {job['state']}: no files yet")
        if name in jobs.takes(job) and name not in jobs.outputs(job):
            x = jobs.take(job, name)
            if x["state"] == "failed":
                return self._error(422, f"{name} could not be made: {x.get('error')}")
            if x["state"] != "done":
                return self._json(202, {"state": x["state"], "file": name}, {"Retry-After": "1"})
        p = jobs.file(job, name)
        if p is None:
            return self._error(404, f"job {job['id']} has no {name}")
        self._attachment = name
        self.send_file(p)

    def end_headers(self):
        name = getattr(self, "_attachment", None)
        if name:
            self.send_header("Content-Disposition", f'attachment; filename="{name}"')
            self._attachment = None
        super().end_headers()

    def _page(self) -> None:
        body = (STATIC / "studio.html").read_bytes()
        self.send_response(200)
        self.send_header("Content-Type", "text/html; charset=utf-8")
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("Referrer-Policy", "no-referrer")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Content-Security-Policy", "frame-ancestors 'none'")
        self.end_headers()
        self.wfile.write(body)

    def _view(self, path: str) -> None:
        """``/view/TOKEN/ID/NAME``: a file of the viewer page of a finished job."""
        parts = path.split("/")
        if len(parts) not in (4, 5) or not secrets.compare_digest(parts[2].encode(), self.token.encode()):
            return self._refuse(HTTPStatus.NOT_FOUND)
        job = self.studio.jobs.get(parts[3])
        name = parts[4] if len(parts) == 5 and parts[4] else "index.html"
        if job is None or job["state"] != "done" or not _NAME.match(name):
            return self._refuse(HTTPStatus.NOT_FOUND)
        try:
            folder = self.studio.view_folder(job)
        except AnimaError as e:
            return self._error(409, uploads.one_line(e))
        except OSError:
            return self._error(409, f"the result of job {job['id']} is no longer there")
        p = confined(folder, name)
        if p is None:
            return self._refuse(HTTPStatus.NOT_FOUND)
        self.send_file(p)

    def do_POST(self):
        t = self._target()
        if t is None:
            return
        path, query = t
        if not self._authorised(query):
            return
        self.close_connection = True  # a refused body is not read to its end: the connection ends with the answer
        if path != "/api/jobs":
            return self._error(404, "no such page")
        try:
            length = int(self.headers.get("Content-Length", ""))
        except ValueError:
            return self._error(411, "Content-Length is required (chunked uploads are not taken)")
        if length < 0:
            return self._error(400, "a negative Content-Length")
        limit = self.studio.max_upload + 2**20  # the files, and the form around them
        if length > limit:
            mb = self.studio.max_upload / 2**20
            return self._error(413, f"the upload is {length / 2**20:,.0f} MB; the limit is {mb:,.0f} MB "
                                    "(anima studio --max-upload-mb)")  # fmt: skip
        body = uploads.Body(self.rfile, length)
        try:
            job = self.studio.submit(body, self.headers.get("Content-Type", ""))
        except UploadError as e:
            body.drain(DRAIN)
            return self._error(e.status, str(e))
        except AnimaError as e:
            return self._error(400, uploads.one_line(e))
        except (BrokenPipeError, ConnectionResetError):
            return None
        except Exception as e:
            return self._error(500, f"{type(e).__name__}: {uploads.one_line(e)}")
        with self.studio.jobs.lock:
            self._json(201, {"id": job["id"], "state": job["state"], "error": job.get("error")})

    def do_DELETE(self):
        t = self._target()
        if t is None:
            return
        path, query = t
        if not self._authorised(query):
            return
        parts = path.strip("/").split("/")
        job = self.studio.jobs.get(parts[2]) if len(parts) == 3 and parts[:2] == ["api", "jobs"] else None
        if job is None:
            return self._error(404, "no such job")
        if job["state"] not in ("queued", "running"):
            return self._error(409, f"job {job['id']} is {job['state']}: nothing to cancel")
        state = self.studio.jobs.cancel(job["id"])
        self._json(200, {"id": job["id"], "state": state})


def studio_url(server) -> str:
    return f"http://{HOST}:{server.server_address[1]}/?token={server.token}"


def serve(
    root: str | Path | None = None,
    port: int | None = None,
    browser: bool = True,
    max_upload_mb: float = DEFAULT_MAX_UPLOAD_MB,
    announce=print,
) -> int:
    """``anima studio``: serve the studio until Ctrl-C / SIGTERM; the running job is stopped with it."""
    if port is not None and not 0 <= port <= 65535:
        raise InputError(f"--port {port}: expected 0 to 65535")
    if not 1 <= max_upload_mb <= 1_000_000:
        raise InputError(f"--max-upload-mb {max_upload_mb:g}: expected 1 to 1000000")
    studio = Studio(Path(root) if root else default_root(), int(max_upload_mb * 2**20))
    server = None
    try:
        handler = type("Studio", (StudioHandler,), {"studio": studio})
        server, note = open_server(studio.views_dir, port or None, handler=handler)
        if note:
            print(f"anima: note: {note}", file=sys.stderr)
        url = studio_url(server)
        announce(f"studio: {url}")
        sys.stdout.flush()
        serve_until_stopped(server, url, browser)
    except KeyboardInterrupt:
        pass
    finally:
        if server is not None:
            server.server_close()
        studio.close()
    return 0
