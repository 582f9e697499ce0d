"""The studio's jobs: each one a folder under the studio's root holding the person's upload (under the studio's
own name), ``job.json`` (the job's record, written atomically) and ``result/``, an ordinary anima result folder
made by anima's own command. Jobs run one at a time, in the order they came, each as a child process
``python -m anima COMMAND ...`` in its own process group: cancelling kills the group, and a crash of the command
cannot take the studio down.

Progress is what the command already shows: its tqdm bars (``track``, ``render``, ``avatar``) on stderr, drawn
every 0.1 s at most whether or not stderr is a terminal; each bar line (``desc: 45%|...| 90/200 [...]``) is read
and mapped onto the job's stages (:data:`PLANS`, shares measured on real runs). The take files (``take.fbx``,
``take.vrma``, ``take.bvh``) are made on request by ``anima export`` into the result folder, queued like jobs and
kept there."""

from __future__ import annotations

import json
import os
import re
import secrets
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections import deque
from pathlib import Path

from anima.errors import InputError
from anima.io.atomic import write_json
from anima.io.outdir import claim_folder, confined, read_manifest
from anima.io.validate import read_json

SCHEMA = "anima.studio_job"
VERSION = 1
KINDS = ("capture", "gesture", "text2face", "retarget")
STATES = ("queued", "running", "done", "failed", "cancelled")
RESULT = "result"
JOB_FILE = "job.json"
ID = re.compile(r"\d{8}-\d{6}-[0-9a-f]{6}$")
SEQUENCES = {"capture": "capture.npz", "text2face": "motion.npz", "gesture": "gesture.npz"}
TAKES = {"take.fbx": "fbx", "take.vrma": "vrma", "take.bvh": "bvh"}
RIGS = ("anima", "mixamo", "vrm", "unreal")
PLANS = {
    # stage, the tqdm bars that measure it, its share of the command's time (measured: an 8-s capture spends
    # 0.4 s starting, 5.2 s tracking and fitting, 4.3 s rendering and writing; text2face 2.5 s, half of it
    # starting; gesture 4.6 s, 2.8 of them loading and searching)
    "capture": (("starting", (), 0.06), ("tracking", ("track",), 0.54), ("rendering", ("render", "avatar"), 0.40)),
    "text2face": (("composing", (), 0.5), ("rendering", ("render", "avatar"), 0.5)),
    "gesture": (("searching", (), 0.6), ("rendering", ("render", "avatar"), 0.4)),
    "retarget": (("retargeting", (), 1.0),),
}
RETARGET_SHARE = 0.1  # of a job whose motion is also put on the person's avatar
_BAR = re.compile(r"^\s*([A-Za-z][\w .-]{0,40}?):\s+\d{1,3}%\|[^|]*\|\s*(\d+)/(\d+)\b")
_ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")
CHILD_ENV = {"PYTHONUNBUFFERED": "1"}
KILL_WAIT_S = 5.0
PACKAGE_ROOT = str(Path(__file__).resolve().parents[2])
"""The folder that holds this ``anima``: first on the commands' path, so a job runs the studio's own anima (not
another copy an environment may name)."""


def new_id() -> str:
    return time.strftime("%Y%m%d-%H%M%S") + "-" + secrets.token_hex(3)


class Progress:
    """One command's progress from its bars: the stage it is in and the fraction of the command done."""

    def __init__(self, plan):
        self.plan, self.stage, self.bars = plan, 0, {}

    def feed(self, desc: str, n: int, total: int) -> bool:
        for i, (_, bars, _) in enumerate(self.plan):
            if desc in bars and i >= self.stage and total > 0:
                if i > self.stage:
                    self.stage, self.bars = i, {}
                self.bars[desc] = max(self.bars.get(desc, 0.0), min(1.0, n / total))  # a bar drawn again
                return True
        return False

    def state(self) -> tuple[str, float, float | None]:
        """(stage, fraction of the command done, fraction of the stage done or None when it has no bar)."""
        name, bars, share = self.plan[self.stage]
        before = sum(s for _, _, s in self.plan[: self.stage])
        # a stage's bars run side by side (the videos and the avatar's render): each counts, seen yet or not
        stage = sum(self.bars.get(b, 0.0) for b in bars) / len(bars) if bars else None
        return name, before + share * (stage or 0.0), stage


def parse_bar(segment: str) -> tuple[str, int, int] | None:
    m = _BAR.match(_ANSI.sub("", segment))
    return (m.group(1).strip(), int(m.group(2)), int(m.group(3))) if m else None


class Jobs:
    """The studio's jobs under ``root``: made, listed, run one at a time by one worker thread, cancelled."""

    def __init__(self, root: Path, python: str = sys.executable):
        self.root = Path(root)
        self.python = python
        self.lock = threading.RLock()
        self.wake = threading.Condition(self.lock)
        self.jobs: dict[str, dict] = {}
        self.queue: deque = deque()  # (job id, task): task "run" or a take's name
        self.proc: subprocess.Popen | None = None
        self.current: tuple[str, str] | None = None
        self.closing = False
        self._load()
        self.worker = threading.Thread(target=self._work, name="anima-studio-jobs", daemon=True)
        self.worker.start()

    # --- the record -------------------------------------------------------------------------------------------

    def folder(self, jid: str) -> Path:
        return self.root / jid

    def _save(self, job: dict) -> None:
        keep = {k: v for k, v in job.items() if not k.startswith("_")}
        write_json(self.folder(job["id"]) / JOB_FILE, keep)

    def _load(self) -> None:
        for d in sorted(self.root.iterdir()) if self.root.is_dir() else []:
            if not ID.match(d.name) or not d.is_dir() or d.is_symlink():
                continue
            try:
                job = read_json(d / JOB_FILE, "job record")
            except (InputError, OSError):
                continue
            if not isinstance(job, dict) or job.get("schema") != SCHEMA or job.get("id") != d.name:
                continue
            for name, x in list(job.get("exports", {}).items()):
                if x.get("state") in ("queued", "running"):
                    del job["exports"][name]  # asked for again when wanted
            if job.get("state") == "running":
                job.update(state="failed", error="the studio stopped while this job ran; send it again")
                self._save(job)
            self.jobs[job["id"]] = job
            if job.get("state") == "queued":
                self.queue.append((job["id"], "run"))

    def create(self, kind: str, title: str, commands: list[dict], options: dict, **extra) -> dict:
        """A new job in its own folder (claimed as anima's), queued; ``commands``: ``{"argv", "plan", "share"}``
        run in order in the job's folder. With ``extra["error"]`` the job is made failed (a refused upload)."""
        job = {
            "schema": SCHEMA,
            "version": VERSION,
            "id": extra.pop("id"),
            "kind": kind,
            "title": title,
            "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            "created_s": time.time(),
            "state": "queued",
            "progress": 0.0,
            "stage": "queued",
            "stage_progress": None,
            "eta_s": None,
            "error": None,
            "options": options,
            "commands": commands,
            "exports": {},
        } | extra
        if job.get("error"):
            job.update(state="failed", stage="refused")
        with self.lock:
            self._save(job)
            self.jobs[job["id"]] = job
            if job["state"] == "queued":
                self.queue.append((job["id"], "run"))
                self.wake.notify_all()
        return job

    def reserve(self) -> tuple[str, Path]:
        """A new job's id and its folder, created and claimed (the upload is written into it)."""
        jid = new_id()
        return jid, claim_folder(self.folder(jid), kind="studio_job", flag="job folder")

    def get(self, jid: str) -> dict | None:
        with self.lock:
            return self.jobs.get(jid) if ID.match(jid or "") else None

    def public(self, job: dict) -> dict:
        out = {k: job.get(k) for k in ("id", "kind", "title", "created", "state", "progress", "stage",
                                       "stage_progress", "eta_s", "error", "options", "source")}  # fmt: skip
        out["outputs"] = self.outputs(job)
        out["exports"] = {n: {"state": x["state"], "error": x.get("error")} for n, x in job.get("exports", {}).items()}
        out["takes"] = self.takes(job)
        return out

    def takes(self, job: dict) -> list[str]:
        """The take files a finished job can be asked for (a BVH needs a body: not of text2face, nor of a face-only
        capture)."""
        if job.get("kind") not in SEQUENCES or job.get("state") != "done":
            return []
        bodiless = job["kind"] == "text2face" or job.get("options", {}).get("face_only")
        return sorted(n for n in TAKES if not (bodiless and n == "take.bvh"))

    def listing(self) -> list[dict]:
        with self.lock:
            newest = sorted(self.jobs.values(), key=lambda j: (j.get("created_s", 0.0), j["id"]), reverse=True)
            return [self.public(j) for j in newest]

    def result(self, job: dict) -> Path:
        return self.folder(job["id"]) / RESULT

    def outputs(self, job: dict) -> list[str]:
        """The files of a finished job: its result's (as its manifest lists them), the takes made, the avatar
        with the motion."""
        if job.get("state") != "done":
            return []
        try:  # read again only when a file came or went (the page asks every 0.4 s)
            stamp = (os.stat(self.result(job)).st_mtime_ns if job["kind"] in SEQUENCES else 0,
                     os.stat(self.folder(job["id"])).st_mtime_ns)  # fmt: skip
        except OSError:
            return []
        if job.get("_outputs", (None,))[0] == stamp:
            return list(job["_outputs"][1])
        names = []
        if job["kind"] in SEQUENCES:
            try:
                names = [n for n in read_manifest(self.result(job)).get("files", {}) if "/" not in n]
            except Exception:
                names = []
            names += [n for n in TAKES if confined(self.result(job), n) is not None]
        names += [n for n in ("retargeted.vrm", "retargeted.glb") if confined(self.folder(job["id"]), n)]
        job["_outputs"] = (stamp, sorted(dict.fromkeys(names)))
        return list(job["_outputs"][1])

    def file(self, job: dict, name: str) -> Path | None:
        """The path of one of :meth:`outputs`."""
        if name not in self.outputs(job):
            return None
        if name.startswith("retargeted."):
            return confined(self.folder(job["id"]), name)
        return confined(self.result(job), name)

    def avatar_of(self, job: dict) -> Path | None:
        a = job.get("avatar")
        return confined(self.folder(job["id"]), a) if a else None

    def motion_of(self, job: dict) -> Path | None:
        """The result folder whose motion a job shows: its own, or for a retarget job its source's."""
        if job["kind"] == "retarget":
            src = self.get(job.get("source") or "")
            return self.result(src) if src else None
        return self.result(job)

    # --- takes -----------------------------------------------------------------------------------------------

    def take(self, job: dict, name: str) -> dict:
        """A take file of a finished job: ``{"state": done}`` when it is there; else queued (once) and its state."""
        with self.lock:
            if confined(self.result(job), name) is not None:
                return {"state": "done"}
            x = job["exports"].get(name)
            if x is None:  # a take that failed stays failed (its reason shown), never retried in a loop
                x = {"state": "queued", "error": None}
                job["exports"][name] = x
                self.queue.append((job["id"], name))
                self.wake.notify_all()
            return dict(x)

    # --- cancel ----------------------------------------------------------------------------------------------

    def cancel(self, jid: str) -> str:
        """Cancel a queued or running job: its new state (or why not)."""
        with self.lock:
            job = self.jobs[jid]
            if job["state"] == "queued":
                self.queue = deque(t for t in self.queue if t != (jid, "run"))
                job.update(state="cancelled", stage="cancelled", eta_s=None)
                self._save(job)
            running = job["state"] == "running"
            if running:
                job["_cancel"] = True
        if running:
            self._kill()  # outside the lock: the worker reads the command's output meanwhile
            self.worker_idle(jid)
        return job["state"]

    def worker_idle(self, jid: str, timeout: float = KILL_WAIT_S + 5) -> None:
        """Wait until the worker has left job ``jid`` (its state written)."""
        t0 = time.monotonic()
        while time.monotonic() - t0 < timeout:
            with self.lock:
                if self.current is None or self.current[0] != jid:
                    return
            time.sleep(0.05)

    def _kill(self) -> None:
        p = self.proc
        if p is None or p.poll() is not None:
            return
        try:
            os.killpg(p.pid, signal.SIGTERM)  # anima ends as on Ctrl-C: its temporary files removed
        except OSError:
            return
        try:
            p.wait(KILL_WAIT_S)
        except subprocess.TimeoutExpired:
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except OSError:
                pass

    def close(self) -> None:
        """Stop: the running command killed (its job cancelled), the queue kept for the next start."""
        with self.lock:
            self.closing = True
            if self.current is not None:
                jid, task = self.current
                if task == "run":
                    self.jobs[jid]["_stopping"] = True
            self.wake.notify_all()
        self._kill()
        self.worker.join(KILL_WAIT_S + 5)

    # --- the worker ------------------------------------------------------------------------------------------

    def _work(self) -> None:
        while True:
            with self.lock:
                while not self.queue and not self.closing:
                    self.wake.wait()
                if self.closing:
                    return
                jid, task = self.queue.popleft()
                job = self.jobs.get(jid)
                if job is None:
                    continue
                self.current = (jid, task)
            try:
                if task == "run":
                    self._run_job(job)
                else:
                    self._run_take(job, task)
            except Exception as e:  # the studio goes on whatever one job does
                with self.lock:
                    target = job if task == "run" else job["exports"].get(task, {})
                    target.update(state="failed", error=f"the studio could not run it: {type(e).__name__}: {e}"[:300])
                    self._save(job)
            finally:
                with self.lock:
                    self.current, self.proc = None, None

    def _run_job(self, job: dict) -> None:
        with self.lock:
            if job["state"] != "queued":
                return
            job.update(state="running", started=time.time(), stage="starting", progress=0.0)
            self._save(job)
        done_share = 0.0
        for cmd in job["commands"]:
            prog = Progress(PLANS[cmd["plan"]])
            base, share = done_share, cmd["share"]

            def update(p=prog, base=base, share=share):
                stage, frac, sf = p.state()
                total = max(job["progress"], base + share * frac)  # shown progress never goes back
                elapsed = time.time() - job["started"]
                eta = elapsed * (1 - total) / total if total > 0.04 and elapsed > 0.5 else None
                job.update(stage=stage, stage_progress=sf, progress=round(total, 4),
                           eta_s=None if eta is None else round(eta, 1))  # fmt: skip

            with self.lock:
                update()
            rc, err = self._spawn(job, cmd["argv"], prog, update)
            with self.lock:
                if job.pop("_cancel", False) or job.pop("_stopping", False):
                    why = "stopped with the studio" if self.closing else None
                    job.update(state="cancelled", stage="cancelled", eta_s=None, error=why)
                    self._save(job)
                    return
                if rc != 0:
                    job.update(state="failed", stage="failed", eta_s=None, error=err)
                    self._save(job)
                    return
            done_share += share
        with self.lock:
            job.update(state="done", stage="done", progress=1.0, stage_progress=None, eta_s=None,
                       finished=time.time())  # fmt: skip
            self._save(job)

    def _run_take(self, job: dict, name: str) -> None:
        with self.lock:
            x = job["exports"].get(name)
            if x is None or x["state"] != "queued":
                return
            x["state"] = "running"
        seq = SEQUENCES[job["kind"]]
        argv = ["export", TAKES[name], f"{RESULT}/{seq}", "--out", f"{RESULT}/{name}",
                "--rig", job["options"].get("rig", "anima")]  # fmt: skip
        rc, err = self._spawn(job, argv, None, None)
        with self.lock:
            x.update(state="done" if rc == 0 else "failed", error=None if rc == 0 else err)
            self._save(job)

    def _spawn(self, job: dict, argv: list[str], prog: Progress | None, update) -> tuple[int, str | None]:
        """Run ``python -m anima ARGV`` in the job's folder, its bars read into ``prog``; (exit code, the error's
        line)."""
        folder = self.folder(job["id"])
        path = [PACKAGE_ROOT] + ([os.environ["PYTHONPATH"]] if os.environ.get("PYTHONPATH") else [])
        env = os.environ | CHILD_ENV | {"PYTHONPATH": os.pathsep.join(path)}
        with self.lock:
            if self.closing or job.get("_cancel"):
                return 130, "cancelled"
            with open(folder / "log.txt", "ab") as out:
                out.write(("$ anima " + " ".join(argv) + "\n").encode())
                out.flush()
                self.proc = subprocess.Popen(
                    [self.python, "-m", "anima", *argv],
                    cwd=folder,
                    env=env,
                    stdin=subprocess.DEVNULL,
                    stdout=out,
                    stderr=subprocess.PIPE,
                    start_new_session=True,  # its own process group: cancel kills the command and its children
                )
            p = self.proc
        lines: deque = deque(maxlen=40)
        pending = b""
        with open(folder / "log.txt", "ab") as log:
            while True:
                chunk = os.read(p.stderr.fileno(), 4096)
                if not chunk:
                    break
                pending += chunk
                *segments, pending = re.split(rb"[\r\n]", pending)
                for raw in segments:
                    seg = raw.decode("utf-8", "replace")
                    bar = parse_bar(seg)
                    if bar is not None:
                        if prog is not None and prog.feed(*bar):
                            with self.lock:
                                update()
                    else:
                        text = _ANSI.sub("", seg).strip()
                        if text:
                            lines.append(text)
                            log.write((text + "\n").encode())
        rc = p.wait()
        p.stderr.close()
        return rc, None if rc == 0 else error_line(list(lines), rc)


def error_line(lines: list[str], rc: int) -> str:
    """The one line that says why a command failed: anima's own ``anima: error: ...`` (without the prefix)."""
    for text in reversed(lines):
        for prefix in ("anima: error: ", "anima: internal error: "):
            if text.startswith(prefix):
                return text[len(prefix) :][:300]
    if rc in (-signal.SIGKILL, 137):
        return "the command was killed (out of memory?)"
    if rc == 130:
        return "interrupted"
    return f"the command failed (exit code {rc}){': ' + lines[-1][:200] if lines else ''}"


def remove_job(folder: Path) -> None:
    """Remove a job folder the studio just made for an upload it refused at the door."""
    shutil.rmtree(folder, ignore_errors=True)


def dumps(obj) -> bytes:
    return json.dumps(obj, separators=(",", ":")).encode()
