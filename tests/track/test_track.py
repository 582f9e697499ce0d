"""The trackers' table (``anima.track``): names, the generated ``--tracker`` option, and what the MediaPipe tracker
gives per frame on a real clip."""

import numpy as np
import pytest

from anima.errors import InputError
from anima.track import DEFAULT, TRACKERS, HolisticFrame, get


def test_the_table_names_its_trackers_and_refuses_others():
    assert DEFAULT in TRACKERS and get() is TRACKERS[DEFAULT] and get("mediapipe").name == "mediapipe"
    with pytest.raises(InputError, match="unknown tracker 'nope': use mediapipe") as e:
        get("nope")
    assert e.value.exit_code == 2


@pytest.mark.parametrize("command", [["capture", "v.mp4", "--out", "o"], ["live", "0"]])
def test_capture_and_live_take_the_tracker_option(command, capsys):
    from anima.cli.main import build_parser

    p = build_parser(command[0])
    assert p.parse_args([*command, "--tracker", "mediapipe"]).tracker == "mediapipe"
    assert p.parse_args(command).tracker == DEFAULT
    with pytest.raises(SystemExit) as e:
        p.parse_args([*command, "--tracker", "nope"])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "invalid choice: 'nope'" in err[0]


@pytest.mark.slow
def test_mediapipe_gives_landmarks_bodies_and_boxes_on_a_real_frame(d0_path):
    from anima.io.video import iter_frames, probe_video

    rgb = next(iter(iter_frames(probe_video(d0_path))))
    t = get()
    with t.face_mesh(static=True) as face:
        lm = face(rgb)
        assert lm.shape == (478, 3) and lm.dtype == np.float32 and face(np.zeros_like(rgb)) is None
    with t.holistic() as h:
        fr = h(rgb)
    assert isinstance(fr, HolisticFrame) and fr.face.shape == (478, 3)
    with t.face_boxes() as boxes:
        (b,) = boxes(rgb)
    assert 0 < b.width < 1 and b.xmin <= lm[1, 0] <= b.xmin + b.width  # the nose tip inside the face's box
    assert t.face_mesh_triangles().shape == (854, 3) and len(t.lip_landmarks()) == 40
    prov = t.face_provenance()
    assert prov["name"] == "mediapipe.face_mesh" and prov["landmarks"] == 478 and prov["version"] == t.version()
    assert t.body_provenance() == "mediapipe.holistic (model_complexity=1)"
