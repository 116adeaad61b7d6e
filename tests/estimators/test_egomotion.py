"""Ego-motion: TUM parsing, interpolation and bad input."""

import numpy as np
import pytest

from estimators.egomotion import ConstantVelocity, TumTrajectory
from estimators.errors import InputError
from estimators.se3 import rot_to_quat, rot_z


def test_constant_velocity_moves_along_body_x():
    ego = ConstantVelocity(speed_mps=15.0)
    np.testing.assert_allclose(ego.pose_at(0.1).t, [1.5, 0, 0])  # thesis: 0.1 s at 15 m/s = 1.5 m
    np.testing.assert_allclose(ego.velocity_at(3.0), [15.0, 0, 0])


def test_tum_interpolation_linear_and_slerp(tmp_path):
    q0 = rot_to_quat(np.eye(3))
    q1 = rot_to_quat(rot_z(np.pi / 2))
    p = tmp_path / "traj.tum"
    p.write_text(
        "# t tx ty tz qx qy qz qw\n"
        f"0.0 0 0 0 {q0[0]} {q0[1]} {q0[2]} {q0[3]}\n"
        f"2.0 4 2 0 {q1[0]} {q1[1]} {q1[2]} {q1[3]}\n"
    )
    traj = TumTrajectory.load(p)
    T = traj.pose_at(0.5)
    np.testing.assert_allclose(T.t, [1.0, 0.5, 0.0])
    np.testing.assert_allclose(T.R, rot_z(np.pi / 8), atol=1e-12)
    np.testing.assert_allclose(traj.velocity_at(1.0), [2.0, 1.0, 0.0])


def test_tum_save_load_round_trip(tmp_path):
    t = np.array([0.0, 0.1, 0.2])
    traj = TumTrajectory(t, np.arange(9.0).reshape(3, 3), np.tile([0, 0, 0, 1.0], (3, 1)))
    traj.save(tmp_path / "a.tum")
    back = TumTrajectory.load(tmp_path / "a.tum")
    np.testing.assert_allclose(back.p_W, traj.p_W)
    np.testing.assert_allclose(back.t_s, t)


@pytest.mark.parametrize(
    "text, match",
    [
        ("0 0 0 0 0 0 0 1\n0 1 0 0 0 0 0 1\n", r":2: timestamps must increase strictly"),
        ("0 0 0 0 0 0 0 1\n1 1 0 0 0 0 1\n", r":2: expected 8 numbers"),
        ("0 0 0 0 0 0 0 1\n1 nan 0 0 0 0 0 1\n", r":2: NaN"),
        ("0 0 0 0 0 0 0 1\n1 x 0 0 0 0 0 1\n", r":2: not a number"),
        ("0 0 0 0 0 0 0 1\n", r"at least 2 poses"),
        ("# t tx ty tz qx qy qz qw\n0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 0\n", r"bad.tum:3: has a zero quaternion"),
        ("0 0 0 0 0 0 0 1\n1 1 0 0 1e308 1e308 1e308 1e308\n", r":2: has a quaternion too large"),
    ],
)
def test_tum_bad_lines_name_the_line(tmp_path, text, match):
    p = tmp_path / "bad.tum"
    p.write_text(text)
    with pytest.raises(InputError, match=match):
        TumTrajectory.load(p)


def test_time_outside_span_is_an_error_not_extrapolation():
    traj = TumTrajectory([0.0, 1.0], np.zeros((2, 3)), np.tile([0, 0, 0, 1.0], (2, 1)), source="t.tum")
    with pytest.raises(InputError, match=r"t.tum: time 1.500000 s is outside"):
        traj.pose_at(1.5)
    assert traj.covers(1.0) and not traj.covers(-0.1)


def test_missing_file():
    with pytest.raises(InputError, match="not found"):
        TumTrajectory.load("/nonexistent/traj.tum")


def test_huge_quaternion_is_normalised_without_overflow():
    # components whose squares overflow a float: the norm is still finite (2e200), the rotation the identity's
    q = np.array([[0, 0, 0, 1.0], [0, 0, 0, 1e200]])
    with np.errstate(all="raise"):
        traj = TumTrajectory([0.0, 1.0], np.zeros((2, 3)), q, source="t.tum")
    np.testing.assert_allclose(traj.pose_at(1.0).R, np.eye(3), atol=1e-15)


def test_zero_quaternion_in_arrays_names_the_pose():
    q = np.array([[0, 0, 0, 1.0], [0, 0, 0, 0.0]])
    with pytest.raises(InputError, match=r"t.tum: pose 1 has a zero quaternion \(norm 0;"):
        TumTrajectory([0.0, 1.0], np.zeros((2, 3)), q, source="t.tum")
