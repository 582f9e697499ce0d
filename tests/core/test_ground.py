"""The character in the world: a floor, feet that plant, a spine that leans only as far as the
evidence goes, hands put on the body where the picture shows them there, steps any body makes. The maths on
constructed cases; the behaviour on real clips of the shared data, measured with checks of their own (contacts
from the source picture, distances to the skinned mesh), not with the code that chose the output."""

import numpy as np
import pytest

from anima.core import ground, rig, world
from anima.core.rotations import matrix_to_rotvec, rotvec_to_matrix
from anima.io.assets import asset

S13 = "liveportrait-examples/assets/examples/source/s13.mp4"  # a woman standing, full body, 25 fps
S20 = "liveportrait-examples/assets/examples/source/s20.mp4"  # half body, hands held at the chest


def test_no_step_beyond_the_limit_and_small_steps_untouched():
    rng = np.random.default_rng(1)
    rv = np.cumsum(rng.normal(0, 0.05, (60, 4, 3)), 0)
    rv[30] += [2.5, 0, 0]  # one joint snaps 143 degrees and back
    L = rotvec_to_matrix(rv)
    out, cut = world.limit_steps(L, 40.0)
    step = np.degrees(np.linalg.norm(matrix_to_rotvec(np.einsum("fjba,fjbc->fjac", out[:-1], out[1:])), axis=-1))
    assert step.max() <= 40.0 + 1e-6 and cut >= 2
    np.testing.assert_allclose(out[:29], L[:29], atol=1e-12)


def test_the_spine_leans_only_as_far_as_the_evidence():
    fps = 25.0
    for deg, hips, lo, hi in ((15, True, 0, 5), (-15, True, -5, 0), (40, True, 20, 30), (20, False, 0, 0)):
        a = np.radians(deg)
        up = np.tile([0.0, np.cos(a), np.sin(a)], (40, 1)) * 0.5
        out = rig.upright(up, np.full(40, hips), fps)
        got = np.degrees(np.arctan2(out[20, 2], out[20, 1]))
        assert lo - 1e-6 <= got <= hi + 1e-6, (deg, hips, got)
        np.testing.assert_allclose(np.linalg.norm(out, axis=-1), 0.5)


def test_the_floor_is_the_ground_plane_under_a_person_who_walks_away():
    """A level pinhole camera 1.3 m above the floor, a person walking from 3 to 6 m away, one foot down at a
    time (the lower foot on the floor, the other lifted up to 15 cm): the floor's row follows the plane (the
    camera's height recovered within 5 %, the stance foot within 1 cm of it); a floor from the nearby frames'
    lowest foot alone was 5-15 cm off at these distances."""
    fps, F, f, h = 25.0, 150, 700.0, 1.3
    d = np.linspace(3.0, 6.0, F)
    mpp = d / f
    rng = np.random.default_rng(0)
    lift = np.abs(np.sin(np.arange(F) * np.pi / 25)) * 0.15
    swing = np.where((np.arange(F) // 25) % 2 == 0, 0, 1)
    heights = np.zeros((F, 2))
    heights[np.arange(F), swing] = lift
    rows_true = 360 + h / mpp  # the floor's row under the person
    rows = rows_true[:, None] - heights / mpp[:, None] + rng.normal(0, 0.5, (F, 2))
    low = rows.max(1)
    floor, cam = ground.floor_rows(low, mpp, fps)
    assert cam is not None and abs(cam - h) < 0.05 * h, cam
    stance = (floor - low) * mpp  # half a pixel of noise is 2-4 mm here
    assert np.median(np.abs(stance)) < 0.01 and np.abs(stance).max() < 0.03, np.abs(stance).max()
    floor_still, none = ground.floor_rows(low, np.full(F, mpp.mean()), fps)  # no change of distance: no plane
    assert none is None


def test_a_panning_camera_does_not_move_a_person_who_stands():
    """A person standing 4 m away, the camera turning 20 degrees: their picture slides by the turn; the
    bearing model leaves them in place (within 2 cm), sideways and in depth."""
    F, W = 100, 720
    f = ground.FOCAL * W
    turn = np.radians(np.linspace(0, 20, F))
    alpha = np.radians(5) - turn  # their angle off the camera's axis as it turns towards them and past
    u = W / 2 + f * np.tan(alpha)
    body = np.full((F, 55, 2), 300.0)
    body3d = np.zeros((F, 55, 3))
    for k, n in enumerate(("left_shoulder", "right_shoulder")):
        j = ground._J[n]
        body[:, j, 0] = u + (k - 0.5) * 40
    pic = ground.Picture(W, W, body, body3d, camera=np.stack([-f * turn, np.zeros(F)], 1))
    x, z = ground.picture_travel(pic, 4.0 * np.cos(alpha) / f, 25.0)  # their depth along the camera's axis
    assert np.abs(x).max() < 0.02 and np.abs(z).max() < 0.02, (np.abs(x).max(), np.abs(z).max())


def test_locks_blend_in_and_out():
    c = np.zeros(40, bool)
    c[10:25] = True
    w = ground.lock_weights(c, 25.0)
    assert w[:6].max() == 0 and w[10:25].min() == 1 and 0 < w[9] < 1 and 0 < w[25] < 1 and w[30:].max() == 0
    ankle = np.cumsum(np.ones((40, 3)) * 0.01, 0)
    a = ground.anchors(ankle, c, 25.0)
    np.testing.assert_allclose(a[12], ankle[10:13].mean(0))


@pytest.fixture(scope="module")
def s13():
    from anima.capture.config import CaptureConfig
    from anima.capture.pipeline import capture_video
    from anima.export.avatar import character_motion

    seq = capture_video(str(asset(S13)), CaptureConfig(), progress=False)
    return seq, character_motion(seq)


def _sole(P, rest):
    return np.min([P[:, rig.IX[n], 1] - rest[rig.IX[n], 1] for S in ("Left", "Right")
                   for n in (f"{S}Foot", f"{S}ToeBase", f"{S}Toe_End")], 0)  # fmt: skip


def test_a_standing_woman_stands_on_the_floor_upright_with_planted_feet(s13):
    """s13: full body, standing and posing. Planted frames are read off the source picture (a foot's points
    still in the picture for three frames, at the lowest rows), not from the method's own contacts."""
    seq, m = s13
    P, rest = m["positions"], m["rest"]
    assert _sole(P, rest).min() > -0.01  # never more than 1 cm under the floor
    rows = ground.foot_rows(ground.Picture(seq.width, seq.height, seq.body_image, seq.body_joints, seq.leg_image,
                                           seq.leg_joints, seq.leg_conf))  # fmt: skip
    slides = []
    for k, (side, pts) in enumerate((("Left", (1, 2, 3)), ("Right", (5, 6, 7)))):
        px = np.nanmean(seq.leg_image[:, list(pts)], 1)
        still = np.linalg.norm(np.diff(px, axis=0), axis=-1) < 0.004 * seq.height
        low = rows[1:, k] > np.nanpercentile(rows[:, k], 60)
        planted = still & low & np.roll(still, 1) & np.roll(still, -1)
        a = P[:, rig.IX[f"{side}Foot"], ::2]
        slides.append(np.linalg.norm(np.diff(a, axis=0), axis=-1)[planted])
        # planted feet stand flat, on the floor: the ankle over the ball of the foot as on the character's own
        # flat foot (tip-toe read 8.4-10.1 cm on unseen clips), the sole at most 2 cm above the floor
        f = np.flatnonzero(planted) + 1
        over = P[f, rig.IX[f"{side}Foot"], 1] - P[f, rig.IX[f"{side}ToeBase"], 1]
        flat = rest[rig.IX[f"{side}Foot"], 1] - rest[rig.IX[f"{side}ToeBase"], 1]
        assert np.max(over) < min(0.05, flat + 0.01), (side, np.max(over), flat)
        own = np.min(
            [P[f, rig.IX[f"{side}{n}"], 1] - rest[rig.IX[f"{side}{n}"], 1] for n in ("Foot", "ToeBase", "Toe_End")], 0
        )
        assert np.median(own) < 0.02, (side, np.median(own))
    slide = np.concatenate(slides)
    assert len(slide) >= 20 and np.median(slide) < 0.004, (len(slide), np.median(slide))  # <= 4 mm a frame
    up = np.einsum("fij,j->fi", m["global"][:, rig.IX["Spine2"]], [0.0, 1.0, 0.0])
    pitch = np.degrees(np.arctan2(up[:, 2], up[:, 1]))
    assert np.abs(pitch[[0, 25, 50]]).max() < 5.0, pitch[[0, 25, 50]]  # upright (it read 14-16 and -13.5)
    g = m["report"]["ground"]
    assert g["floor"].startswith("the feet's lowest plants") and min(g["contact_fraction"]) > 0.5


def test_a_hand_on_the_chest_is_put_on_it_and_a_gesturing_hand_is_not(s13, captures):
    """s13 sweeps her left hand onto her chest (frames 27-33): it is placed on the character's torso (its palm
    within 6 cm of the skinned mesh, measured on the mesh), moved only in depth (its picture position kept).
    John Oliver's hands gesture in front of his chest (PATS oliver1): never put on it."""
    from anima.export.avatar import body_of, character_motion, head_rotations, legs_of, picture_of
    from anima.facemodel.character import load_character, skin

    seq, m = s13
    hc = m["hand_contact"]
    assert 4 <= hc[:, 0].sum() <= 15 and not hc[:, 1].any(), hc.sum(0)
    ch = load_character()
    main = ch.skin_joints[np.arange(len(m["vertices"])), np.argmax(ch.skin_weights, 1)]
    torso = np.isin(main, [rig.IX[n] for n in ("Hips", "Spine", "Spine1", "Spine2")])
    frames = np.flatnonzero(hc[:, 0])
    dist = []
    for f in frames:
        V = skin(m["vertices"], m["rest"], m["global"][f : f + 1], m["positions"][f : f + 1], ch)[0]
        P = m["positions"][f]
        palm = 0.5 * P[rig.IX["LeftHand"]] + 0.5 * P[[rig.IX[f"LeftHand{x}1"] for x in ("Index", "Middle")]].mean(0)
        dist.append(np.linalg.norm(V[torso] - palm, axis=-1).min())
    assert np.max(dist) < 0.06, dist
    # only the depth moved: without the torso surface, the same hand is where the picture has it
    free = world.solve(body_of(seq), m["rest"], seq.fps, head_rotations(seq), picture_of(seq), legs_of(seq),
                       frames=seq.n_frames)  # fmt: skip
    d = m["positions"][frames, rig.IX["LeftHand"]] - free["positions"][frames, rig.IX["LeftHand"]]
    assert np.abs(d[:, :2]).max() < 0.02 and np.abs(d[:, 2]).max() > 0.05
    assert not character_motion(captures["oliver1"])["hand_contact"].any()


def test_an_arm_the_clip_never_shows_hangs_at_ease():
    """CREMA-D's actor 1001 (a head-and-shoulders take): his left arm never enters the picture, so the rig's rest
    would hold it out in a T at shoulder height; it hangs at ease instead, the hand well below the shoulder and
    beside the hip on every frame, and the report still names the joints the clip never showed."""
    from anima.capture.config import CaptureConfig
    from anima.capture.pipeline import capture_video
    from anima.export.avatar import character_motion

    seq = capture_video(str(asset("emotion-clips/crema-d/1001_DFA_ANG_XX.flv")), CaptureConfig(), progress=False)
    m = character_motion(seq)
    never = m["report"]["joints_never_seen"]
    assert "LeftArm" in never and "LeftHand" in never, never
    P = m["positions"]
    drop = P[:, rig.IX["LeftArm"], 1] - P[:, rig.IX["LeftHand"], 1]
    assert drop.min() > 0.35, drop.min()  # a T-posed hand: at the shoulder's height (0)
    out = np.abs(P[:, rig.IX["LeftHand"], 0] - P[:, rig.HIPS, 0])
    assert out.max() < 0.35, out.max()  # beside the hip, not held out sideways


def test_the_head_eases_back_when_the_face_returns_and_bridges_a_short_loss():
    """The face fit's head rotation is lost for 1.2 s (a fast turn) and comes back 77 degrees away from the body's
    own head line: the head eases between the two over FACE_BLEND_S, never a snap (before: 77 degrees in one
    frame); a face lost for two frames is bridged along the shortest arc, the head never leaves its turn."""
    from anima.core.rotations import rotvec_to_matrix
    from anima.facemodel.character import load_character

    fps, F = 25.0, 100
    _, rest = load_character().shaped(np.zeros(load_character().n_components))
    body = rig.idle_body(F, rest, fps)
    face = np.repeat(rotvec_to_matrix(np.array([[0.0, np.radians(77.0), 0.0]])), F, 0)
    lost = face.copy()
    lost[10:40] = np.nan
    turns = []
    for head_rot in (lost,):
        G = rig.solve(body, rest, fps, head_rot)["global"][:, rig.IX["Head"]]
        fwd = G @ np.array([0.0, 0.0, 1.0])
        turns = np.degrees(np.arccos(np.clip((fwd[1:] * fwd[:-1]).sum(-1), -1, 1)))
    assert turns.max() < 20.0, turns.max()  # 77 degrees spread over the blend's 7-8 frames
    blink = face.copy()
    blink[50:52] = np.nan
    G = rig.solve(body, rest, fps, blink)["global"][:, rig.IX["Head"]]
    yaw = np.degrees(np.arctan2((G @ [0.0, 0.0, 1.0])[:, 0], (G @ [0.0, 0.0, 1.0])[:, 2]))
    assert np.abs(yaw[45:60] - yaw[44]).max() < 3.0, yaw[45:60]


def test_a_speaker_seen_from_the_waist_up_sits(captures):
    """PATS oliver1: John Oliver at his desk, his hips at the picture's bottom edge, no leg in the picture. With
    --posture auto (the default) he sits: the thighs level, the shins down, the feet on the floor, and the
    report says so and why; --posture standing stands him up."""
    import dataclasses

    from anima.export.avatar import character_motion

    seq = captures["oliver1"]
    m = character_motion(seq)
    P = m["positions"]
    assert m["report"]["posture"].startswith("seated (auto:"), m["report"]["posture"]
    for S in ("Left", "Right"):
        thigh = P[:, rig.IX[f"{S}Leg"]] - P[:, rig.IX[f"{S}UpLeg"]]
        shin = P[:, rig.IX[f"{S}Foot"]] - P[:, rig.IX[f"{S}Leg"]]
        pitch = np.degrees(np.arctan2(-thigh[:, 1], np.hypot(thigh[:, 0], thigh[:, 2])))
        assert np.abs(pitch).max() < 10.0, pitch
        assert (np.degrees(np.arccos(-shin[:, 1] / np.linalg.norm(shin, axis=-1))) < 15.0).all()
    assert np.abs(_sole(P, m["rest"])).max() < 0.01
    standing = dataclasses.replace(seq, meta={**seq.meta, "posture": "standing"})
    m2 = character_motion(standing)
    assert m2["report"]["posture"] == "standing (--posture standing)"
    assert m2["root"][:, 1].mean() > m["root"][:, 1].mean() + 0.3  # the hips stand


def test_a_chest_up_framing_stands_and_a_waist_up_host_sits():
    """--posture auto seats the character only where the picture shows a seat. CREMA-D's actor 1001, a standing
    man framed from the chest up: the picture never shows his hips (MediaPipe places them half a picture under
    its bottom edge, a guess), so nothing shows a seat and he stands, the report saying why. John Oliver at his
    desk (PATS oliver1): his hips are seen at the picture's bottom edge, no leg under them, and he sits."""
    from anima.capture.config import CaptureConfig
    from anima.capture.pipeline import capture_video
    from anima.export.avatar import character_motion, legs_of, posture_of

    seq = capture_video(str(asset("emotion-clips/crema-d/1001_DFA_NEU_XX.flv")), CaptureConfig(), progress=False)
    m = character_motion(seq)
    assert m["report"]["posture"].startswith("standing (auto: the hips never seen"), m["report"]["posture"]
    assert not m["report"]["legs"].startswith("seated"), m["report"]["legs"]
    hips = m["rest"][rig.HIPS, 1]  # the character's hips standing at rest
    assert np.abs(m["root"][:, 1] - hips).max() < 0.1 * hips  # the hips stand (seated they sit ~40 % lower)
    host = capture_video(str(asset("gesture-video/pats-crops/oliver1_gt.mp4")), CaptureConfig(max_frames=60),
                         progress=False)  # fmt: skip
    posture, why = posture_of(host, legs_of(host))
    assert posture == "seated" and "bottom edge" in why, why


def test_auto_posture_reads_the_hips_the_picture_shows():
    """The rule on constructed pictures (640 x 480): hips seen at the bottom edge with no leg sit; hips seen
    higher up stand; hips the picture never shows (only MediaPipe's guess, under the picture) stand, as they do
    when seen in too few frames; legs seen (both thighs) are followed; --posture overrides; no picture, no
    posture."""
    import dataclasses

    from anima.capture.pipeline import empty_face_sequence
    from anima.core.contract import JOINT_NAMES
    from anima.export.avatar import HIPS_SEEN, posture_of

    F, hips = 40, [JOINT_NAMES.index("left_hip"), JOINT_NAMES.index("right_hip")]
    base = empty_face_sequence(F, 640, 480, 25.0, {})

    def picture(row, seen_frames=F, **meta):
        image = np.full((F, len(JOINT_NAMES), 2), 200.0)
        image[:, hips, 1] = row * 480
        conf = np.ones((F, len(JOINT_NAMES)))
        conf[seen_frames:, hips] = 0.0
        joints = np.zeros((F, len(JOINT_NAMES), 3))
        return dataclasses.replace(base, body_image=image, body_conf=conf, body_joints=joints, meta=meta)

    assert posture_of(picture(0.97), None)[0] == "seated"
    assert posture_of(picture(1.04), None)[0] == "seated"  # the hip joint a little under the cut
    assert posture_of(picture(0.80), None)[0] == "standing"
    assert posture_of(picture(1.55, seen_frames=0), None) == (
        "standing",
        "auto: the hips never seen (the picture is cut above them): nothing shows a seat",
    )
    few = int(F * HIPS_SEEN) - 1
    assert posture_of(picture(0.97, seen_frames=few), None)[0] == "standing"
    legs = {f"{s}_{j}": np.zeros((F, 3)) for s in ("left", "right") for j in ("hip", "knee")}
    assert posture_of(picture(0.97), legs)[0] == "tracked"
    legs["right_knee"] = np.full((F, 3), np.nan)  # one knee is no pair of legs the rig can follow
    assert posture_of(picture(0.97), legs)[0] == "seated"
    assert posture_of(picture(1.55, seen_frames=0, posture="seated"), None) == ("seated", "--posture seated")
    assert posture_of(picture(0.97, posture="standing"), None) == ("standing", "--posture standing")
    assert posture_of(dataclasses.replace(base, body_image=None), None) is None
