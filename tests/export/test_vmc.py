"""The VMC protocol: anima's OSC packets read by an independent parser (python-osc), `anima vmc`
playing a real capture at its frame rate into a receiver that checks addresses, types, Unity's bone names and
unit quaternions, and the round trip: the received bones pose anima's character to within 1 degree of the sent
ones."""

import numpy as np
import pytest
from vmc_receiver import VmcReceiver, _messages

from anima.core import rig
from anima.core.rotations import matrix_to_quat, quat_to_matrix
from anima.export.avatar import character_motion
from anima.export.vmc import BLEND_NAMES, UNITY_BONES, frame_bundle, to_unity_position, to_unity_rotation
from anima.io.osc import bundle, message, parse
from anima.io.sequence import write_sequence


def test_osc_packets_are_read_by_another_parser():
    b = bundle([message("/VMC/Ext/Bone/Pos", "Hips", 0.1, 1.0, -0.2, 0.0, 0.0, 0.0, 1.0), message("/VMC/Ext/OK", 1),
                message("/VMC/Ext/Blend/Apply")])  # fmt: skip
    got = _messages(b)
    assert [g[0] for g in got] == ["/VMC/Ext/Bone/Pos", "/VMC/Ext/OK", "/VMC/Ext/Blend/Apply"]
    assert got[0][1] == "sfffffff" and got[0][2][0] == "Hips" and got[1][2] == [1]
    assert parse(b)[0] == ("/VMC/Ext/Bone/Pos", pytest.approx(["Hips", 0.1, 1.0, -0.2, 0.0, 0.0, 0.0, 1.0]))
    with pytest.raises(TypeError):
        message("/x", True)


def test_unity_axes_are_a_mirror_of_animas():
    """Positions (-x, y, z), rotations (x, -y, -z, w): the rotation S R S with S = diag(-1, 1, 1)."""
    rng = np.random.default_rng(0)
    q = rng.normal(size=(20, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    S = np.diag([-1.0, 1.0, 1.0])
    np.testing.assert_allclose(quat_to_matrix(to_unity_rotation(q)), S @ quat_to_matrix(q) @ S, atol=1e-12)
    np.testing.assert_allclose(to_unity_position([1.0, 2.0, 3.0]), [-1.0, 2.0, 3.0])
    assert len(UNITY_BONES) == 52 and len(BLEND_NAMES) == 64


def _anima_from_unity(frame: dict, rest: np.ndarray) -> np.ndarray:
    """Local rotations [65, 3, 3] from a received frame (bones not sent: identity)."""
    L = np.tile(np.eye(3), (rig.N_RIG, 1, 1))
    for j, name in UNITY_BONES.items():
        L[j] = quat_to_matrix(to_unity_rotation(frame["bones"][name][1]))
    return L


def test_vmc_plays_a_capture_and_the_bones_pose_the_character(captures, tmp_path, cli):
    seq = captures["oliver1"]
    path = write_sequence(seq, tmp_path / "capture.npz")
    with VmcReceiver() as rx:
        r = cli("vmc", tmp_path, "--to", f"127.0.0.1:{rx.port}", "--json")
    assert r.returncode == 0, r.stderr
    assert not rx.bad, rx.bad[:5]
    F = len(rx.frames)
    assert F == seq.n_frames
    t = np.array([f["t"] for f in rx.frames])
    assert (F - 1) / (t[-1] - t[0]) >= 20  # at the capture's own rate (25 fps)
    f0 = rx.frames[0]
    assert len(f0["bones"]) >= 50 and set(f0["blend"]) == set(BLEND_NAMES) and f0["applied"]
    assert f0["ok"][0] == 1 and f0["time"] is not None
    moved_bones, moved_blends = rx.moving()
    assert moved_bones >= 40 and moved_blends >= 40, (moved_bones, moved_blends)
    # the round trip: received bones -> anima's character, world rotations within 1 degree of what was sent
    m = character_motion(seq)
    for k in (0, F // 2, F - 1):
        L = _anima_from_unity(rx.frames[k], m["rest"])
        G, _ = rig.forward(L[None], m["rest"], m["root"][k : k + 1])
        G0, _ = rig.forward(m["local"][k : k + 1], m["rest"], m["root"][k : k + 1])
        mapped = sorted(UNITY_BONES)
        d = np.einsum("jab,jac->jbc", G[0, mapped], G0[0, mapped])
        ang = np.degrees(np.arccos(np.clip((np.trace(d, axis1=1, axis2=2) - 1) / 2, -1, 1)))
        assert ang.max() < 1.0, (k, ang.max())
    hips = rx.frames[F // 2]["bones"]["Hips"][0]
    np.testing.assert_allclose(to_unity_position(hips), m["root"][F // 2], atol=1e-4)
    for to, words in (("nohost", "HOST:PORT"), ("127.0.0.1:0", "HOST:PORT"), ("127.0.0.1:99999", "HOST:PORT")):
        r = cli("vmc", path, "--to", to)
        assert r.returncode == 2 and words in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_a_frame_bundle_is_one_udp_packet():
    rest = np.zeros((rig.N_RIG, 3))
    b = frame_bundle(np.tile(np.eye(3), (rig.N_RIG, 1, 1)), rest[0], rig.rest_offsets(rest), np.zeros(64), 0.0)
    assert len(b) < 65_000
    assert matrix_to_quat(np.eye(3)).tolist() == [0.0, 0.0, 0.0, 1.0]


def test_a_frame_bundle_is_the_bytes_message_by_message_gives(captures):
    """The pre-encoded frame (:class:`anima.io.osc.FloatMessages`) is byte for byte the bundle of one
    :func:`message` per bone and blend value, on a real capture's frame."""
    m = character_motion(captures["oliver1"])
    k = len(m["local"]) // 2
    local, hips, offsets = m["local"][k], m["root"][k], rig.rest_offsets(m["rest"])
    blends = np.random.default_rng(1).random(64)
    q = to_unity_rotation(matrix_to_quat(local))
    msgs = [message("/VMC/Ext/Root/Pos", "root", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)]
    for j, name in UNITY_BONES.items():
        p = to_unity_position(hips if j == rig.HIPS else offsets[j])
        msgs.append(message("/VMC/Ext/Bone/Pos", name, *map(float, p), *map(float, q[j])))
    msgs += [message("/VMC/Ext/Blend/Val", n, float(v)) for n, v in zip(BLEND_NAMES, blends)]
    msgs += [message("/VMC/Ext/Blend/Apply"), message("/VMC/Ext/OK", 1, 3, 0, 1), message("/VMC/Ext/T", 2.5)]
    assert frame_bundle(local, hips, offsets, blends, 2.5) == bundle(msgs)
