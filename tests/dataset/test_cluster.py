"""A dataset build on a real two-node Ray cluster survives losing a node: a head and a second node,
each started with ``ray start`` (token authentication, the nodes' own processes found and stopped by process
id, never a broad kill), ``anima dataset build --address``, the second node killed with SIGKILL while it works on
a video. The build finishes with every video, the output of a one-node build, and says which node made what."""

import json
import os
import random
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

from anima.dataset.ray_guard import descendants
from anima.io.assets import asset

pytestmark = pytest.mark.slow
CLIPS = [f"gesture-video/pats-crops/{n}_gt.mp4" for n in ("oliver4", "seth2", "noah2")]
RAY = str(Path(sys.executable).parent / "ray")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return ""


def _pids(needle: str) -> set[int]:
    return {int(d) for d in os.listdir("/proc") if d.isdigit() and needle in _cmdline(int(d))}


class Cluster:
    """Two Ray nodes on this machine; every process of each is recorded so that one node can be killed and
    everything stopped by process id."""

    def __init__(self, tmp: Path):
        self.tmp, self.port = tmp, _free_port()
        self.env = {
            **os.environ,
            "RAY_AUTH_MODE": "token",
            "RAY_AUTH_TOKEN": secrets.token_hex(32),
            "RAY_USAGE_STATS_ENABLED": "0",
        }
        self.env.pop("RAY_ADDRESS", None)
        self.env.pop("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", None)  # (anima's loopback switch: one node only)
        # Ray's socket paths must stay under 107 bytes: a short folder of its own
        self.session = tempfile.mkdtemp(prefix="anima-rc-", dir="/tmp")
        self.head: set[int] = set()
        self.node2_raylet: int | None = None

    def _start(self, *args):
        r = subprocess.run([RAY, "start", *args], env=self.env, capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]

    def start(self):
        self._start("--head", "--port", str(self.port), "--node-ip-address", "127.0.0.1", "--num-cpus", "1",
                    "--include-dashboard", "false", "--disable-usage-stats", "--temp-dir", self.session)  # fmt: skip
        self.head = _pids(self.session)
        before = {p for p in self.head if "raylet/raylet" in _cmdline(p)}
        self._start("--address", f"127.0.0.1:{self.port}", "--node-ip-address", "127.0.0.1", "--num-cpus", "1")
        raylets = {p for p in _pids(self.session) if "raylet/raylet" in _cmdline(p)} - before
        assert len(raylets) == 1, raylets
        self.node2_raylet = raylets.pop()

    def node2(self) -> set[int]:
        return {self.node2_raylet, *descendants(self.node2_raylet)}

    def busy_on_node2(self) -> bool:
        return any("ray::_task" in _cmdline(p) or "ray::_assemble" in _cmdline(p) for p in self.node2())

    def kill_node2(self):
        for p in self.node2():
            try:
                os.kill(p, signal.SIGKILL)
            except OSError:
                pass

    def stop(self):
        pids = _pids(self.session)
        for p in list(pids):
            pids |= set(descendants(p))
        pids |= self.node2() if self.node2_raylet else set()
        for p in pids:
            try:
                os.kill(p, signal.SIGKILL)
            except OSError:
                pass
        deadline = time.time() + 15
        while time.time() < deadline and any(Path(f"/proc/{p}").exists() for p in pids):
            time.sleep(0.1)


def _build(args, env, timeout=600):
    return subprocess.run(
        [sys.executable, "-m", "anima", "dataset", "build", *map(str, args)],
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def test_a_build_on_two_nodes_survives_losing_one(tmp_path):
    clips = [asset(c) for c in CLIPS]
    common = ["--min-len", "1", "--max-len", "2", "--max-frames", "50", "--quiet", "--json"]
    ref = _build([*clips, "--out", tmp_path / "one", "--workers", "1", *common], os.environ)
    assert ref.returncode == 0, ref.stderr[-2000:]
    seed = random.randrange(10**6)
    rng = random.Random(seed)
    cluster = Cluster(tmp_path)
    try:
        cluster.start()
        p = subprocess.Popen(
            [sys.executable, "-m", "anima", "dataset", "build", *map(str, clips), "--out", str(tmp_path / "two"),
             "--address", f"127.0.0.1:{cluster.port}", *common],
            env=cluster.env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        deadline = time.time() + 180
        while time.time() < deadline and not cluster.busy_on_node2() and p.poll() is None:
            time.sleep(0.1)
        assert cluster.busy_on_node2(), f"no task ran on the second node (seed {seed})"
        time.sleep(rng.uniform(0.0, 2.0))  # a random point of its video
        cluster.kill_node2()
        out, err = p.communicate(timeout=600)
        assert p.returncode == 0, f"seed {seed}: {err[-2000:]}"
    finally:
        cluster.stop()
        shutil.rmtree(cluster.session, ignore_errors=True)
    assert out.strip(), f"seed {seed}: no summary; stderr {err[-3000:]}"
    assert out.lstrip().startswith("{"), out[:1000]
    two, one = json.loads(out), json.loads(ref.stdout)
    assert two["videos_done"] == one["videos_done"] == len(CLIPS) and two["videos_failed"] == 0, seed
    assert two["clips_kept"] == one["clips_kept"] and two["windows"] == one["windows"], seed
    manifest = json.loads((tmp_path / "two" / "manifest.json").read_text())
    nodes = manifest["last_run"]["videos_per_node"]
    assert sum(len(v) for v in nodes.values()) == len(CLIPS) and "None" not in nodes  # who made what
    from anima.dataset.storage import read_table

    a = read_table(tmp_path / "one", "text_motion").to_pydict()
    b = read_table(tmp_path / "two", "text_motion").to_pydict()
    order_a, order_b = np.argsort(a["clip_id"]), np.argsort(b["clip_id"])
    assert [a["clip_id"][i] for i in order_a] == [b["clip_id"][i] for i in order_b]
    for i, j in zip(order_a, order_b):  # the same motion (MediaPipe on the same frames)
        np.testing.assert_allclose(np.asarray(a["motion"][i]), np.asarray(b["motion"][j]), atol=1e-4)
    shutil.rmtree(cluster.session, ignore_errors=True)
