from anima.eval.body import body_report_clip, hand_images_report
from anima.io.assets import asset


def test_body_report_on_a_pats_clip():
    r = body_report_clip(str(asset("gesture-video/pats-crops/oliver3_gt.mp4")), max_frames=80)
    assert r["frames"] == 80 and r["body_tracked"] == 1.0
    assert r["left_hand_after_interpolation"] >= r["left_hand_tracked"] - 0.05
    assert r["bone_cv_cleaned"] < r["bone_cv_raw"]


def test_hand_detector_on_still_images():
    rows = hand_images_report()
    assert len(rows) == 3 and all(r["hands_found"] >= 1 for r in rows)
