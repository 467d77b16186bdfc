"""Branch continuity along paths (dualpuma.kinematics.continuity) against ground truth and against an
independent reference: joint paths built first (so the answer is known), then solved back from
their FK; object random walks compared with an all-branch reference built here from ``ik_all``.

(Formerly tests/test_branch_path.py: the planner's one-branch fast path and solve_path's general
path are now one implementation, so the fast-vs-general comparison became a comparison with the
reference below.)"""

import math

import numpy as np
import pinocchio as pin
import pytest
from motion_reference import MotionReference, geodesic_poses, track_hand

from dualpuma import puma
from dualpuma.kinematics import continue_paths, hands_from_object, solve_dual, solve_path
from dualpuma.kinematics.continuity import SINGULAR_Q5, wrist_tracks
from dualpuma.kinematics.dual import solve_path_unchecked
from dualpuma.kinematics.providers import PumaIK

LIM = puma.JOINT_LIMITS
LIM2 = np.stack([LIM, LIM])
MAX_STEP = math.radians(20.0)
PUMAS = [PumaIK(), PumaIK()]


def joint_path(q_start, q_end, n):
    s = np.linspace(0.0, 1.0, n + 1)[1:, None]
    return q_start + s * (q_end - q_start)


def solve(qL_path, qR_path, q0L, q0R, max_step=MAX_STEP, limits=LIM2):
    """One path for both arms: (Q (n, 12), ok (2, n), first (2,), status [2], why [2])."""
    T = np.stack([puma.fk(qL_path), puma.fk(qR_path)])
    return unpack(continue_paths(PUMAS, T, np.zeros(1, dtype=np.int64), np.stack([q0L, q0R]), limits, max_step))


def unpack(out, li=0, a=0, b=None):
    q, ok, first, reasons = out
    b = q.shape[1] if b is None else b
    return (np.hstack([q[0, a:b], q[1, a:b]]), ok[:, a:b], first[:, li], [reasons[k][li][0] for k in range(2)],
            [reasons[k][li][1] for k in range(2)])


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


def test_exactly_singular_pose_takes_q4_from_the_start(q_pair):
    """A pose exactly at q5 = 0 (only q4 + q6 defined): q4 is the start's, the path goes on."""
    a = np.array([0.3, -1.0, -1.2, 0.4, 0.2, 0.2])
    b = a.copy()
    b[4] = -0.2
    L = joint_path(a, b, 20)
    L[9, 4] = 0.0
    Q, ok, _first, _status, why = solve(L, np.tile(q_pair[1], (20, 1)), a, q_pair[1])
    assert ok.all(), why
    assert Q[9, 3] == a[3]  # taken from the start joints (q4 stays 0.4 along this path)
    np.testing.assert_allclose(Q[:, :6], L, atol=1e-8)
    np.testing.assert_allclose(puma.fk(Q[9, :6]), puma.fk(L[9]), atol=1e-12)


def test_reports_limits_jumps_and_reach(q_pair):
    qL, qR = q_pair
    R = np.tile(qR, (10, 1))
    # joint 2 driven past its +45 deg limit at a known index
    end = qL.copy()
    end[1] = LIM[1, 1] + 0.2
    L = joint_path(qL, end, 10)
    wider = LIM + np.array([[0, 0], [0, 1.0], [0, 0], [0, 0], [0, 0], [0, 0]])
    assert solve(L, R, qL, qR, limits=np.stack([wider, LIM]))[3] == ["ok", "ok"]  # inside the widened limits
    _Q, _ok, first, status, _why = solve(L, R, qL, qR)
    k = int(np.argmax(L[:, 1] > LIM[1, 1] + 1e-12))
    assert first[0] == k and status[0] == "joint_limits" and first[1] == 10
    # a jump: the same path in two samples instead of ten, with a small max_step
    _Q, _ok, first, status, why = solve(joint_path(qL, end, 2), R[:2], qL, qR, max_step=math.radians(5))
    assert first[0] == 0 and status[0] == "jump" and "rad in one step" in why[0]  # SI in the API
    # unreachable: the wrist centre 2 m away
    T = puma.fk(L)
    T[4:, :3, 3] *= 5.0
    out = continue_paths(PUMAS, np.stack([T, puma.fk(R)]), np.zeros(1, dtype=np.int64), np.stack([qL, qR]), LIM2, MAX_STEP)
    _Q, _ok, first, status, why = unpack(out)
    assert first[0] == 4 and status[0] == "unreachable" and "on the arm's IK branch" in why[0]
    # (it said "outside the arm's reach": a UR5 pose reachable on another branch was told so in the viewer)


def test_several_paths_equal_each_alone(rng, q_pair):
    qL, qR = q_pair
    paths = []
    for n in (7, 12, 3):
        eL, eR = qL + rng.uniform(-0.3, 0.3, 6), qR + rng.uniform(-0.3, 0.3, 6)
        paths.append((puma.fk(joint_path(qL, eL, n)), puma.fk(joint_path(qR, eR, n))))
    starts = np.array([0, 7, 19])
    T = np.stack([np.concatenate([p[0] for p in paths]), np.concatenate([p[1] for p in paths])])
    many = continue_paths(PUMAS, T, starts, np.stack([qL, qR]), LIM2, MAX_STEP)
    for li, ((TL, TR), a, b) in enumerate(zip(paths, starts, [7, 19, 22])):
        alone = unpack(continue_paths(PUMAS, np.stack([TL, TR]), np.zeros(1, dtype=np.int64), np.stack([qL, qR]), LIM2,
                                      MAX_STEP))
        got = unpack(many, li, a, b)
        np.testing.assert_array_equal(got[0], alone[0])
        np.testing.assert_array_equal(got[2], alone[2])
        assert got[3] == alone[3]


def reference_path(world, P, q0, max_step):
    """The general route written independently: all eight branches of every pose (ik_all), the
    start's branch and its wrist partner followed by wrist_tracks, unwrapped along the path, then
    limits and jumps; returns (n_ok, q_left, q_right)."""
    qs, firsts = [], []
    for k, T_bh in enumerate(hands_from_object(world.cell, P)):
        sols, valid = puma.ik_all(T_bh, q_near=q0[k])
        b = int(puma.branch_of(q0[k]))
        q, flipped = wrist_tracks(sols[:, b], sols[:, b ^ 1], q0[k])
        ok = valid[np.arange(len(P)), np.where(flipped, b ^ 1, b)] & ~np.isnan(q).any(axis=1)
        qq = np.where(ok[:, None], q, 0.0)
        delta = np.diff(np.vstack([q0[k], qq]), axis=0)
        q_unw = qq - 2 * np.pi * np.cumsum(np.round(delta / (2 * np.pi)), axis=0)
        ok &= np.all((q_unw >= LIM[:, 0] - 1e-12) & (q_unw <= LIM[:, 1] + 1e-12), axis=1)
        ok &= np.max(np.abs(np.diff(np.vstack([q0[k], q_unw]), axis=0)), axis=1) <= max_step
        qs.append(q_unw)
        firsts.append(len(P) if ok.all() else int(np.argmin(ok)))
    return min(firsts), qs[0], qs[1]


@pytest.mark.parametrize(("max_step_deg", "dx", "dphi", "walks"), [(20.0, 0.02, 0.04, 40), (170.0, 0.08, 0.5, 150)])
def test_path_equals_the_all_branch_reference(world, cell, rng, max_step_deg, dx, dphi, walks):
    """solve_path against the independent all-branch reference, on object random walks that also
    run into limits and out of reach (also with a step bound so loose that big jumps pass and only
    the wrist-partner rule decides)."""
    max_step = math.radians(max_step_deg)
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
        sol = solve_path(world, P, q0, max_step=max_step)
        n_ref, qL, qR = reference_path(world, P, q0, max_step)
        assert sol.n_ok == n_ref, sol.reason
        np.testing.assert_allclose(sol.q_left[: sol.n_ok], qL[: sol.n_ok], atol=1e-9)
        np.testing.assert_allclose(sol.q_right[: sol.n_ok], qR[: sol.n_ok], atol=1e-9)
        if sol.n_ok < len(P):
            assert sol.reason.startswith(("left arm at step", "right arm at step"))


def test_branch_signs_match_branch_of(rng):
    Q = rng.uniform(LIM[:, 0], LIM[:, 1], (500, 6))
    idx = []
    for q in Q:
        sh, el, flip = puma.branch_signs(q)
        idx.append(4 * (sh < 0) + 2 * (el < 0) + int(flip))
    assert idx == puma.branch_of(Q).tolist()
    assert len(set(idx)) == 8


def test_empty_path_gives_an_empty_solution(world, cell):
    """Zero poses: an empty, 'ok' solution rather than failing on indexing."""
    q0 = (np.asarray(cell.left.q_home, float), np.asarray(cell.right.q_home, float))
    for sol in (solve_path(world, np.zeros((0, 4, 4)), q0), solve_path_unchecked(world, np.zeros((0, 4, 4)), q0, 0.3)):
        assert sol.n_ok == 0 and sol.status == ("ok", "ok")
        assert sol.q_left.shape == (0, 6) and sol.q_right.shape == (0, 6) and sol.ok.shape == (0,)


def test_singular_status_is_reported_next_to_q5_zero(q_pair):
    """A jump next to the wrist singularity is reported as 'singular', elsewhere as 'jump'."""
    a = np.array([0.3, -1.0, -1.2, 0.4, 0.5 * SINGULAR_Q5, 0.2])
    b = a.copy()
    b[3] += 1.0  # q4 turns 57 deg in one pose with q5 near zero
    _Q, _ok, first, status, _why = solve(joint_path(a, b, 1), np.tile(q_pair[1], (1, 1)), a, q_pair[1])
    assert first[0] == 0 and status[0] == "singular"


# ----------------------------------------------------------------------------- near the wrist singularity
# Two consecutive rows of a reached plan (found by the certified-motion property): the bar's poses
# and both arms' joints (left, right). The left arm's q5 goes from +6.6 deg to -0.5 deg: sampled
# coarsely, its IK was continued onto the wrist partner (q4 8.7 -> 0 deg), but the bar's path only
# passes 0.05 deg from q5 = 0, and holding the bar along it the wrist swings q4 and q6 by ~180 deg.
_ROW_A = np.array([
    [0.995159566641218, -0.08884575526873459, -0.0419984367946165, 1.654455232554317],
    [-0.08646037910273147, -0.9947048312324903, 0.055559891721951644, -0.17123050576044382],
    [-0.04671230852650337, -0.051659757001665675, -0.9975716664674542, 0.2302616955006931],
    [0.0, 0.0, 0.0, 1.0]])
_ROW_B = np.array([
    [9.9935533837776158e-01, -3.5901360083842204e-02, -4.3966485711713910e-18, 1.6280671352038172e+00],
    [-3.5901360083842204e-02, -9.9935533837776158e-01, -1.2238573163551458e-16, -1.6857571875798100e-01],
    [0.0, 1.2246467991473532e-16, -1.0, 2.1841083046699092e-01],
    [0.0, 0.0, 0.0, 1.0]])
_Q_A = np.array([0.8990947803232114, -0.03222087766271268, -0.01445404784447299, 0.1511688848960761,
                 0.11549281092407242, -0.7345918857489778, -1.2877494731472496, 0.20598529396082454,
                 0.36922987204840074, 0.11497802851812855, -0.6031718704857431, -2.866306461228565])
_Q_B = np.array([8.4119536500304259e-01, 2.1124116201105270e-02, -1.2327431308612524e-02, 1.0658141036401503e-14,
                 -8.7966848924928235e-03, -6.9369188497510237e-01, -1.4002595462005245e+00,
                 2.0162820626594657e-01, 3.6086790309442907e-01, 0.0, -5.6249610936037575e-01,
                 -2.9351467961786581e+00])


def test_a_false_wrist_crossing_is_refused(world, cell):
    """The closed chain follows a step across sin q5 = 0 only if the IK continued densely along the
    bar's path ends at the step's end joints (what a timed trajectory does); checked against a
    Pinocchio-only tracking of the left hand along the same path (4,000 poses)."""
    from dualpuma.kinematics.bar_path import WRIST_SWING, first_unfollowed

    hands = world.hand_poses(_Q_A[:6], _Q_A[6:]), world.hand_poses(_Q_B[:6], _Q_B[6:])
    for H, T in zip(hands, (_ROW_A, _ROW_B)):  # the rows hold the bar
        np.testing.assert_allclose(H[0], T @ cell.grasp_left.T_object_hand, atol=1e-9)
        np.testing.assert_allclose(H[1], T @ cell.grasp_right.T_object_hand, atol=1e-9)
    targets = [np.linalg.inv(cell.left.T_world_base) @ T @ cell.grasp_left.T_object_hand
               for T in geodesic_poses(_ROW_A, _ROW_B, np.arange(1, 4001) / 4000)]
    q_end = track_hand(world.arms["left"], targets, _Q_A[:6].copy())[-1]
    np.testing.assert_allclose(world.arms["left"].fk(q_end), targets[-1], atol=1e-9)
    gap = np.abs((q_end - _Q_B[:6] + np.pi) % (2 * np.pi) - np.pi)
    assert gap[3] > 2.5 and gap[5] > 2.5  # holding the bar, the wrist ends about pi away in q4 and q6
    P, Q = _ROW_B[None], _Q_B[None]
    assert first_unfollowed(world, P, Q[:, :6], Q[:, 6:], _Q_A, _ROW_A, 1, 1) == (0, WRIST_SWING)
    assert first_unfollowed(world, P, Q[:, :6], Q[:, 6:], _Q_A, None, 1, 1) == (0, WRIST_SWING)  # the start pose from the left hand's joints
    assert first_unfollowed(world, P, q_end[None], _Q_B[None, 6:], _Q_A, _ROW_A, 1, 1) == (1, "")  # as the arms follow it


# Two consecutive rows of a plan Striving returned as reached on a random problem (default cell,
# seed 13604, 0.1 m steps, one substep): the right elbow is at 44.23 and 44.77 deg (limit 45) at the
# rows and at 44.98 and 45.00 deg at the poses checked between them, but holding the bar along the
# path between those it reaches 45.02 deg: no timed trajectory could follow the step.
_ROW_4 = np.array([[0.9910893541299959, -0.13319869417598573, -1.4493500288243887e-17, 1.795993883387809],
                   [-0.1331986941759857, -0.9910893541299959, -9.418800055279763e-17, -0.19666961168320093],
                   [-1.8186351590789973e-18, 9.527923994710125e-17, -1.0, 0.3930327304833399], [0.0, 0.0, 0.0, 1.0]])
_ROW_5 = np.array([[0.9883669049850098, -0.15208833331440216, -1.758641829384422e-17, 1.7056857073140084],
                   [-0.15208833331440214, -0.9883669049850098, -1.0745599414785208e-16, -0.1960638375788284],
                   [-1.0390307642697103e-18, 1.0888063740528056e-16, -1.0, 0.4101576570853058], [0.0, 0.0, 0.0, 1.0]])
_Q_4 = np.array([1.0351021051205764, -0.3124805592393702, -0.12967319174034542, -2.0657707066829264e-16,
                 0.4421537509797156, -0.40209848317057856, -0.6313729500354436, -0.20000000117756433,
                 0.7719513727722703, 0.0, -0.5719513715947062, -2.068573538326598])
_Q_5 = np.array([0.9507198292361594, -0.4133251184897965, 0.15272989647348217, -3.790746947524498e-16,
                 0.26059522201631424, -0.4673956535544612, -0.9690535789461426, -0.28234871325130256,
                 0.7813354245751133, 0.0, -0.49898671132381095, -2.387169061736763])


def test_a_step_whose_path_leaves_a_joint_limit_is_refused(world, cell):
    """Both rows hold the bar within the joint limits, but a Pinocchio-only tracking of the right
    hand along the bar's path between them (2,000 poses) takes the elbow beyond its 45 deg limit:
    the step is not followed, and the reason says why (it was accepted before: only wrist crossings
    were followed densely). The same check passes a step that stays inside."""
    from dualpuma.kinematics.bar_path import LIMIT_EXCURSION, first_unfollowed

    for q, T in ((_Q_4, _ROW_4), (_Q_5, _ROW_5)):
        H = world.hand_poses(q[:6], q[6:])
        np.testing.assert_allclose(H[1], T @ cell.grasp_right.T_object_hand, atol=1e-9)
    lim = world.arms["right"].limits
    assert np.all((_Q_4[6:] > lim[:, 0]) & (_Q_4[6:] < lim[:, 1]) & (_Q_5[6:] > lim[:, 0]) & (_Q_5[6:] < lim[:, 1]))
    path = MotionReference(cell).bar_path(_ROW_4, _ROW_5, _Q_4, 2000)
    q, elbow = path[-1, 6:], path[:, 8]  # the right arm; its elbow
    np.testing.assert_allclose(q, _Q_5[6:], atol=1e-9)  # the tracking ends at the row's joints
    assert max(elbow) > lim[2, 1] + math.radians(0.01)  # beyond the limit on the way
    P = _ROW_5[None]
    assert first_unfollowed(world, P, _Q_5[None, :6], _Q_5[None, 6:], _Q_4, _ROW_4, 1, 1) == (0, LIMIT_EXCURSION)
    # halfway along the same step the elbow is still inside: that part is followed
    mid = 0.25
    T = geodesic_poses(_ROW_4, _ROW_5, [mid])[0]
    sol = solve_path_unchecked(world, T[None], (_Q_4[:6], _Q_4[6:]), 1.0)
    assert sol.n_ok == 1 and max(elbow[: int(mid * 2000)]) < lim[2, 1]
    assert first_unfollowed(world, T[None], sol.q_left, sol.q_right, _Q_4, _ROW_4, 1, 1) == (1, "")
    # a plan holding that step cannot be timed, and time_plan says why
    import dataclasses

    from dualpuma import plan
    from dualpuma.errors import ParameterError
    from dualpuma.planning import time_plan

    goal = cell.T_world_object_start.copy()
    goal[2, 3] += 0.01
    two = plan(cell, cell.T_world_object_start, goal, world=world)
    two = dataclasses.replace(two, T_world_object=np.stack([_ROW_4, _ROW_5]), q_left=np.stack([_Q_4[:6], _Q_5[:6]]),
                              q_right=np.stack([_Q_4[6:], _Q_5[6:]]), clearance=two.clearance[:2], pair=two.pair[:2],
                              t=two.t[:2])
    with pytest.raises(ParameterError, match="from row 0 to row 1 .* takes a joint beyond its limit"):
        time_plan(two, world)


def _turned(T, axis, angle, shift):
    out = T.copy()
    out[:3, :3] = T[:3, :3] @ pin.exp3(np.asarray(axis, float) * angle)
    out[:3, 3] += shift
    return out


def test_hold_bar_continues_each_pose_from_its_own_joints(world, cell, rng):
    """hold_bar solves both arms at many bar poses at once, each from its own nearby joints: the
    result is the continuous motion from those joints (a Pinocchio-only tracking of both hands
    along the bar's path to the pose, 40 poses), and its hands hold the bar (Pinocchio FK)."""
    from dualpuma.kinematics.bar_path import hold_bar
    from dualpuma.kinematics.dual import bar_poses

    A = cell.T_world_object_start
    s0 = solve_dual(world, A, (cell.left.q_home, cell.right.q_home), max_step=2 * math.pi, check_clearance=False)
    starts, targets = [], []
    for _ in range(12):
        q = np.concatenate([s0.q_left, s0.q_right])
        Tq = _turned(A, rng.normal(size=3) / math.sqrt(3), rng.uniform(-0.1, 0.1), rng.uniform(-0.05, 0.05, 3))
        s = solve_dual(world, Tq, (q[:6], q[6:]), max_step=2 * math.pi, check_clearance=False)
        starts.append(np.concatenate([s.q_left, s.q_right]))
        targets.append(_turned(Tq, rng.normal(size=3) / math.sqrt(3), rng.uniform(-0.03, 0.03),
                               rng.uniform(-0.01, 0.01, 3)))
    Q0, P = np.array(starts), np.array(targets)
    Q, ok = hold_bar(world, P, Q0)
    ref = MotionReference(cell)
    assert ok.all()
    for k in range(P.shape[0]):
        expect = ref.bar_path(bar_poses(world, Q0[k : k + 1])[0], P[k], Q0[k], 40)[-1]
        np.testing.assert_allclose(Q[k], expect, atol=1e-8)
        H = world.hand_poses(Q[k, :6], Q[k, 6:])
        np.testing.assert_allclose(H[0], P[k] @ cell.grasp_left.T_object_hand, atol=1e-9)
        np.testing.assert_allclose(H[1], P[k] @ cell.grasp_right.T_object_hand, atol=1e-9)
    far = P[:1].copy()
    far[0, :3, 3] += (3.0, 0.0, 0.0)
    assert not hold_bar(world, far, Q0[:1])[1][0]  # out of reach


def test_hold_bar_follows_the_wrist_past_q5_zero(world, cell):
    """Near q5 = 0 either wrist label may be the continuation (hold_bar weighs both there): along
    the bar's path from _ROW_A to _ROW_B, which passes 0.05 deg from the left wrist's singularity
    while q4 and q6 swing by about 180 deg, hold_bar from each of 80 tracked configurations to the
    pose 5 / 400 of the step further gives the Pinocchio-only tracking's joints there."""
    from dualpuma.kinematics.bar_path import hold_bar

    n, ahead = 400, 5
    path = np.vstack([_Q_A, MotionReference(cell).bar_path(_ROW_A, _ROW_B, _Q_A, n)])
    poses = geodesic_poses(_ROW_A, _ROW_B, np.arange(0, n + 1) / n)
    k = np.arange(0, n + 1 - ahead, ahead)
    Q, ok = hold_bar(world, poses[k + ahead], path[k])
    assert ok.all()
    np.testing.assert_allclose(Q, path[k + ahead], atol=1e-6)
    assert np.sum(np.abs(path[k, 4]) < 2 * SINGULAR_Q5) > 10  # many starts where both labels are weighed
    assert np.ptp(path[:, 3]) > 2.5  # q4 swings on the way
