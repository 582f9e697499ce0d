"""No orphaned Ray processes: a small watchdog process that outlives a dataset build's driver.

While the driver runs, the watchdog records the driver's Ray descendants (raylet, GCS, agents, workers) every
half second; when the driver is gone (finished, interrupted, or killed with SIGKILL, when no cleanup code of
its own can run), it kills whichever of them are still alive (Ray's dashboard and runtime-env agents ignore
SIGTERM and would otherwise stay). Process identity is (pid, start time), so a reused pid is never touched.

``python -m anima.dataset.ray_guard DRIVER_PID`` (started by :func:`start`); stdlib only, so it starts fast.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path


def _stat(pid: int) -> tuple[int, int] | None:
    """(parent pid, start time) of ``pid`` from /proc, or None when it is gone."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = text[text.rindex(")") + 2 :].split()
    return int(fields[1]), int(fields[19])


def _is_ray(pid: int) -> bool:
    try:
        cmd = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ")
    except OSError:
        return False
    return b"ray" in cmd


def descendants(root: int) -> dict[int, int]:
    """``{pid: start time}`` of the Ray processes below ``root``."""
    parent = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            st = _stat(int(d))
            if st:
                parent[int(d)] = st
    out, frontier = {}, [root]
    while frontier:
        p = frontier.pop()
        for c, (pp, start) in parent.items():
            if pp == p and c not in out:
                out[c] = start
                frontier.append(c)
    return {p: s for p, s in out.items() if _is_ray(p)}


def watch(driver: int, period: float = 0.5) -> int:
    seen: dict[int, int] = {}
    while _stat(driver) is not None:
        seen.update(descendants(driver))
        time.sleep(period)
    killed = 0
    for pid, start in seen.items():
        st = _stat(pid)
        if st is not None and st[1] == start:
            try:
                os.kill(pid, signal.SIGKILL)
                killed += 1
            except OSError:
                pass
    return killed


def start(driver: int | None = None) -> None:
    """Start the watchdog of ``driver`` (default: this process), detached: an intermediate process launches it
    in its own session and exits, so the watchdog is not the driver's child (Ray kills the children of a
    driver that exits, which would take the watchdog with it)."""
    subprocess.run(
        [sys.executable, "-m", "anima.dataset.ray_guard", "--detach", str(driver or os.getpid())],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        check=False,
        timeout=30,
    )


if __name__ == "__main__":
    if sys.argv[1] == "--detach":
        subprocess.Popen(
            [sys.executable, "-m", "anima.dataset.ray_guard", sys.argv[2]],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
            close_fds=True,
        )
    else:
        watch(int(sys.argv[1]))
