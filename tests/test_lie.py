"""The SE(3) helpers at the UI edge (dualpuma.lie): quaternions against Pinocchio's own conversion
and a hand-built rotation, roll-pitch-yaw round trips, and typed errors for bad input."""

import math

import numpy as np
import pinocchio as pin
import pytest

from dualpuma.errors import PoseError
from dualpuma.lie import pose_from_wxyz, quaternion_wxyz, rot_to_rpy, rpy_to_rot


def test_quaternion_round_trip_against_pinocchio(rng):
    for _ in range(50):
        R = pin.Quaternion(*rng.normal(size=4)).normalized().toRotationMatrix()
        w, x, y, z = quaternion_wxyz(R)
        # independent: the rotation a unit quaternion (w, x, y, z) stands for, written out
        Rq = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                       [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                       [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
        np.testing.assert_allclose(Rq, R, atol=1e-12)
        T = pose_from_wxyz((2 * w, 2 * x, 2 * y, 2 * z), (0.1, -0.2, 0.3))  # normalised there
        np.testing.assert_allclose(T[:3, :3], R, atol=1e-12)
        np.testing.assert_array_equal(T[:3, 3], [0.1, -0.2, 0.3])


def test_rpy_round_trip(rng):
    rpy = rng.uniform([-math.pi, -1.5, -math.pi], [math.pi, 1.5, math.pi], (200, 3))
    np.testing.assert_allclose(rot_to_rpy(rpy_to_rot(rpy)), rpy, atol=1e-12)


def test_rpy_gives_back_its_rotation_at_gimbal_lock(rng):
    """At pitch +-90 deg only roll - yaw (or roll + yaw) is defined; whatever angles come out must
    rebuild the rotation, by Pinocchio's rpyToMatrix (Rz(yaw) Ry(pitch) Rx(roll)). The PUMA's hand
    at q = (10, 20, 30, 0, 40, 0) deg points straight down: its angles were 6.8 deg off."""
    pitches = np.concatenate([[math.pi / 2, -math.pi / 2] * 100, math.pi / 2 - 10.0 ** rng.uniform(-16, -3, 100),
                              rng.uniform(-math.pi / 2, math.pi / 2, 100)])
    for p in pitches:
        r, y = rng.uniform(-math.pi, math.pi, 2)
        R = pin.rpy.rpyToMatrix(r, p, y)
        np.testing.assert_allclose(pin.rpy.rpyToMatrix(*rot_to_rpy(R)), R, atol=1e-14)
    from urdf_reference import FullUrdf

    from dualpuma.kinematics import Arm

    arm = Arm.load("puma560")
    ref = FullUrdf(arm.urdf_path, [arm.model.names[j] for j in range(1, 7)], arm.hand_frame)
    for q_deg in ((10, 20, 30, 0, 40, 0), (10, 20, 30, 0, -140, 0)):
        R = ref.fk(np.radians(q_deg))[:3, :3]
        rpy = rot_to_rpy(R)
        assert abs(abs(rpy[1]) - math.pi / 2) < 1e-7  # at the lock
        np.testing.assert_allclose(pin.rpy.rpyToMatrix(*rpy), R, atol=1e-14)


@pytest.mark.parametrize(("fn", "args"), [
    (quaternion_wxyz, (np.full((3, 3), np.nan),)),
    (quaternion_wxyz, (2.0 * np.eye(3),)),
    (quaternion_wxyz, (np.tile(np.eye(3), (2, 1, 1)),)),
    (quaternion_wxyz, ("abc",)),
    (pose_from_wxyz, ((0.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0))),
    (pose_from_wxyz, ((1.0, 0.0, 0.0, math.nan), (0.0, 0.0, 0.0))),
    (pose_from_wxyz, ((1.0, 0.0, 0.0, 0.0), (0.0, math.inf, 0.0))),
    (pose_from_wxyz, ((1.0, 0.0, 0.0), (0.0, 0.0, 0.0))),
    (rot_to_rpy, (np.diag([1.0, 1.0, -1.0]),)),
    (rot_to_rpy, (np.eye(4),)),
])
def test_bad_input_is_a_pose_error(fn, args):
    with pytest.raises(PoseError):
        fn(*args)


def test_slerp_pairs_is_the_geodesic_of_each_pair(rng):
    """slerp_pairs (vectorised over pairs) gives, for each pair, the pose a fraction of the way:
    translation linear, rotation R_A exp(s log(R_A^T R_B)) by Pinocchio's exp3 / log3, including
    no rotation, tiny and near-pi rotations; s = 1 gives B exactly."""
    from dualpuma.lie import slerp_pairs

    angles = [0.0, 1e-10, 1e-4, 0.3, 2.0, 3.0, 3.1, math.pi - 1e-6]
    A, B, s = [], [], []
    for k, th in enumerate(angles * 3):
        a = np.eye(4)
        a[:3, :3] = pin.exp3(rng.normal(size=3))
        a[:3, 3] = rng.normal(size=3)
        axis = rng.normal(size=3)
        b = np.eye(4)
        b[:3, :3] = a[:3, :3] @ pin.exp3(th * axis / np.linalg.norm(axis))
        b[:3, 3] = rng.normal(size=3)
        A.append(a)
        B.append(b)
        s.append([0.0, 0.37, 1.0][k // len(angles)])
    A, B, s = np.array(A), np.array(B), np.array(s)
    out = slerp_pairs(A, B, s)
    for k in range(len(s)):
        R = A[k, :3, :3] @ pin.exp3(s[k] * pin.log3(A[k, :3, :3].T @ B[k, :3, :3]))
        np.testing.assert_allclose(out[k, :3, :3], R, atol=1e-12)
        np.testing.assert_allclose(out[k, :3, 3], A[k, :3, 3] + s[k] * (B[k, :3, 3] - A[k, :3, 3]), atol=1e-15)
    assert np.array_equal(out[s == 1.0], B[s == 1.0])


def test_angles_against_pinocchio_at_every_angle():
    from dualpuma.lie import angles

    rng = np.random.default_rng(4)
    th = np.concatenate([[0.0, 1e-9, 1e-4, math.pi - 1e-9, math.pi], rng.uniform(0, math.pi, 200)])
    Ra = np.array([pin.exp3(rng.normal(size=3)) for _ in th])
    axes = rng.normal(size=(th.size, 3))
    Rb = np.array([R @ pin.exp3(a / np.linalg.norm(a) * t) for R, a, t in zip(Ra, axes, th)])
    want = np.array([np.linalg.norm(pin.log3(a.T @ b)) for a, b in zip(Ra, Rb)])
    np.testing.assert_allclose(angles(Ra, Rb), want, atol=1e-7)
    np.testing.assert_allclose(angles(Ra, Rb), th, atol=1e-7)
