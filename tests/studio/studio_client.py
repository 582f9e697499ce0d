"""``anima studio`` as a person starts it (``python -m anima studio --no-browser``, its address read from the one
line it prints), and a small client of its JSON API that speaks plain HTTP (urllib, a multipart body built by
hand, so nothing of the studio's own code is on the client's side)."""

from __future__ import annotations

import json
import os
import re
import secrets
import signal
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
CLIP = "gesture-video/pats-crops/noah2_gt.mp4"  # a talking man, 9.6 s, used by no other test
SHORT = "gesture-video/pats-crops/oliver4_gt.mp4"  # 3.2 s


class Studio:
    def __init__(self, root: Path, *args, cwd: Path | None = None, env: dict | None = None):
        self.root = Path(root)
        env = dict(os.environ if env is None else env)
        env["PYTHONPATH"] = str(REPO)  # this checkout's anima, wherever the studio's working folder is
        self.p = subprocess.Popen(
            [sys.executable, "-m", "anima", "studio", "--root", str(root), "--no-browser", *map(str, args)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            cwd=cwd,
            env=env,
        )
        line = self.p.stdout.readline()
        m = re.fullmatch(r"studio: (http://127\.0\.0\.1:(\d+))/\?token=([A-Za-z0-9_-]+)\n", line)
        if not m:
            self.p.kill()
            raise AssertionError(f"anima studio printed {line!r}; stderr: {self.p.stderr.read()[-2000:]}")
        self.base, self.port, self.token = m.group(1), int(m.group(2)), m.group(3)
        self.url = f"{self.base}/?token={self.token}"

    def stop(self) -> str:
        if self.p.poll() is None:
            self.p.send_signal(signal.SIGTERM)
            try:
                self.p.wait(30)
            except subprocess.TimeoutExpired:
                self.p.kill()
        err = self.p.stderr.read()
        assert "Traceback" not in err, err[-3000:]
        return err

    def request(self, method: str, path: str, body: bytes | None = None, headers: dict | None = None,
                token: str | None | bool = True) -> tuple[int, dict, bytes]:  # fmt: skip
        h = dict(headers or {})
        if token is True:
            h["X-Anima-Token"] = self.token
        elif token:
            h["X-Anima-Token"] = token
        req = urllib.request.Request(self.base + path, data=body, method=method, headers=h)
        try:
            with urllib.request.urlopen(req, timeout=60) as r:
                return r.status, dict(r.headers), r.read()
        except urllib.error.HTTPError as e:
            return e.code, dict(e.headers), e.read()

    def get_json(self, path: str, **kw) -> tuple[int, dict]:
        status, _, body = self.request("GET", path, **kw)
        return status, json.loads(body)

    def submit(self, fields: dict, files: dict | None = None, filenames: dict | None = None) -> tuple[int, dict]:
        body, ctype = multipart(fields, files or {}, filenames or {})
        status, _, out = self.request("POST", "/api/jobs", body, {"Content-Type": ctype})
        return status, json.loads(out)

    def job(self, jid: str) -> dict:
        status, j = self.get_json(f"/api/jobs/{jid}")
        assert status == 200, j
        return j

    def wait(self, jid: str, timeout: float = 240, until=("done", "failed", "cancelled")) -> tuple[dict, list]:
        """Poll a job every 50 ms until it is in one of ``until``: (the job, every (state, progress, stage, seconds
        left) seen)."""
        seen = []
        t0 = time.time()
        while time.time() - t0 < timeout:
            j = self.job(jid)
            s = (j["state"], j["progress"], j["stage"], j["eta_s"])
            if not seen or seen[-1] != s:
                seen.append(s)
            if j["state"] in until:
                return j, seen
            time.sleep(0.05)
        raise AssertionError(f"job {jid} not {until} in {timeout} s: {seen[-5:]}")

    def take(self, jid: str, name: str, timeout: float = 120) -> bytes:
        """A take file, asked for until it is made (202 while queued or being made)."""
        t0 = time.time()
        while time.time() - t0 < timeout:
            status, headers, body = self.request("GET", f"/api/jobs/{jid}/files/{name}")
            if status == 200:
                return body
            assert status == 202, (status, body[:300])
            time.sleep(0.2)
        raise AssertionError(f"{name} of {jid} not made in {timeout} s")


def multipart(fields: dict, files: dict, filenames: dict) -> tuple[bytes, str]:
    boundary = "----studio" + secrets.token_hex(8)
    out = b""
    for k, v in fields.items():
        out += f'--{boundary}\r\nContent-Disposition: form-data; name="{k}"\r\n\r\n'.encode() + str(v).encode()
        out += b"\r\n"
    for k, data in files.items():
        name = filenames.get(k, "upload.bin")
        out += (f'--{boundary}\r\nContent-Disposition: form-data; name="{k}"; filename="{name}"\r\n'
                "Content-Type: application/octet-stream\r\n\r\n").encode() + data + b"\r\n"  # fmt: skip
    out += f"--{boundary}--\r\n".encode()
    return out, f"multipart/form-data; boundary={boundary}"


def rising_in_steps(seen: list) -> list[float]:
    """The progress values a running job showed: they never go down."""
    values = [p for s, p, *_ in seen if s == "running"]
    assert values == sorted(values), values
    return sorted(set(values))
