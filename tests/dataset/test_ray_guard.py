"""A dataset build's local Ray instance listens on loopback only, and a build killed with SIGKILL (no cleanup
code can run) leaves no Ray process behind."""

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


def _listening(pids) -> list[str]:
    """``ADDRESS:PORT`` of every listening TCP socket and bound UDP socket the processes ``pids`` hold, read
    from /proc (the sockets' inodes in each process's fds, matched against /proc/net)."""
    import ipaddress

    inodes = set()
    for pid in pids:
        try:
            for fd in os.listdir(f"/proc/{pid}/fd"):
                try:
                    link = os.readlink(f"/proc/{pid}/fd/{fd}")
                except OSError:
                    continue
                if link.startswith("socket:["):
                    inodes.add(link[8:-1])
        except OSError:
            continue
    out = []
    for table in ("tcp", "tcp6", "udp", "udp6"):
        try:
            rows = open(f"/proc/net/{table}").read().splitlines()[1:]
        except OSError:
            continue
        for row in rows:
            f = row.split()
            if f[9] not in inodes or (table.startswith("tcp") and f[3] != "0A"):  # 0A: LISTEN
                continue
            hexaddr, port = f[1].split(":")
            raw = bytes.fromhex(hexaddr)
            # /proc/net writes the address as 32-bit words in host (little-endian) order
            raw = b"".join(raw[i : i + 4][::-1] for i in range(0, len(raw), 4))
            addr = ipaddress.ip_address(raw)
            if isinstance(addr, ipaddress.IPv6Address) and addr.ipv4_mapped:
                addr = addr.ipv4_mapped
            out.append(f"{addr}:{int(port, 16)}")
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
    # no Ray port of a local build (GCS, raylet, object manager, workers, agents, the driver)
    # listens beyond 127.0.0.1
    sockets = _listening([p.pid, *descendants(p.pid)])
    assert len(sockets) >= 3, sockets
    assert all(s.startswith("127.") for s in sockets), sockets
    os.kill(p.pid, signal.SIGKILL)  # the driver only: its own cleanup cannot run
    p.wait()
    deadline = time.time() + 90  # the watchdog polls; a loaded 2-core machine can take a while
    while time.time() < deadline and _ray_processes() - before:
        time.sleep(0.5)
    assert not _ray_processes() - before, "orphaned Ray processes"


def test_a_non_ray_address_is_refused_within_seconds():
    """``--address`` at a closed port or at a server that is not Ray's head is refused in seconds (Ray's own
    client waits minutes there)."""
    import http.server
    import threading

    from anima.dataset.build import check_ray_address
    from anima.errors import InputError

    srv = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.BaseHTTPRequestHandler)
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    try:
        for address, why in ((f"127.0.0.1:{srv.server_address[1]}", "not a Ray"), ("127.0.0.1:9", "no Ray")):
            t0 = time.perf_counter()
            with pytest.raises(InputError, match=why):
                check_ray_address(address)
            assert time.perf_counter() - t0 < 10
        with pytest.raises(InputError, match="HOST:PORT"):
            check_ray_address("nowhere")
    finally:
        srv.shutdown()
        srv.server_close()
