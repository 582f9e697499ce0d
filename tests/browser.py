"""The real browser of the viewer tests: the system's Chromium (Debian package ``chromium``) driven by selenium
through ``chromium-driver``, headless, with WebGL2 on SwiftShader (no GPU), and ``anima view`` served as a
user starts it.

    with served(result_dir) as url, chromium() as b:
        b.get(url); wait_ready(b); b.execute_script("return anima.state()")

Run as a script (``python tests/browser.py DIR OUT.json``) it opens ``anima view DIR``, plays it and writes
what the page reported: the offline test runs it inside a network namespace with only the loopback device.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMEDRIVER = shutil.which("chromedriver") or "/usr/bin/chromedriver"
FLAGS = [
    "--headless=new",
    "--no-sandbox",
    "--disable-gpu",
    "--use-gl=swiftshader",
    "--enable-unsafe-swiftshader",
    "--disable-dev-shm-usage",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--mute-audio",
    "--autoplay-policy=no-user-gesture-required",
    "--window-size=1280,900",
    "--allow-file-access-from-files",
]


def have_browser() -> str | None:
    """None when Chromium and its driver are installed, else what is missing."""
    missing = [p for p in (CHROMIUM, CHROMEDRIVER) if not Path(p).exists()]
    return None if not missing else f"{', '.join(missing)} missing: ./dev setup installs chromium and chromium-driver"


@contextmanager
def chromium():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for f in FLAGS:
        opts.add_argument(f)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL", "performance": "ALL"})
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)
    driver.set_page_load_timeout(60)
    driver.set_script_timeout(60)
    try:
        yield driver
    finally:
        driver.quit()


@contextmanager
def served(folder, *args):
    """``anima view FOLDER --no-browser ARGS``: yields (url, the process); stopped with SIGTERM as Ctrl-C is."""
    p = subprocess.Popen(
        [sys.executable, "-m", "anima", "view", str(folder), "--no-browser", *map(str, args)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line = p.stdout.readline()
        m = re.search(r"(http://127\.0\.0\.1:\d+/[A-Za-z0-9_-]+/index\.html)", line)
        if not m:
            p.kill()
            raise AssertionError(f"anima view printed {line!r}; stderr: {p.stderr.read()[-2000:]}")
        p.url = m.group(1)
        yield p.url, p
    finally:
        if p.poll() is None:
            p.terminate()
            try:
                p.wait(20)
            except subprocess.TimeoutExpired:
                p.kill()


def wait_ready(driver, timeout: float = 60.0) -> dict:
    t0 = time.time()
    while time.time() - t0 < timeout:
        r = driver.execute_script(
            "return window.anima ? {ready: anima.ready, error: anima.error || null, ms: anima.readyMs} : null"
        )
        if r and r["error"]:
            raise AssertionError(f"the page failed: {r['error']}; console: {console(driver)}")
        if r and r["ready"]:
            return r
        time.sleep(0.05)
    raise AssertionError(f"the page was not ready in {timeout} s; console: {console(driver)}")


def wait_media(driver, timeout: float = 30.0) -> None:
    """Until every video and the audio can play (readyState >= 3: enough data at the current time)."""
    t0 = time.time()
    js = "return [...document.querySelectorAll('video')].map(v => v.readyState)"
    while time.time() - t0 < timeout:
        if all(s >= 3 for s in driver.execute_script(js)):
            return
        time.sleep(0.05)
    raise AssertionError(f"videos not playable: readyState {driver.execute_script(js)}; console: {console(driver)}")


def console(driver) -> list[str]:
    try:
        return [e["message"] for e in driver.get_log("browser")]
    except Exception:
        return []


def requests(driver) -> list[str]:
    """Every URL the page asked for (the DevTools network log)."""
    urls = []
    for e in driver.get_log("performance"):
        msg = json.loads(e["message"])["message"]
        if msg.get("method") == "Network.requestWillBeSent":
            urls.append(msg["params"]["request"]["url"])
    return urls


def play_and_sample(driver, seconds: float = 3.0, every_ms: int = 40) -> dict:
    """Play from frame 0 and, inside the page, read its state every ``every_ms``: ``[frame the 3D view shows,
    the videos' clocks, the audio's clock, playing, seconds since play, seconds since the page's clock chose that
    frame, distinct frames the 3D view drew since play]``; then how many distinct frames it drew per second."""
    return driver.execute_async_script(
        """
        const [secs, every, done] = arguments;
        anima.seek(0);
        anima.play();
        const out = [];
        const t0 = performance.now();
        const d0 = anima.renderedFrames;
        function sample() {
          const s = anima.state();
          out.push([s.frame, s.videoTimes, s.audioTime, s.playing, (performance.now() - t0) / 1000, s.frameAge,
                    anima.renderedFrames - d0]);
          if (performance.now() - t0 < secs * 1000) return setTimeout(sample, every);
          const wall = (performance.now() - t0) / 1000;
          const r = {samples: out, drawn_frames_per_s: (anima.renderedFrames - d0) / wall, wall_s: wall};
          anima.pause();
          done(r);
        }
        setTimeout(sample, every);
        """,
        seconds,
        every_ms,
    )


def main(folder: str, out: str) -> int:
    """Open ``anima view FOLDER``, wait until ready, play 2 s: write what the page reported."""
    with served(folder) as (url, _), chromium() as b:
        b.get(url)
        ready = wait_ready(b)
        wait_media(b)
        played = play_and_sample(b, 2.0)
        result = {"ready": ready, "played": played, "requests": requests(b), "console": console(b)}
    tmp = f"{out}.{os.getpid()}.tmp"
    Path(tmp).write_text(json.dumps(result))
    os.replace(tmp, out)
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:3]))
