"""The planner's one-branch IK fast path (dualpuma.branch_path) against ground truth and the
general path: joint paths built first (so the answer is known), then solved back from their FK."""

import math

import numpy as np
import pytest

from dualpuma import puma
from dualpuma.branch_path import solve_lines_branch, solve_path_branch
from dualpuma.coordination import solve_path

LIM = puma.JOINT_LIMITS
MAX_STEP = math.radians(20.0)


def joint_path(q_start, q_end, n):
    s = np.linspace(0.0, 1.0, n + 1)[1:, None]
    return q_start + s * (q_end - q_start)


def solve(qL_path, qR_path, q0L, q0R, max_step=MAX_STEP):
    return solve_path_branch((puma.fk(qL_path), puma.fk(qR_path)), (q0L, q0R), LIM, max_step)


@pytest.fixture()
def q_pair(cell):
    return np.asarray(cell.left.q_home, float), np.asarray(cell.right.q_home, float)


def well_inside_one_branch(path):
    """The whole path on one branch, away from the shoulder, elbow and wrist singularities."""
    q2, q3, q5 = path[:, 1], path[:, 2], path[:, 4]
    r = puma.A2 * np.cos(q2) + puma.A3 * np.cos(q2 + q3) - puma.D4 * np.sin(q2 + q3)
    elbow = np.cos(math.atan2(puma.A3, puma.D4) - q3)
    return (np.all(np.abs(r) > 0.05) and np.all(np.abs(elbow) > 0.1) and np.all(np.abs(q5) > 0.25)
            and len(set(puma.branch_of(path).tolist())) == 1)


def test_recovers_known_joint_paths(rng, q_pair):
    """Random smooth joint paths inside the limits on random branches come back exactly."""
    branches = set()
    for _ in range(30):
        paths = []
        for _arm in range(2):
            while True:
                a = rng.uniform(LIM[:, 0] + 0.3, LIM[:, 1] - 0.3)
                b = np.clip(a + rng.uniform(-0.6, 0.6, 6), LIM[:, 0], LIM[:, 1])
                path = joint_path(a, b, 40)
                if well_inside_one_branch(np.vstack([a, path])):
                    break
            paths.append((a, path))
            branches.add(int(puma.branch_of(a)))
        (a, L), (b, R) = paths
        Q, ok, first, status, why = solve(L, R, a, b)
        assert ok.all() and tuple(first) == (40, 40) and status == ["ok", "ok"], why
        np.testing.assert_allclose(Q[:, :6], L, atol=1e-9)
        np.testing.assert_allclose(Q[:, 6:], R, atol=1e-9)
    assert len(branches) >= 6  # most of the eight branches were exercised


def test_continues_through_the_wrist_singularity(q_pair):
    """q5 crossing zero: the wrist-flip label changes, the joint path must not jump."""
    a = np.array([0.3, -1.0, -1.2, 0.4, 0.35, 0.2])
    b = a.copy()
    b[3], b[4], b[5] = 0.9, -0.35, -0.4
    L = joint_path(a, b, 41)  # no sample exactly at q5 = 0
    assert puma.branch_of(L[0]) != puma.branch_of(L[-1])
    R = np.tile(q_pair[1], (41, 1))
    Q, ok, _first, _status, why = solve(L, R, a, q_pair[1])
    assert ok.all(), why
    np.testing.assert_allclose(Q[:, :6], L, atol=1e-8)


def test_exactly_singular_is_left_to_the_general_path(q_pair):
    a = np.array([0.3, -1.0, -1.2, 0.4, 0.2, 0.2])
    b = a.copy()
    b[4] = -0.2
    L = joint_path(a, b, 20)
    L[9, 4] = 0.0
    assert solve(L, np.tile(q_pair[1], (20, 1)), a, q_pair[1]) is None


def test_reports_limits_jumps_and_reach(q_pair):
    qL, qR = q_pair
    R = np.tile(qR, (10, 1))
    # joint 2 driven past its +45 deg limit at a known index
    end = qL.copy()
    end[1] = LIM[1, 1] + 0.2
    L = joint_path(qL, end, 10)
    out = solve_path_branch((puma.fk(L), puma.fk(R)), (qL, qR), LIM + np.array([[0, 0], [0, 1.0], [0, 0], [0, 0], [0, 0], [0, 0]]), MAX_STEP)
    assert out[3] == ["ok", "ok"]  # inside the widened limits
    _Q, _ok, first, status, _why = solve(L, R, qL, qR)
    k = int(np.argmax(L[:, 1] > LIM[1, 1] + 1e-12))
    assert first[0] == k and status[0] == "joint_limits" and first[1] == 10
    # a jump: the same path in two samples instead of ten, with a small max_step
    _Q, _ok, first, status, why = solve(joint_path(qL, end, 2), R[:2], qL, qR, max_step=math.radians(5))
    assert first[0] == 0 and status[0] == "jump" and "deg in one step" in why[0]
    # unreachable: the wrist centre 2 m away
    T = puma.fk(L)
    T[4:, :3, 3] *= 5.0
    _Q, _ok, first, status, why = solve_path_branch((T, puma.fk(R)), (qL, qR), LIM, MAX_STEP)
    assert first[0] == 4 and status[0] == "unreachable"


def test_several_lines_equal_each_alone(rng, q_pair):
    qL, qR = q_pair
    paths = []
    for n in (7, 12, 3):
        eL, eR = qL + rng.uniform(-0.3, 0.3, 6), qR + rng.uniform(-0.3, 0.3, 6)
        paths.append((puma.fk(joint_path(qL, eL, n)), puma.fk(joint_path(qR, eR, n))))
    starts = np.array([0, 7, 19])
    T_bh = (np.concatenate([p[0] for p in paths]), np.concatenate([p[1] for p in paths]))
    many = solve_lines_branch(T_bh, starts, (qL, qR), LIM, MAX_STEP)
    for (TL, TR), got in zip(paths, many):
        alone = solve_path_branch((TL, TR), (qL, qR), LIM, MAX_STEP)
        np.testing.assert_array_equal(got[0], alone[0])
        np.testing.assert_array_equal(got[2], alone[2])
        assert got[3] == alone[3]


@pytest.mark.parametrize(("max_step_deg", "dx", "dphi", "walks"), [(None, 0.02, 0.04, 40), (170.0, 0.08, 0.5, 150)])
def test_fast_path_equals_general_solve_path(world, cell, rng, max_step_deg, dx, dphi, walks):
    """solve_path's planner fast path (_trusted) against its general path, on object random walks
    that also run into limits and out of reach (also with a step bound so loose that big jumps
    pass and only the wrist-partner rule tells the paths apart)."""
    kw = {} if max_step_deg is None else {"max_step": math.radians(max_step_deg)}
    q0 = (np.asarray(cell.left.q_home, float), np.asarray(cell.right.q_home, float))
    for _ in range(walks):
        P = [cell.T_world_object_start]
        for _i in range(30):
            T = P[-1].copy()
            T[:3, 3] += rng.normal(0.0, dx, 3)
            w = rng.normal(0.0, dphi, 3)
            th = np.linalg.norm(w)
            K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / th
            T[:3, :3] = (np.eye(3) + math.sin(th) * K + (1 - math.cos(th)) * K @ K) @ T[:3, :3]
            P.append(T)
        P = np.array(P[1:])
        fast = solve_path(world, P, q0, _trusted=True, **kw)
        general = solve_path(world, P, q0, **kw)
        assert fast.n_ok == general.n_ok and fast.status == general.status and fast.reason == general.reason
        np.testing.assert_allclose(fast.q_left[: fast.n_ok], general.q_left[: fast.n_ok], atol=1e-9)
        np.testing.assert_allclose(fast.q_right[: fast.n_ok], general.q_right[: fast.n_ok], atol=1e-9)


def test_branch_signs_match_branch_of(rng):
    from dualpuma.planner import _branch_index

    Q = rng.uniform(LIM[:, 0], LIM[:, 1], (500, 6))
    assert [_branch_index(q) for q in Q] == puma.branch_of(Q).tolist()
    assert len(set(puma.branch_of(Q).tolist())) == 8


def test_empty_path_gives_an_empty_solution(world, cell):
    """Zero poses: both routes return an empty, 'ok' solution rather than failing on indexing."""
    q0 = (np.asarray(cell.left.q_home, float), np.asarray(cell.right.q_home, float))
    for trusted in (False, True):
        sol = solve_path(world, np.zeros((0, 4, 4)), q0, _trusted=trusted)
        assert sol.n_ok == 0 and sol.status == ("ok", "ok")
        assert sol.q_left.shape == (0, 6) and sol.q_right.shape == (0, 6) and sol.ok.shape == (0,)
