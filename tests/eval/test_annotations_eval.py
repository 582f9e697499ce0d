from anima.eval.annotations import capture_labelled, load_labels, score


def test_detectors_find_the_labelled_smile_and_blink_of_d0():
    lab = next(l for l in load_labels() if l["name"] == "d0")
    r = score([(capture_labelled(lab), lab)])
    assert r["smile"]["recall"] == 1.0 and r["smile"]["precision"] == 1.0
    assert r["blink"]["recall"] == 1.0
    assert r["yawn"]["detections"] == 0 and r["talk"]["detections"] == 0


def test_labels_are_well_formed():
    labs = load_labels()
    assert len(labs) >= 6
    for lab in labs:
        for attr, ranges in lab["labels"].items():
            assert all(0 <= a <= b < lab["frames"] for a, b in ranges), (lab["name"], attr)
