"""The one kinematics module: forward kinematics, rotations from positions, rotation fitting and two-bone IK, on
the character's rig and on constructed cases."""

import numpy as np

from anima.core import kinematics, rig
from anima.core.rotations import rotvec_to_matrix


def _pose(F=20, seed=0):
    rng = np.random.default_rng(seed)
    L = rotvec_to_matrix(rng.normal(scale=0.5, size=(F, rig.N_RIG, 3)))
    return L, rng


def test_forward_places_every_bone_at_its_rest_length_and_inverts_to_the_locals():
    from anima.facemodel.character import load_character

    rest = load_character().joints
    L, rng = _pose()
    root = rest[rig.HIPS] + rng.normal(scale=0.1, size=(len(L), 3))
    G, P = rig.forward(L, rest, root)
    G2, P2 = kinematics.forward(L, rig.PARENTS_RIG, rig.rest_offsets(rest), root)
    assert np.array_equal(G, G2) and np.array_equal(P, P2)  # the rig's is the one module's
    np.testing.assert_allclose(P[:, rig.HIPS], root)
    off = np.linalg.norm(rig.rest_offsets(rest)[1:], axis=-1)
    np.testing.assert_allclose(
        np.linalg.norm(P[:, 1:] - P[:, rig.PARENTS_RIG[1:]], axis=-1), np.broadcast_to(off, (20, 64))
    )
    np.testing.assert_allclose(kinematics.local_rotations(G, rig.PARENTS_RIG), L, atol=1e-12)
    # per-frame offsets (a BVH's position channels): the same positions when they do not change
    P3 = kinematics.forward(L, rig.PARENTS_RIG, np.broadcast_to(rig.rest_offsets(rest), (20, rig.N_RIG, 3)), root)[1]
    np.testing.assert_allclose(P3, P, atol=1e-12)


def test_rotations_from_positions_pose_the_rest_skeleton_like_them():
    from anima.facemodel.character import load_character

    rest = load_character().joints
    off = rig.rest_offsets(rest)
    L, _ = _pose(seed=1)
    L[:, rig.LEAVES] = np.eye(3)
    P = kinematics.forward_kinematics(L, rig.PARENTS_RIG, off)
    G = kinematics.positions_to_rotations(P, rig.PARENTS_RIG, off)
    again = kinematics.forward_kinematics(kinematics.local_rotations(G, rig.PARENTS_RIG), rig.PARENTS_RIG, off)
    np.testing.assert_allclose(again, P, atol=1e-9)


def test_kabsch_and_the_smallest_rotation_recover_a_turn():
    rng = np.random.default_rng(2)
    R = rotvec_to_matrix(rng.normal(size=(10, 3)))
    A = rng.normal(size=(10, 5, 3))
    np.testing.assert_allclose(kinematics.kabsch(A, A @ np.swapaxes(R, -1, -2)), R, atol=1e-9)
    a, b = kinematics.unit(rng.normal(size=(10, 3))), kinematics.unit(rng.normal(size=(10, 3)))
    a[0], b[0] = [1.0, 0, 0], [-1.0, 0, 0]  # opposite vectors
    M = kinematics.min_rotation(a, b)
    np.testing.assert_allclose(np.einsum("fij,fj->fi", M, a), b, atol=1e-9)
    np.testing.assert_allclose(M @ np.swapaxes(M, -1, -2), np.broadcast_to(np.eye(3), M.shape), atol=1e-9)
    seen = kinematics.fit_rotation(A[0], A @ np.swapaxes(R, -1, -2))
    assert np.isfinite(seen).all()
    A2 = A.copy()
    A2[3, 1] = np.nan
    assert np.isnan(kinematics.fit_rotation(A[0], A2)[3]).all()  # a target unseen: NaN, the others fitted


def test_two_bone_ik_reaches_and_keeps_the_knee_plane():
    rng = np.random.default_rng(0)
    hip = rng.normal(size=(50, 3))
    target = hip + rng.normal(size=(50, 3)) * 0.3
    pole = rng.normal(size=(50, 3))
    knee = kinematics.two_bone(hip, target, 0.45, 0.42, pole)
    np.testing.assert_allclose(np.linalg.norm(knee - hip, axis=-1), 0.45, atol=1e-9)
    reach = np.linalg.norm(target - hip, axis=-1) < 0.87
    np.testing.assert_allclose(np.linalg.norm(knee - target, axis=-1)[reach], 0.42, atol=1e-9)
    n = np.cross(target - hip, pole)
    assert np.abs(np.einsum("fi,fi->f", knee - hip, n))[reach].max() < 1e-9  # in the plane of hip, target, pole


def test_parents_come_first():
    parents = np.array([3, -1, 1, 1, 2, -1, 5])
    order = kinematics.parents_first(parents)
    assert sorted(order) == list(range(7))
    pos = {j: k for k, j in enumerate(order)}
    assert all(parents[j] < 0 or pos[parents[j]] < pos[j] for j in range(7))
