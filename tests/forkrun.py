"""Run many ``anima`` command lines fast: this process imports the command line once, then forks a child per
command line, so each child behaves like a fresh ``anima`` process (its own file descriptors, exit code,
stdout and stderr at the file-descriptor level, so ffmpeg or numpy chatter would be caught) without paying
the interpreter start and imports again.

    python tests/forkrun.py < cases.jsonl > results.jsonl

Each input line: ``{"id": ..., "argv": [...], "env": {...}, "timeout": s}``; each output line: ``{"id", "rc",
"stdout", "stderr", "seconds"}`` (rc -9 when the case ran past its timeout and was killed).
"""

import faulthandler
import json
import os
import signal
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# the heavy libraries most command lines load, imported once here so that each forked child does not pay for
# them again (about 1 s a case): importing starts no thread, so forking after it is safe
import cv2  # noqa: F401
import torch  # noqa: F401

import anima.capture.pipeline  # MediaPipe
import anima.dataset.build
import anima.text2face.generate  # noqa: F401
from anima.cli.main import build_parser, main

build_parser()  # and every command group's module


def run_case(case: dict) -> dict:
    out = tempfile.TemporaryFile()
    err = tempfile.TemporaryFile()
    t0 = time.perf_counter()
    pid = os.fork()
    if pid == 0:  # the child: a fresh "anima" process
        try:
            os.setsid()
            os.dup2(out.fileno(), 1)
            os.dup2(err.fileno(), 2)
            sys.stdout = os.fdopen(1, "w", buffering=1)
            sys.stderr = os.fdopen(2, "w", buffering=1)
            faulthandler.enable(sys.stderr)  # a crash (SIGABRT, SIGSEGV) leaves its Python trace in stderr
            os.environ.update(case.get("env", {}))
            try:
                code = main(case["argv"])
            except SystemExit as e:
                code = e.code if isinstance(e.code, int) else (0 if e.code is None else 2)
            sys.stdout.flush()
            sys.stderr.flush()
        except BaseException:
            code = 99
        os._exit(int(code))
    deadline = t0 + case.get("timeout", 120)
    rc = None
    while rc is None:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            rc = os.waitstatus_to_exitcode(status)
        elif time.perf_counter() > deadline:
            os.killpg(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            rc = -9
        else:
            time.sleep(0.01)
    try:  # leftovers of the child's session (ffmpeg, Ray)
        os.killpg(pid, signal.SIGKILL)
    except OSError:
        pass
    out.seek(0)
    err.seek(0)
    return {
        "id": case["id"],
        "rc": rc,
        "stdout": out.read().decode(errors="replace"),
        "stderr": err.read().decode(errors="replace"),
        "seconds": round(time.perf_counter() - t0, 3),
    }


if __name__ == "__main__":
    for line in sys.stdin:
        if line.strip():
            print(json.dumps(run_case(json.loads(line))), flush=True)
