"""Poses and quaternions against hand-worked values."""

import numpy as np
import pytest

from estimators.errors import InputError
from estimators.se3 import Pose, quat_to_rot, rot_to_quat, rot_z, slerp


def test_quaternion_of_90deg_yaw_matches_hand_rotation():
    # q = [0, 0, sin(45deg), cos(45deg)] rotates x onto y.
    s = np.sqrt(0.5)
    R = quat_to_rot([0.0, 0.0, s, s])
    np.testing.assert_allclose(R @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(R, rot_z(np.pi / 2), atol=1e-12)


def test_quaternion_round_trip_random():
    rng = np.random.default_rng(0)
    for _ in range(200):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        q2 = rot_to_quat(quat_to_rot(q))
        assert min(np.abs(q - q2).max(), np.abs(q + q2).max()) < 1e-12


def test_pose_compose_and_inverse():
    T_A_B = Pose(rot_z(0.3), [1.0, 2.0, 3.0])
    T_B_C = Pose(rot_z(-1.1), [0.5, 0.0, -1.0])
    p_C = np.array([0.2, -0.4, 2.0])
    np.testing.assert_allclose((T_A_B @ T_B_C).apply(p_C), T_A_B.apply(T_B_C.apply(p_C)), atol=1e-12)
    np.testing.assert_allclose(T_A_B.inverse().apply(T_A_B.apply(p_C)), p_C, atol=1e-12)
    np.testing.assert_allclose(Pose.from_matrix(T_A_B.matrix()).t, T_A_B.t)


def test_slerp_halfway_is_half_angle():
    q0 = rot_to_quat(np.eye(3))
    q1 = rot_to_quat(rot_z(1.0))
    np.testing.assert_allclose(quat_to_rot(slerp(q0, q1, 0.5)), rot_z(0.5), atol=1e-12)


@pytest.mark.parametrize(
    "R, t, match",
    [
        (np.eye(3) * 2, np.zeros(3), "not a rotation"),
        (np.diag([1.0, 1.0, -1.0]), np.zeros(3), "not a rotation"),
        (np.eye(3), [np.nan, 0, 0], "finite"),
        (np.eye(2), np.zeros(3), r"expected R \(3, 3\)"),
    ],
)
def test_pose_rejects_bad_input(R, t, match):
    with pytest.raises(InputError, match=match):
        Pose(R, t)


def test_zero_quaternion_rejected():
    with pytest.raises(InputError, match="non-zero"):
        quat_to_rot([0, 0, 0, 0])
