"""The character's rig: a full skeleton in a T-pose rest with exact export presets, the person's
proportions chosen from the captured bone lengths, every tracked bone followed on the character's own lengths,
legs seated or standing with the feet on the floor, and joints that come back blending in instead of snapping."""

import dataclasses

import numpy as np
import pytest

from anima.core import rig
from anima.core.rotations import matrix_to_rotvec
from anima.io.assets import asset

pytestmark = pytest.mark.slow  # MediaPipe on four real clips


@pytest.fixture(scope="module")
def motions(captures):
    from anima.export.avatar import character_motion

    return {n: character_motion(seq) for n, seq in captures.items()}


def _angle(a, b):
    c = (a * b).sum(-1) / np.linalg.norm(a, axis=-1) / np.linalg.norm(b, axis=-1)
    return np.degrees(np.arccos(np.clip(c, -1, 1)))


def test_the_rest_pose_is_a_t_pose_and_the_presets_are_exact():
    from anima.facemodel.character import load_character

    rest = load_character().joints
    d = lambda a, b: (rest[rig.IX[b]] - rest[rig.IX[a]]) / np.linalg.norm(rest[rig.IX[b]] - rest[rig.IX[a]])
    for side, sx in (("Left", 1), ("Right", -1)):
        for a, b in (("Arm", "ForeArm"), ("ForeArm", "Hand"), ("HandMiddle1", "HandMiddle2")):
            np.testing.assert_allclose(d(f"{side}{a}", f"{side}{b}"), (sx, 0, 0), atol=1e-3)
        np.testing.assert_allclose(d(f"{side}UpLeg", f"{side}Leg"), (0, -1, 0), atol=1e-3)
        assert rest[rig.IX[f"{side}Toe_End"], 2] > rest[rig.IX[f"{side}Foot"], 2] + 0.1  # the feet point forwards
    assert d("Spine", "Neck")[1] > 0.97 and rest[:, 1].min() > -0.01  # the spine up, nothing below the floor
    assert len(set(rig.NAMES)) == rig.N_RIG == 65 and all(rig.PARENTS_RIG[j] < j for j in range(1, rig.N_RIG))
    for preset in rig.PRESETS:
        assert len(set(rig.preset_names(preset))) == rig.N_RIG
    mixamo = rig.preset_names("mixamo")  # Mixamo's names and its hierarchy
    parent = {mixamo[j]: mixamo[rig.PARENTS_RIG[j]] for j in range(1, rig.N_RIG)}
    assert (
        parent["mixamorig:LeftArm"] == "mixamorig:LeftShoulder"
        and parent["mixamorig:LeftShoulder"] == "mixamorig:Spine2"
    )
    assert parent["mixamorig:Spine2"] == "mixamorig:Spine1" and parent["mixamorig:LeftUpLeg"] == "mixamorig:Hips"
    assert (
        parent["mixamorig:LeftHandIndex1"] == "mixamorig:LeftHand"
        and parent["mixamorig:HeadTop_End"] == "mixamorig:Head"
    )
    vrm = dict(zip(rig.NAMES, rig.preset_names("vrm")))
    assert (
        vrm["Spine1"] == "chest"
        and vrm["LeftForeArm"] == "leftLowerArm"
        and vrm["LeftHandThumb1"] == "leftThumbMetacarpal"
    )
    assert vrm["LeftToeBase"] == "leftToes" and vrm["RightHandPinky3"] == "rightLittleDistal"
    ue = dict(zip(rig.NAMES, rig.preset_names("unreal")))
    assert ue["Hips"] == "pelvis" and ue["LeftArm"] == "upperarm_l" and ue["RightToeBase"] == "ball_r"


def test_every_tracked_bone_is_followed_on_the_characters_own_lengths(captures, motions):
    from anima.core.contract import JOINT_NAMES

    T = {n: i for i, n in enumerate(JOINT_NAMES)}
    for name, seq in captures.items():
        m = motions[name]
        P = m["positions"]
        G, fk = rig.forward(m["local"], m["rest"], m["root"])
        np.testing.assert_allclose(fk, P, atol=1e-9)  # the positions are the rotations' forward kinematics
        off = np.linalg.norm(rig.rest_offsets(m["rest"])[1:], axis=-1)
        L = np.linalg.norm(P[:, 1:] - P[:, rig.PARENTS_RIG[1:]], axis=-1)
        np.testing.assert_allclose(L, np.broadcast_to(off, L.shape), atol=1e-9)  # one skeleton, every frame
        J = seq.body_joints
        for S, s in (("Left", "left"), ("Right", "right")):
            for a, b, ta, tb in (("Arm", "ForeArm", "shoulder", "elbow"), ("ForeArm", "Hand", "elbow", "wrist")):
                got = P[:, rig.IX[f"{S}{b}"]] - P[:, rig.IX[f"{S}{a}"]]
                want = J[:, T[f"{s}_{tb}"]] - J[:, T[f"{s}_{ta}"]]
                ok = np.isfinite(want).all(-1)
                assert np.median(_angle(got[ok], want[ok])) < 1.0, (name, S, a)
        steps = np.linalg.norm(np.diff(P, axis=0), axis=-1)
        assert steps.max() < 0.20, (name, steps.max())  # no joint jumps 20 cm in a frame (40 ms)
        feet = P[:, [rig.IX["LeftFoot"], rig.IX["RightFoot"]]]
        assert feet[..., 1].min() > 0.03 and np.ptp(feet[..., 1]) < 0.01, name  # the feet on the floor
        assert m["report"]["legs"].startswith("seated"), name  # hosts at their desks: hips at the bottom edge


def test_the_character_has_the_persons_proportions(captures, motions):
    """The captured arm (shoulder to wrist) chooses the character's within 10 % on the shared gesture clips;
    the fitted person is of human height and its hands are of human size (17-20 cm wrist to fingertip)."""
    from anima.facemodel.character import tracked_measures

    for name, seq in captures.items():
        m, rest = tracked_measures(seq.body_joints), motions[name]["rest"]
        arm = np.linalg.norm(rest[rig.IX["LeftForeArm"]] - rest[rig.IX["LeftArm"]]) + np.linalg.norm(
            rest[rig.IX["LeftHand"]] - rest[rig.IX["LeftForeArm"]]
        )
        assert abs(arm / (m["upper_arm"] + m["forearm"]) - 1) < 0.10, name
        assert 1.5 <= motions[name]["report"]["height_m"] <= 1.95, name
        hand = np.linalg.norm(rest[rig.IX["LeftHandMiddle4"]] - rest[rig.IX["LeftHand"]])
        assert 0.17 <= hand <= 0.21, (name, hand)


def test_a_joint_that_returns_blends_in_instead_of_snapping(captures):
    """An arm lost for 2 s comes back over at least 0.3 s: its bones hold, then turn into the tracked pose a
    little each frame, and no joint moves 20 cm in a frame."""
    from anima.core.contract import JOINT_NAMES
    from anima.export.avatar import character_motion

    seq = captures["oliver1"]
    J = seq.body_joints.copy()
    lost = [i for i, n in enumerate(JOINT_NAMES) if n.startswith(("left_elbow", "left_wrist", "left_hand"))]
    gap = slice(20, 70)
    J[gap, lost] = np.nan
    m = character_motion(dataclasses.replace(seq, body_joints=J))
    P = m["positions"]
    assert np.linalg.norm(np.diff(P, axis=0), axis=-1).max() < 0.20
    fore = m["local"][:, rig.IX["LeftForeArm"]]
    assert np.allclose(fore[gap], fore[gap.start])  # held while lost
    n = int(np.ceil(rig.BLEND_S * seq.fps))
    step = np.swapaxes(fore[gap.stop - 1 : gap.stop + n], -1, -2) @ fore[gap.stop : gap.stop + n + 1]
    d = np.degrees(np.linalg.norm(matrix_to_rotvec(step), axis=-1))
    assert (d > 0).sum() >= n - 1  # turning over the blend's frames, not in one
    said = [r for r in m["report"]["lost"] if r["part"] == "left hand"]  # and info.json says so, with its frames
    assert said and said[0]["frames"][0] <= gap.start and said[0]["frames"][1] >= gap.stop - 1, m["report"]["lost"]


def test_a_clip_that_never_shows_the_hips_still_gets_a_whole_body(captures, tmp_path):
    from anima.export.formats import export_bvh
    from anima.io.bvh import read_bvh

    J = captures["oliver1"].body_joints.copy()
    J[:, 1:3] = np.nan  # the hips are never seen
    seq = dataclasses.replace(captures["oliver1"], body_joints=J)
    b = read_bvh(export_bvh(seq, tmp_path / "x.bvh"))
    assert np.isfinite(b.positions()).all() and b.names == list(rig.NAMES)
    b = read_bvh(export_bvh(seq, tmp_path / "m.bvh", preset="mixamo"))
    assert b.names[0] == "mixamorig:Hips" and len(b.names) == rig.N_RIG


def test_the_cli_presets_are_the_rigs():
    from anima.cli.common import RIG_PRESETS

    assert set(RIG_PRESETS) == set(rig.PRESETS)
    assert sorted(rig.NAME_SEARCH) == sorted(rig.PRESETS)  # a user's skeleton is matched against every one


def test_a_missing_or_damaged_character_is_one_line_with_the_install_step(monkeypatch, tmp_path):
    import anima.facemodel.character as character
    from anima.errors import AssetNotFound

    for content in (None, b"not an npz"):
        p = tmp_path / "character.npz"
        if content is not None:
            p.write_bytes(content)
        monkeypatch.setattr(character, "package_data", lambda name, p=p: p)
        character.load_character.cache_clear()
        with pytest.raises(AssetNotFound, match="reinstall anima"):
            character.load_character()
    monkeypatch.undo()
    character.load_character.cache_clear()
    assert character.load_character().n_body == 13718 and len(character.load_character().vertices) == 13984


@pytest.fixture(scope="module")
def standing_clip():
    """A real clip whose legs are in the picture (LivePortrait's s13: a woman standing, knees to feet)."""
    from anima.capture.config import CaptureConfig
    from anima.capture.pipeline import capture_video

    src = "liveportrait-examples/assets/examples/source/s13.mp4"
    return capture_video(str(asset(src)), CaptureConfig(max_frames=60), progress=False)


def test_legs_in_the_picture_are_followed_and_blend_with_standing_where_lost(standing_clip):
    from anima.core.contract import JOINT_NAMES, LEG_JOINTS
    from anima.export.avatar import character_motion

    seq = standing_clip
    assert seq.leg_joints.shape == (seq.n_frames, len(LEG_JOINTS), 3)
    seen = np.isfinite(seq.leg_joints).all((-1, -2))
    assert seen.mean() > 0.9
    hip_y = seq.body_joints[:, JOINT_NAMES.index("left_hip"), 1]
    knee_y, ankle_y = seq.leg_joints[:, LEG_JOINTS.index("left_knee"), 1], seq.leg_joints[:, 1, 1]
    assert (ankle_y[seen] < knee_y[seen]).all() and (knee_y[seen] < hip_y[seen]).all()
    m = character_motion(seq)
    assert m["report"]["legs"] == "tracked"
    P = m["positions"]
    assert np.linalg.norm(np.diff(P, axis=0), axis=-1).max() < 0.20
    # the character's thighs and shins point where the person's do (the rig's world is the body's frame)
    for S, s in (("Left", "left"), ("Right", "right")):
        thigh = P[:, rig.IX[f"{S}Leg"]] - P[:, rig.IX[f"{S}UpLeg"]]
        shin = P[:, rig.IX[f"{S}Foot"]] - P[:, rig.IX[f"{S}Leg"]]
        hip = seq.body_joints[:, JOINT_NAMES.index(f"{s}_hip")]
        knee, ankle = (
            seq.leg_joints[:, LEG_JOINTS.index(f"{s}_knee")],
            seq.leg_joints[:, LEG_JOINTS.index(f"{s}_ankle")],
        )
        assert np.median(_angle(thigh[seen], (knee - hip)[seen])) < 10
        assert np.median(_angle(shin[seen], (ankle - knee)[seen])) < 10
    # the legs lost for a second: they hold their last tracked pose (a seated person stays seated), then blend
    # into the tracked pose over BLEND_S when seen again, no snap
    legs = seq.leg_joints.copy()
    gap = slice(15, 40)
    legs[gap] = np.nan
    m2 = character_motion(dataclasses.replace(seq, leg_joints=legs))
    assert m2["report"]["legs"] == "tracked"
    P2 = m2["positions"]
    assert np.linalg.norm(np.diff(P2, axis=0), axis=-1).max() < 0.20
    up = m2["local"][:, rig.IX["LeftUpLeg"]]
    step = np.swapaxes(up[gap.stop - 1 : -1], -1, -2) @ up[gap.stop :]
    n = int(np.ceil(rig.BLEND_S * seq.fps))
    assert (np.degrees(np.linalg.norm(matrix_to_rotvec(step[:n]), axis=-1)) > 0.05).sum() >= n - 1


def test_a_hand_flipped_for_a_few_frames_is_a_tracker_flip_not_a_motion():
    from anima.core.rotations import rotvec_to_matrix

    fps = 25.0
    t = np.arange(50)
    steady = rotvec_to_matrix(np.stack([np.radians(40.0) * t, 0 * t, 0 * t], -1))  # 40 deg a frame: a motion
    assert not rig._flipped_runs(steady, fps).any()
    flip = rotvec_to_matrix(np.tile([0.1, 0.2, 0.0], (50, 1)))
    flip[20:23] = rotvec_to_matrix(np.array([np.radians(160.0), 0, 0])) @ flip[20:23]
    out = rig._flipped_runs(flip, fps)
    assert out[20:23].all() and out.sum() == 3
    stays = flip.copy()
    stays[20:] = stays[20]  # flipped and never back: kept, but reached by a hold and a blend, not a snap
    out = rig._flipped_runs(stays, fps)
    assert out[20:32].all() and out.sum() == round(rig.FLIP_RUN_S * fps)
    filled, _ = rig.hold_and_blend(np.where(out[:, None, None], np.nan, stays)[:, None], fps)
    steps = np.degrees(
        np.linalg.norm(matrix_to_rotvec(np.einsum("fji,fjk->fik", filled[:-1, 0], filled[1:, 0])), axis=-1)
    )
    assert steps.max() < 25.0 and np.allclose(filled[-1, 0], stays[-1])
