"""A dataset build killed with SIGKILL (no cleanup code can run) leaves no Ray process behind."""

import os
import signal
import subprocess
import sys
import time

import pytest

from anima.dataset.ray_guard import descendants
from anima.io.assets import asset

pytestmark = pytest.mark.slow


def _ray_processes() -> set[int]:
    out = set()
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                cmd = open(f"/proc/{d}/cmdline", "rb").read()
            except OSError:
                continue
            if b"ray::" in cmd or b"raylet" in cmd or b"gcs_server" in cmd or b"ray/dashboard" in cmd:
                out.add(int(d))
    return out


def test_killed_driver_leaves_no_ray_agents(tmp_path):
    before = _ray_processes()
    clip = asset("gesture-video/pats-crops/oliver1_gt.mp4")
    p = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "anima",
            "dataset",
            "build",
            str(clip),
            "--out",
            str(tmp_path / "ds"),
            "--min-len",
            "2",
            "--workers",
            "1",
            "--quiet",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.time() + 120
    while time.time() < deadline and not descendants(p.pid):
        time.sleep(0.2)
    time.sleep(3)  # Ray's agents are up
    assert _ray_processes() - before, "Ray did not start"
    os.kill(p.pid, signal.SIGKILL)  # the driver only: its own cleanup cannot run
    p.wait()
    deadline = time.time() + 90  # the watchdog polls; a loaded 2-core machine can take a while
    while time.time() < deadline and _ray_processes() - before:
        time.sleep(0.5)
    assert not _ray_processes() - before, "orphaned Ray processes"
