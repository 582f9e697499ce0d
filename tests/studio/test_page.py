"""``anima studio``'s page in a real browser (headless Chromium, as the viewer's tests drive it): a video given to
the page's file input (what a drop hands it) becomes a job whose bar rises while it runs, the finished job opens
in anima's viewer with the character drawn, and the FBX button brings ``take.fbx`` home. A second job is
cancelled from its button; a sentence typed into the page becomes a text2face job that opens in the viewer (no
BVH offered for a face). Screenshots land in ``test-artifacts/studio/`` (look at them)."""

import os
import time
from pathlib import Path

import numpy as np
import pytest
from browser import chromium, console, have_browser, wait_ready
from studio_client import CLIP, REPO, Studio

from anima.io.assets import asset

pytestmark = pytest.mark.slow
SHOTS = Path(os.environ.get("ANIMA_TEST_ARTIFACTS", REPO / "test-artifacts")) / "studio"
BACKGROUND = np.array([0x1C, 0x1C, 0x1C])
DROP_JS = """
const dt = new DataTransfer();
dt.items.add(new File(["this is not a video\\n".repeat(50)], "holiday.mp4", {type: "video/mp4"}));
const drop = new DragEvent("drop", {dataTransfer: dt, bubbles: true, cancelable: true});
document.getElementById("drop").dispatchEvent(drop);
"""
JOB_JS = """
const li = document.querySelector(`#jobs .job[data-id="${arguments[0]}"]`) || (arguments[0] ? null
  : document.querySelector('#jobs .job'));
if (!li) return null;
const bar = li.querySelector('progress');
return {id: li.dataset.id, state: li.dataset.state, bar: bar ? bar.value : null,
        stage: (li.querySelector('.stage') || {}).textContent || null};
"""


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    s = Studio(tmp_path_factory.mktemp("studio-page") / "root")
    yield s
    s.stop()


def shot(b, name: str) -> np.ndarray:
    import cv2

    SHOTS.mkdir(parents=True, exist_ok=True)
    png = b.get_screenshot_as_png()
    (SHOTS / f"{name}.png").write_bytes(png)
    return cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)[..., ::-1]


def new_job(b, known: set, timeout: float = 30) -> str:
    """The id of a job the page lists that is not in ``known``."""
    t0 = time.time()
    while time.time() - t0 < timeout:
        ids = b.execute_script("return studio.jobs.map(j => j.id)")
        fresh = [i for i in ids if i not in known]
        if fresh:
            return fresh[0]
        time.sleep(0.05)
    raise AssertionError(f"no new job on the page; console: {console(b)}")


def follow(b, jid: str | None, until, timeout: float = 180) -> list[dict]:
    """The job's row as the page shows it, sampled every 50 ms until ``until(row)``."""
    rows = []
    t0 = time.time()
    while time.time() - t0 < timeout:
        r = b.execute_script(JOB_JS, jid or "")
        if r and (not rows or rows[-1] != r):
            rows.append(r)
        if r and until(r):
            return rows
        time.sleep(0.05)
    raise AssertionError(f"the page's job did not get there in {timeout} s: {rows[-5:]}; console: {console(b)}")


def test_a_video_dropped_on_the_page_reaches_the_viewer_and_the_fbx_comes_home(page, short_clip, tmp_path):
    assert have_browser() is None, have_browser()
    downloads = tmp_path / "downloads"
    downloads.mkdir()
    with chromium() as b:
        b.execute_cdp_cmd("Browser.setDownloadBehavior", {"behavior": "allow", "downloadPath": str(downloads)})
        b.get(page.url)
        # a drop (a synthetic one: the DataTransfer a drag hands the page) of a text file named like a video
        b.execute_script(DROP_JS)
        jid = new_job(b, set())
        rows = follow(b, jid, lambda r: r["state"] != "queued", 30)
        assert rows[-1]["state"] == "failed", rows
        err = b.execute_script(f"return document.querySelector('#jobs .job[data-id=\"{jid}\"] .err').textContent")
        assert "not a video" in err, err
        # a real clip, given to the file input (what the page's drop handler hands the same code)
        b.find_element("id", "file").send_keys(str(short_clip))
        jid = new_job(b, {jid})
        rows = follow(b, jid, lambda r: r["state"] in ("done", "failed", "cancelled"))
        assert rows[-1]["state"] == "done", rows
        bars = [r["bar"] for r in rows if r["state"] == "running" and r["bar"] is not None]
        assert bars == sorted(bars) and len({v for v in bars if 0 < v < 100}) >= 3, rows  # a bar that rises
        assert any("tracking" in (r["stage"] or "") for r in rows), rows
        # the finished job opens by itself in anima's viewer, which draws the character
        t0 = time.time()
        while b.execute_script("return studio.openId") != jid and time.time() - t0 < 10:
            time.sleep(0.05)
        frame = b.find_element("id", "viewer")
        b.switch_to.frame(frame)
        wait_ready(b, 90)
        b.execute_script("anima.seek(20)")
        b.execute_async_script("const d = arguments[0]; requestAnimationFrame(() => requestAnimationFrame(d));")
        head = b.execute_script("return anima.headOnScreen()")
        b.switch_to.default_content()
        left, top = b.execute_script("const r = arguments[0].getBoundingClientRect(); return [r.left, r.top]", frame)
        img = shot(b, "done")
        x, y, r = int(left + head["x"]), int(top + head["y"]), max(4, int(head["halfWidth"]))
        patch = img[y - r : y + r, x - r : x + r].reshape(-1, 3)
        drawn = np.abs(patch.astype(int) - BACKGROUND).max(1) > 30
        assert drawn.mean() > 0.6, f"no character where the viewer says its head is: {SHOTS / 'done.png'}"
        # the FBX button: made on demand (Blender), then saved by the browser
        names = b.execute_script("return [...document.querySelectorAll('#downloads button')].map(x => x.dataset.file)")
        assert {"avatar.glb", "take.fbx", "take.vrma", "body.bvh", "arkit.csv"} <= set(names), names
        b.find_element("css selector", '#downloads button[data-file="take.fbx"]').click()
        t0 = time.time()
        fbx = downloads / "take.fbx"
        while not fbx.is_file() and time.time() - t0 < 120:
            time.sleep(0.1)
        assert fbx.is_file(), (b.execute_script("return studio.downloads"), list(downloads.iterdir()))
        time.sleep(0.3)
        assert fbx.read_bytes().startswith(b"Kaydara FBX Binary")
        assert fbx.read_bytes() == (page.root / jid / "result" / "take.fbx").read_bytes()
        # a second job, running, beside the finished one (the picture of docs/studio.md); then cancelled
        known = set(b.execute_script("return studio.jobs.map(j => j.id)"))
        b.find_element("id", "file").send_keys(str(asset(CLIP)))
        second = new_job(b, known)
        follow(b, second, lambda r: r["state"] == "running" and (r["bar"] or 0) >= 30, 120)
        shot(b, "running")
        b.find_element("css selector", f'#jobs .job[data-id="{second}"] button[data-act="cancel"]').click()
        rows = follow(b, second, lambda r: r["state"] in ("cancelled", "done", "failed"), 60)
        assert rows[-1]["state"] == "cancelled", rows
        # a sentence typed into the page: a text2face job, opened in the viewer when done
        known = set(b.execute_script("return studio.jobs.map(j => j.id)"))
        b.find_element("id", "prompt").send_keys("she smiles, then blinks twice")
        b.find_element("css selector", "#textform button").click()
        third = new_job(b, known)
        rows = follow(b, third, lambda r: r["state"] in ("cancelled", "done", "failed"), 120)
        assert rows[-1]["state"] == "done", rows
        t0 = time.time()
        while b.execute_script("return studio.openId") != third and time.time() - t0 < 10:
            time.sleep(0.05)
        names = b.execute_script("return [...document.querySelectorAll('#downloads button')].map(x => x.dataset.file)")
        assert {"take.fbx", "take.vrma", "arkit.csv"} <= set(names) and "take.bvh" not in names, names
        b.switch_to.frame(b.find_element("id", "viewer"))
        wait_ready(b, 90)
        title = b.execute_script("return document.getElementById('title').textContent")
        b.switch_to.default_content()
        assert "she smiles, then blinks twice" in title, title
        assert not [c for c in console(b) if "SEVERE" in c and "favicon" not in c], console(b)
