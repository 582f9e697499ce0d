"""``anima live``: a real clip fed as a camera drives the character in headless Chromium over the
WebSocket (the page's own receipt times give frames/s and glass-to-avatar latency; numbers in
benchmarks/bench_live.py, tests check behaviour), Live Link Face packets leave at the tracking rate, and a
recorded take matches an offline `anima capture` of the same frames."""

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from browser import chromium, have_browser
from livelink_parser import LiveLinkParser

from anima.io.assets import asset
from anima.io.sequence import read_sequence

pytestmark = pytest.mark.slow
SHOTS = Path(os.environ.get("ANIMA_TEST_ARTIFACTS", Path(__file__).resolve().parents[2] / "test-artifacts")) / "live"
D0 = "liveportrait-examples/assets/examples/driving/d0.mp4"  # a face: a smile and blinks
D6 = "liveportrait-examples/assets/examples/driving/d6.mp4"  # a face turning, 30 fps
S13 = "liveportrait-examples/assets/examples/source/s13.mp4"  # a woman standing, full body, 25 fps


def _ctrl_c_works() -> None:
    """A runner started in the background (``cmd &``) ignores SIGINT and its children inherit that: the child
    gets Ctrl-C back, as it has in a terminal."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _live(*args):
    return subprocess.Popen(
        [sys.executable, "-m", "anima", "live", *map(str, args), "--no-browser", "--json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_ctrl_c_works,
    )


def _result(p, timeout=120):
    out, err = p.communicate(timeout=timeout)
    assert p.returncode == 0, err[-2000:]
    return json.loads(out[out.index("{") :])


def test_a_clip_fed_as_a_camera_moves_the_character_in_the_browser(tmp_path):
    assert have_browser() is None, have_browser()
    rx = LiveLinkParser(idle_s=4).__enter__()
    p = _live(asset(D6), "--face-only", "--realtime", "--loop", "--max-seconds", "90", "--livelink",
              f"127.0.0.1:{rx.port}")  # fmt: skip
    url = re.search(r"(http://127\.0\.0\.1:\d+/\S+/index\.html)", p.stdout.readline()).group(1)
    with chromium() as b:
        b.get(url)
        samples = []
        for _ in range(6):
            time.sleep(0.5)
            samples.append(b.execute_script("return [anima.live, anima.state()]"))
        b.refresh()  # a page that reloads reconnects and keeps receiving
        time.sleep(1.5)
        after = b.execute_script("return anima.live")
    p.send_signal(signal.SIGINT)  # Ctrl-C ends the take: its numbers are still printed
    r = _result(p)
    assert r["interrupted"], r
    rx.__exit__(None, None, None)
    packets = rx.packets
    live, state = samples[-1]
    assert live and live["connects"] >= 1 and live["received"] > 20, {k: live[k] for k in ("connects", "received")}
    frames = [f for f, _ in live["frames"]]
    assert frames == sorted(frames) and len(set(frames)) == len(frames)  # in order, never back in time
    lat = np.array(live["latencies"])
    assert np.isfinite(lat).all() and (lat >= 0).all() and np.median(lat) < 1000
    heads = np.array([s["joints"]["Head"] for _, s in samples])
    morphs = np.array([[s["morphs"][n] for n in ("jawOpen", "eyeBlinkLeft", "mouthSmileLeft")] for _, s in samples])
    assert np.ptp(morphs, 0).max() > 0.02 or np.ptp(heads, 0).max() > 0.005  # the character moves
    assert after["received"] > 0 and after["connects"] >= 1, after  # the reloaded page's own counters
    # the take's numbers, and Live Link packets at the tracking rate with finite, moving values
    assert r["frames_tracked"] + r["frames_dropped"] == r["frames_offered"] and r["frames_with_face"] > 0
    assert r["frames_tracked"] - 1 <= len(packets) <= r["frames_tracked"]  # the interrupt may fall before a send
    t = np.array([x for x, _ in packets])
    V = np.stack([v["values"] for _, v in packets])
    assert (len(t) - 1) / (t[-1] - t[0]) >= 20 and np.isfinite(V).all() and np.ptp(V[:, :52], 0).max() > 0.1


def test_a_recorded_take_matches_an_offline_capture(d0_capture, captures, tmp_path):
    """Every frame of a file (no --realtime) recorded live: the face-only take against `anima capture
    --face-only` of d0, the full take (one tracker, --body male) against the capture of the same 90 PATS frames:
    expression weights correlate >= 0.9 per channel that moves, joints within 2 cm median."""
    r = _result(_live(asset(D0), "--face-only", "--record", tmp_path / "face"))
    assert r["frames_dropped"] == 0 and r["record"]["frames"] == d0_capture.n_frames
    take = read_sequence(tmp_path / "face" / "capture.npz")
    for k in np.flatnonzero(d0_capture.expression.std(0) > 0.05):
        assert np.corrcoef(take.expression[:, k], d0_capture.expression[:, k])[0, 1] >= 0.9, take.expr_names[k]

    r = _result(_live(asset("gesture-video/pats-crops/oliver1_gt.mp4"), "--trackers", "1", "--max-frames", "90",
                      "--body", "male", "--record", tmp_path / "full"))  # fmt: skip
    off = captures["oliver1"]
    take = read_sequence(tmp_path / "full" / "capture.npz")
    assert take.n_frames == off.n_frames == 90 and (tmp_path / "full" / "body.bvh").is_file()
    assert take.meta["body"] == "male"  # the build the page showed is the take's, so its exports make it again
    rs = [np.corrcoef(take.expression[:, k], off.expression[:, k])[0, 1]
          for k in np.flatnonzero(off.expression.std(0) > 0.05)]  # fmt: skip
    d = np.linalg.norm(take.body_joints - off.body_joints, axis=-1)
    low = {take.expr_names[k]: round(r, 3) for k, r in zip(np.flatnonzero(off.expression.std(0) > 0.05), rs) if r < 0.9}
    print(f"full take: {len(rs)} moving channels, r min {min(rs):.3f} median {np.median(rs):.3f}; {low} "
          f"joints median {np.nanmedian(d) * 100:.1f} cm")  # fmt: skip
    assert min(rs) >= 0.9 and np.nanmedian(d) <= 0.02  # every moving channel (the take smoothed as capture is)


def test_bad_sources_and_options_are_refused(cli, tmp_path):
    for args, code, words in (
        (["nosuchfile.mp4"], 2, "not found"),
        (["rtsp://example.com/cam"], 2, "--allow-network"),
        ([str(asset(D0)), "--livelink", "nohost"], 2, "HOST:PORT"),
        ([str(asset(D0)), "--trackers", "9"], 2, "--trackers"),
        (["7"], 3, "no camera 7"),  # no camera on this machine (CI has none)
        ([], 2, "SOURCE"),
        ([str(asset(D0)), "--avatar", str(tmp_path / "none.vrm")], 2, "not found"),
        ([str(asset(D0)), "--avatar", str(asset(D0))], 2, "expected a .vrm"),
        (["--recover", str(tmp_path / "none")], 2, "no unfinished take"),
        ([str(asset(D0)), "--recover", str(tmp_path / "none")], 2, "takes no SOURCE"),
    ):
        r = cli("live", *args, "--no-browser")
        assert r.returncode == code and words in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    user = tmp_path / "mine"
    user.mkdir()
    (user / "notes.txt").write_text("mine")
    r = cli("live", asset(D0), "--no-browser", "--record", user)
    assert r.returncode == 2 and (user / "notes.txt").read_text() == "mine"


def test_a_killed_take_keeps_its_parts_and_is_recovered(tmp_path):
    """SIGKILL mid-take: the parts flushed every 2 s stay, listed in anima's marker (the folder is still anima's,
    without a manifest: partial); a new --record into it is refused with the way out; --recover writes the
    result from the parts (at most the last 2 s lost) and removes them."""
    from anima.io.outdir import check_complete, read_marker

    rec = tmp_path / "take"
    p = _live(asset(D6), "--face-only", "--realtime", "--record", rec)
    deadline = time.time() + 60
    while time.time() < deadline and len(list((rec / "take").glob("part-*.npz"))) < 3:
        time.sleep(0.2)
    p.send_signal(signal.SIGKILL)
    p.communicate(timeout=30)
    parts = sorted((rec / "take").glob("part-*.npz"))
    assert len(parts) >= 3 and not (rec / "manifest.json").exists()
    assert {f"take/{q.name}" for q in parts} <= set(read_marker(rec)["files"])
    r = subprocess.run([sys.executable, "-m", "anima", "live", str(asset(D0)), "--record", str(rec), "--no-browser"],
                       capture_output=True, text=True)  # fmt: skip
    assert r.returncode == 2 and "--recover" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    n_parts = len(set(np.concatenate([np.load(q)["index"] for q in parts]).tolist()))  # warm-up frames: twice
    r = subprocess.run([sys.executable, "-m", "anima", "live", "--recover", str(rec), "--json"],
                       capture_output=True, text=True)  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    check_complete(rec)
    take = read_sequence(rec / "capture.npz")
    assert take.n_frames >= n_parts and np.isfinite(take.expression).all() and take.expression.std(0).max() > 0.02
    assert not (rec / "take").exists() and not any(n.startswith("take/") for n in read_marker(rec)["files"])


@pytest.mark.parametrize("avatar", ["shared sample", "cut like VRoid's"])
def test_a_users_vrm_follows_the_camera_live(tmp_path, avatar):
    """--avatar: the page loads the user's VRM as it is (three-vrm) and each message poses its own bones (the
    retargeting of `anima retarget`, one frame at a time): its hands move with the tracked person's. The shared
    sample (a third party's VRM, its head a test quad) and anima's own VRM cut in meshes as VRoid's avatars are
    (a face mesh of two primitives with the morphs, a body mesh): that one also shows its face close up, its face
    morphs moving with the person's."""
    from hostile_avatars import split_like_vroid

    from anima.export.vrm import write_character_avatar

    assert have_browser() is None, have_browser()
    if avatar == "shared sample":
        vrm = asset("avatars/VRMC_materials_mtoon_UV_Animation_Test.vrm")
    else:
        vrm = split_like_vroid(write_character_avatar(tmp_path / "t.vrm"), tmp_path / "split.vrm")
    p = _live(asset("gesture-video/pats-crops/oliver1_gt.mp4"), "--realtime", "--trackers", "1", "--avatar", vrm,
              "--max-seconds", "30")  # fmt: skip
    url = re.search(r"(http://127\.0\.0\.1:\d+/\S+/index\.html)", p.stdout.readline()).group(1)
    face = (  # the close-up's canvas, and the morph weights of the close-up's face parts
        "const w = []; anima._debug.scene.traverse((o) => { if (o.isMesh && o.layers.mask === 2"
        " && o.morphTargetInfluences) w.push(...o.morphTargetInfluences); });"
        " return [!!document.getElementById('face3d'), w];"
    )
    with chromium() as b:
        b.get(url)
        samples = []
        for _ in range(8):
            time.sleep(0.6)
            samples.append(
                b.execute_script(f"return [anima.live, anima.state(), anima.error || null, (() => {{{face}}})()]")
            )
        if avatar != "shared sample":  # for people to look at: the avatar and its face close up, live
            SHOTS.mkdir(parents=True, exist_ok=True)
            (SHOTS / "live_vroid_cut.png").write_bytes(b.get_screenshot_as_png())
    p.send_signal(signal.SIGINT)
    _result(p)
    live, state, err, _ = samples[-1]
    assert err is None and live and live["received"] > 10, (err, live and live["received"])
    assert state["humanoid"] and "leftHand" in state["humanoid"], state["humanoid"]
    hands = np.array([s["humanoid"]["leftHand"] + s["humanoid"]["rightHand"] for _, s, _, _ in samples[2:]])
    assert np.isfinite(hands).all() and np.ptp(hands, 0).max() > 0.01  # the avatar's own hands move
    shown = [f for *_, f in samples[2:]]
    if avatar == "shared sample":  # no skinned head: no close-up
        assert not any(c for c, _ in shown), shown
    else:
        assert all(c for c, _ in shown), shown
        morphs = np.array([w for _, w in shown])
        print(avatar, "the close-up's face morphs move by up to", np.ptp(morphs, 0).max().round(3))
        assert morphs.shape[1] == 2 * 52 and np.ptp(morphs, 0).max() > 0.05, morphs.shape  # the face moves (ARKit 52)


def test_a_take_never_touches_what_it_did_not_start(cli, tmp_path):
    """``--record`` into an existing result is refused up front and the result stays byte-identical; a take that
    ends with nothing to record (no face, no body) removes its own parts and the folder it made, nothing else."""
    from anima.io.outdir import OutputFolder
    from anima.io.video import FFMPEG

    res = tmp_path / "result"
    with OutputFolder(res, kind="capture") as od:
        od.file("info.json").write_text('{"frames": 1}')
    before = {p.name: p.read_bytes() for p in res.iterdir()}
    r = cli("live", asset(D0), "--no-browser", "--record", res, "--max-frames", "3")
    assert r.returncode == 2 and "already holds files" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert {p.name: p.read_bytes() for p in res.iterdir()} == before
    blank = tmp_path / "blank.mp4"  # two seconds of a test card: no face, no body
    subprocess.run([FFMPEG, "-v", "error", "-f", "lavfi", "-i", "testsrc=size=160x120:rate=25", "-t", "2",
                    "-pix_fmt", "yuv420p", str(blank)], check=True)  # fmt: skip
    take = tmp_path / "take"
    r = cli("live", blank, "--no-browser", "--record", take)
    assert r.returncode == 2 and "nothing to record" in r.stderr, r.stderr
    assert not take.exists()


def test_live_sends_every_frame_over_vmc(tmp_path):
    """``anima live CLIP --realtime --vmc``: a full-body clip at 25 fps played as a camera; the VMC receiver
    (python-osc) gets at least 20 bundles a second, every humanoid bone with a unit quaternion, and bones and
    blend values that move."""
    from vmc_receiver import VmcReceiver

    with VmcReceiver(idle_s=20) as rx:
        r = _result(_live(asset(S13), "--realtime", "--vmc", f"127.0.0.1:{rx.port}"), timeout=180)
    assert not rx.bad, rx.bad[:5]
    t = np.array([f["t"] for f in rx.frames])
    rate = (len(t) - 1) / (t[-1] - t[0])  # every tracked frame arrives, at the tracking rate (2 cores: 15-20 fps)
    assert len(t) == r["frames_tracked"] and rate >= 0.9 * r["fps"] and rate >= 10, (len(t), rate, r["fps"])
    assert min(len(f["bones"]) for f in rx.frames) >= 50
    moved_bones, moved_blends = rx.moving()
    assert moved_bones >= 50 and moved_blends >= 40, (moved_bones, moved_blends)  # legs too: she stands and steps
    assert r["vmc"]["bundles_sent"] == len(rx.frames) and r["vmc"]["unsent"] == 0
