"""Object -> hands (eq. 5.6), dual IK with branch continuity, paths, interpolation."""

import math
import re

import numpy as np
import pinocchio as pin
import pytest
from seed_reference import seed_calcrot

from dualpuma import puma
from dualpuma.errors import ParameterError
from dualpuma.kinematics import hands_from_object, solve_dual, solve_path
from dualpuma.lie import n_steps, rot_to_rpy, rpy_to_rot
from dualpuma.planning import interpolate_object, robmov
from dualpuma.units import display_text


def moved(T, dp=(0, 0, 0), rpy=(0, 0, 0)):
    out = T.copy()
    out[:3, :3] = pin.rpy.rpyToMatrix(*rpy) @ T[:3, :3]
    out[:3, 3] += dp
    return out


def test_hands_from_object_at_start_are_the_start_joints(cell):
    TL, TR = hands_from_object(cell, cell.T_world_object_start)
    np.testing.assert_allclose(TL, puma.fk(cell.left.q_home), atol=1e-12)
    np.testing.assert_allclose(TR, puma.fk(cell.right.q_home), atol=1e-12)
    # batched form
    TLb, _ = hands_from_object(cell, np.stack([cell.T_world_object_start] * 3))
    assert TLb.shape == (3, 4, 4)


@pytest.mark.parametrize("method", ["slerp", "se3", "rpy", "puma"])
def test_closed_chain_along_path(world, cell, method):
    T0 = cell.T_world_object_start
    T1 = moved(T0, (-0.05, 0.02, 0.03), (0.05, -0.05, 0.15))
    path = interpolate_object(T0, T1, n_steps(float(np.linalg.norm(T1[:3, 3] - T0[:3, 3])), 0.0, 0.01, 1.0), method)
    sol = solve_path(world, path, (cell.left.q_home, cell.right.q_home))
    assert sol.n_ok == len(path), sol.reason
    for T, qL, qR in zip(path, sol.q_left, sol.q_right):
        HL, HR = world.hand_poses(qL, qR)
        np.testing.assert_allclose(HL, T @ cell.grasp_left.T_object_hand, atol=1e-9)
        np.testing.assert_allclose(HR, T @ cell.grasp_right.T_object_hand, atol=1e-9)
    # same branches all the way (never switched)
    assert set(puma.branch_of(sol.q_left)) == {int(puma.branch_of(cell.left.q_home))}
    assert set(puma.branch_of(sol.q_right)) == {int(puma.branch_of(cell.right.q_home))}


def test_solve_dual_matches_solve_path(world, cell):
    T0 = cell.T_world_object_start
    path = interpolate_object(T0, moved(T0, (0.05, 0, 0.05), (0, 0, 0.2)), 10)
    sol = solve_path(world, path, (cell.left.q_home, cell.right.q_home))
    q = (cell.left.q_home, cell.right.q_home)
    for i, T in enumerate(path):
        d = solve_dual(world, T, q)
        assert d.ok, d.reason
        np.testing.assert_allclose(d.q_left, sol.q_left[i], atol=1e-9)
        np.testing.assert_allclose(d.q_right, sol.q_right[i], atol=1e-9)
        assert d.clearance >= cell.safety_margin
        q = (d.q_left, d.q_right)


def test_unreachable_and_jump_are_reported(world, cell):
    q = (cell.left.q_home, cell.right.q_home)
    far = moved(cell.T_world_object_start, (0.0, 0.0, 2.0))
    d = solve_dual(world, far, q)
    assert not d.ok and d.status == ("unreachable", "unreachable") and d.q_left is None
    # a big rotation in one step needs a joint jump: reported, not hidden
    big = moved(cell.T_world_object_start, rpy=(0, 0, math.radians(20)))
    d = solve_dual(world, big, q, max_step=math.radians(5))
    assert not d.ok and ("jump" in d.status or "singular" in d.status)
    # SI in the API, degrees where a person reads it: the shown value is the written one converted
    moved_rad = float(re.search(r"would move (\d+\.\d{4}) rad in one step", d.reason).group(1))
    assert f"would move {math.degrees(moved_rad):.2f} deg in one step" in display_text(d.reason)
    sol = solve_path(world, np.stack([cell.T_world_object_start, big]), q, max_step=math.radians(5))
    assert sol.n_ok == 1 and sol.status[0] in ("jump", "singular") and "step 1" in sol.reason
    with pytest.raises(ParameterError):
        solve_dual(world, big, q, max_step=0.0)


def test_collision_is_reported(world, cell):
    q = (cell.left.q_home, cell.right.q_home)
    low = moved(cell.T_world_object_start, (0.0, 0.0, -0.1))  # bar pushed into the floor
    d = solve_dual(world, low, q, max_step=math.pi)
    assert not d.ok and "collision" in d.status and "floor" in d.reason and d.clearance < cell.safety_margin


def test_calc_rot_equals_seed_calcrot():
    rng = np.random.default_rng(4)
    for rpy in rng.uniform(-np.pi, np.pi, (200, 3)):
        np.testing.assert_allclose(rpy_to_rot(rpy), seed_calcrot(rpy), atol=1e-15)
        np.testing.assert_allclose(rpy_to_rot(rpy), pin.rpy.rpyToMatrix(*rpy), atol=1e-14)
        np.testing.assert_allclose(rpy_to_rot(rot_to_rpy(rpy_to_rot(rpy))), rpy_to_rot(rpy), atol=1e-12)


@pytest.mark.parametrize("method", ["slerp", "se3", "rpy", "puma"])
def test_interpolation_endpoints_exact(method):
    rng = np.random.default_rng(8)
    A = moved(np.eye(4), (0.1, 0.2, 0.3), (0.2, -0.4, 1.0))
    B = moved(np.eye(4), (-0.2, 0.5, 0.1), (-0.3, 0.5, -2.0))
    P = interpolate_object(A, B, 7, method)
    assert P.shape == (7, 4, 4) and np.array_equal(P[-1], B)
    for T in P:  # all valid rigid transforms
        np.testing.assert_allclose(T[:3, :3].T @ T[:3, :3], np.eye(3), atol=1e-12)
    if method != "se3":  # the screw geodesic's translation is not a straight line
        np.testing.assert_allclose(P[:, :3, 3], A[:3, 3] + np.arange(1, 8)[:, None] / 7 * (B[:3, 3] - A[:3, 3]), atol=1e-12)
    del rng


def test_joint_space_steps():
    q0 = np.zeros((2, 6))
    q1 = np.radians([[50, -30, 10, 0, 5, 0], [0, 0, 0, 90, 0, -45]])
    R = robmov(q0, q1)
    assert np.array_equal(R[-1], q1) and np.abs(np.diff(np.vstack([q0[None], R]), axis=0)).max() <= math.radians(20) + 1e-12
    assert len(R) == 5  # 90 deg in <= 20 deg steps
    with pytest.raises(ParameterError):
        robmov(q0, q1, max_step=-1)
