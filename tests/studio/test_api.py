"""``anima studio``'s JSON API against the real commands: a capture of an unseen 8-s talking clip and a text2face
job reach done with progress rising in steps, ``take.fbx`` (Blender) and ``take.vrma`` download and stay in the
result, every result is an ordinary anima result folder (``anima view`` reads it, its manifest verifies), a
queued or running job can be cancelled while the queue goes on, the jobs are listed again after a restart, and
nothing is answered without the token."""

import json
import shutil
import socket
import time

import pytest
from studio_client import Studio, rising_in_steps

from anima.io.assets import asset
from anima.io.outdir import check_complete
from anima.view.export import detect

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def studio(tmp_path_factory):
    s = Studio(tmp_path_factory.mktemp("studio") / "root")
    yield s
    s.stop()


def test_the_api_refuses_a_call_without_the_token(studio):
    assert studio.request("GET", "/api/jobs", token=None)[0] == 401
    assert studio.request("GET", "/api/jobs", token="not-the-token")[0] == 403
    assert studio.request("GET", "/", token=None)[0] == 401
    assert studio.request("GET", "/?token=" + studio.token, token=None)[0] == 200
    assert studio.request("GET", "/api/jobs?token=" + studio.token, token=None)[0] == 200
    status, _, body = studio.request("POST", "/api/jobs", b"x", {"Content-Type": "text/plain"}, token=None)
    assert status == 401 and b"token" in body
    assert studio.request("DELETE", "/api/jobs/20260101-000000-abcdef", token=None)[0] == 401
    assert studio.request("GET", "/view/wrong/20260101-000000-abcdef/index.html", token=None)[0] == 404
    # another origin, another host name (DNS rebinding), a page of another site: refused with the token
    assert studio.request("GET", "/api/jobs", headers={"Origin": "http://evil.example"})[0] == 403
    assert studio.request("GET", "/api/jobs", headers={"Sec-Fetch-Site": "cross-site"})[0] == 403
    with socket.create_connection(("127.0.0.1", studio.port), timeout=10) as c:
        c.sendall(f"GET /api/jobs?token={studio.token} HTTP/1.1\r\nHost: evil.example:{studio.port}\r\n\r\n".encode())
        assert c.recv(100).split(b" ")[1] == b"421"  # answered, not served
    assert studio.get_json("/api/jobs")[0] == 200  # and still answering


def test_a_text_file_sent_as_a_video_is_a_failed_job_with_one_line(studio):
    status, r = studio.submit({"kind": "capture"}, {"file": b"hello, this is not a video\n" * 20})
    assert status == 201 and r["state"] == "failed", r
    j = studio.job(r["id"])
    assert j["state"] == "failed" and "\n" not in j["error"] and "not a video" in j["error"], j
    assert "upload" not in j["error"] and str(studio.root) not in j["error"]  # no file names of the studio's


def test_text2face_reaches_done_with_progress_in_steps(studio):
    status, r = studio.submit({"kind": "text2face", "prompt": "a woman smiles, then blinks twice"})
    assert status == 201 and r["state"] == "queued", r
    j, seen = studio.wait(r["id"], 120)
    assert j["state"] == "done", (j, seen)
    steps = [p for p in rising_in_steps(seen) if 0 < p < 1]
    assert len(steps) >= 3, seen  # the render's bar, read as it moves
    assert {"composing", "rendering"} <= {st for _, _, st, _ in seen}, seen
    assert {"motion.npz", "avatar.glb", "arkit.csv", "face.mp4"} <= set(j["outputs"]), j
    result = studio.root / r["id"] / "result"
    assert detect(result) == "text2face"  # an ordinary result: anima view, info, export read it
    check_complete(result)
    vrma = studio.take(r["id"], "take.vrma")
    assert vrma[:4] == b"glTF"
    assert "take.vrma" in studio.job(r["id"])["outputs"]
    assert studio.job(r["id"])["takes"] == ["take.fbx", "take.vrma"]  # no BVH of a face without a body
    assert studio.request("GET", f"/api/jobs/{r['id']}/files/take.bvh")[0] == 404


def test_a_capture_of_an_unseen_talking_clip_gives_fbx_and_vrma(studio, clip):
    t0 = time.time()
    status, r = studio.submit({"kind": "capture", "options": json.dumps({"max_seconds": 8})}, {"file": clip})
    assert status == 201 and r["state"] == "queued", r
    j, seen = studio.wait(r["id"], 240)
    took = time.time() - t0
    assert j["state"] == "done", (j, seen)
    steps = [p for p in rising_in_steps(seen) if 0 < p < 1]
    assert len(steps) >= 6, seen
    stages = [st for s, _, st, _ in seen if s == "running"]
    assert stages.index("tracking") < stages.index("rendering"), stages
    left = [e for s, p, _, e in seen if s == "running" and e is not None]
    assert left and all(e >= 0 for e in left) and j["eta_s"] is None, seen  # time left while it runs
    result = studio.root / r["id"] / "result"
    assert detect(result) == "capture"
    assert {"capture.npz", "avatar.glb", "body.bvh", "arkit.csv", "overlay.mp4"} <= set(j["outputs"])
    from anima.io.sequence import read_sequence

    seq = read_sequence(result / "capture.npz", landmarks=False)
    assert seq.n_frames == 200 and seq.tracked.mean() > 0.9  # 8 s at 25 fps, a face throughout
    assert shutil.which("blender"), "Blender makes the FBX: ./dev setup installs it"
    fbx = studio.take(r["id"], "take.fbx", 180)
    assert fbx.startswith(b"Kaydara FBX Binary"), fbx[:40]
    vrma = studio.take(r["id"], "take.vrma")
    assert vrma[:4] == b"glTF" and b"VRMC_vrm_animation" in vrma[:20000]
    # kept in the result: asked again, answered at once; the result still verifies against its manifest
    assert (result / "take.fbx").read_bytes() == fbx
    t1 = time.time()
    status, headers, body = studio.request("GET", f"/api/jobs/{r['id']}/files/take.fbx")
    assert status == 200 and body == fbx and time.time() - t1 < 5
    assert 'filename="take.fbx"' in headers.get("Content-Disposition", "")
    check_complete(result)
    status, _, csv = studio.request("GET", f"/api/jobs/{r['id']}/files/arkit.csv")
    assert status == 200 and csv.startswith(b"Timecode")
    assert studio.request("GET", f"/api/jobs/{r['id']}/files/job.json")[0] == 404  # only the result's files
    assert studio.request("GET", f"/api/jobs/{r['id']}/files/..%2Fjob.json")[0] == 404
    print(f"capture of 8 s: {took:.1f} s to done; {len(steps)} progress steps")


def test_gestures_for_speech_on_your_avatar_and_a_retarget_job(studio):
    """A speech file with a VRM: gestures, then the motion on the VRM (one job, its stages in turn); a retarget job
    puts a finished job's motion on the avatar, and its viewer page is built with it."""
    speech = asset("videoretalking-examples/examples/audio/1.wav").read_bytes()
    vrm = asset("avatars/VRMC_materials_mtoon_UV_Animation_Test.vrm").read_bytes()
    status, r = studio.submit({"kind": "gesture", "options": json.dumps({"rig": "mixamo"})},
                              {"file": speech, "avatar": vrm})  # fmt: skip
    assert status == 201 and r["state"] == "queued", r
    j, seen = studio.wait(r["id"], 120)
    assert j["state"] == "done", (j, seen)
    rising_in_steps(seen)
    stages = [st for s, _, st, _ in seen if s == "running"]
    assert stages.index("rendering") < stages.index("retargeting"), stages
    assert {"gesture.npz", "avatar.glb", "body.bvh", "speech.wav", "retargeted.vrm"} <= set(j["outputs"]), j
    assert b"mixamorig:" in studio.take(r["id"], "take.bvh")[:4000]  # the joint names asked for
    status, _, out = studio.request("GET", f"/api/jobs/{r['id']}/files/retargeted.vrm")
    assert status == 200 and out[:4] == b"glTF"
    # a retarget job: the motion of a finished job on an avatar sent now
    status, t = studio.submit({"kind": "retarget", "source": r["id"]}, {"avatar": vrm})
    assert status == 201, t
    j, _ = studio.wait(t["id"], 60)
    assert j["state"] == "done" and j["outputs"] == ["retargeted.vrm"], j
    for name in ("index.html", "view-data.js", "avatar-glb.js"):
        status, _, body = studio.request("GET", f"/view/{studio.token}/{t['id']}/{name}", token=None)
        assert status == 200 and body, name
    assert studio.submit({"kind": "retarget", "source": "20200101-000000-000000"}, {"avatar": vrm})[0] == 400


def test_cancel_a_running_and_a_queued_job_and_the_queue_goes_on(studio, clip):
    _, a = studio.submit({"kind": "capture"}, {"file": clip})
    _, b = studio.submit({"kind": "text2face", "prompt": "he frowns"})
    _, c = studio.submit({"kind": "text2face", "prompt": "she smiles"})
    j, _ = studio.wait(a["id"], 60, until=("running",))
    while studio.job(a["id"])["stage"] != "tracking":
        time.sleep(0.05)
    assert studio.request("DELETE", f"/api/jobs/{b['id']}")[0] == 200  # queued: never runs
    status, _, body = studio.request("DELETE", f"/api/jobs/{a['id']}")
    assert status == 200, body
    j, _ = studio.wait(a["id"], 30)
    assert j["state"] == "cancelled" and j["outputs"] == []
    assert studio.job(b["id"])["state"] == "cancelled"
    j, _ = studio.wait(c["id"], 120)
    assert j["state"] == "done"
    assert studio.request("DELETE", f"/api/jobs/{c['id']}")[0] == 409  # done: nothing to cancel


def test_earlier_results_are_listed_after_a_restart(studio, clip):
    """Stopped while a job runs and another waits: the running one is cancelled with the reason, the waiting one
    runs when the studio is started again, and every finished job is listed with its files."""
    _, before = studio.get_json("/api/jobs")
    done = {j["id"]: j["outputs"] for j in before["jobs"] if j["state"] == "done"}
    assert len(done) >= 3
    _, running = studio.submit({"kind": "capture"}, {"file": clip})
    _, waiting = studio.submit({"kind": "text2face", "prompt": "she raises her brows"})
    studio.wait(running["id"], 60, until=("running",))
    studio.stop()
    again = Studio(studio.root)
    try:
        j = again.job(running["id"])
        assert j["state"] == "cancelled" and "stopped" in j["error"], j
        j, _ = again.wait(waiting["id"], 120)
        assert j["state"] == "done", j
        _, after = again.get_json("/api/jobs")
        assert {j["id"]: j["outputs"] for j in after["jobs"] if j["state"] == "done"} == done | {j["id"]: j["outputs"]}
        jid = next(iter(done))
        assert again.request("GET", f"/api/jobs/{jid}/files/avatar.glb")[0] == 200
        assert again.request("GET", "/api/jobs", token=studio.token)[0] == 403  # a new run, a new token
    finally:
        again.stop()
