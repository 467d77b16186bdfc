"""RRT-Connect fallback in SE(3) (dualpuma.fallback): the snaking slot field is solved and every
returned step is re-checked independently; determinism; honest failures; validated parameters.

The independent checks use Pinocchio's FK of the combined model (World.hand_poses), the scalar coal
query (World.clearance), pinocchio.exp3 for the sub-poses and the scalar, step-by-step dual IK
(solve_dual) — not the module's vectorised paths (solve_path, clearance_batch, its own SE(3)
interpolation).
"""

from __future__ import annotations

import dataclasses
import math
import re
import time
import types

import numpy as np
import pinocchio as pin
import pytest

from dualpuma import Cell, World
from dualpuma.errors import JointError, ParameterError, PoseError
from dualpuma.kinematics import solve_dual
from dualpuma.lie import rpy_to_rot
from dualpuma.model import Obstacle
from dualpuma.planning import FallbackParams, FallbackResult, interpolate_object, rrt_connect
from dualpuma.scenarios import SLOT_YAW, slot_field_cell

GJK_TOL = 1e-6  # coal's GJK/EPA distances agree to about this whatever the query order [m]


def assert_path_valid(
    world: World, res: FallbackResult, *, margin: float, params: FallbackParams, fine: int = 5
) -> None:
    """Every step, and ``fine - 1`` sub-poses between steps, are permitted; steps are small."""
    cell = world.cell
    T, QL, QR, t = res.T_world_object, res.q_left, res.q_right, res.t
    n = T.shape[0]
    assert n >= 2 and QL.shape == QR.shape == (n, 6) and res.clearance.shape == t.shape == (n,)
    for i in range(n):
        HL, HR = world.hand_poses(QL[i], QR[i])  # Pinocchio FK
        np.testing.assert_allclose(
            HL, T[i] @ cell.grasp_left.T_object_hand, atol=1e-9, err_msg=f"left grasp, step {i}"
        )
        np.testing.assert_allclose(
            HR, T[i] @ cell.grasp_right.T_object_hand, atol=1e-9, err_msg=f"right grasp, step {i}"
        )
        for side, q in (("left", QL[i]), ("right", QR[i])):
            lim = world.arms[side].limits
            assert np.all(q >= lim[:, 0] - 1e-12) and np.all(q <= lim[:, 1] + 1e-12), (
                f"{side} limits, step {i}"
            )
        c = world.clearance(QL[i], QR[i], T[i], float(t[i]))
        assert c.distance >= margin - GJK_TOL, f"step {i}: clearance {c.distance} ({c.pair})"
        assert abs(c.distance - res.clearance[i]) < GJK_TOL, (
            f"step {i}: reported clearance {res.clearance[i]} vs {c.distance}"
        )
        if i == 0:
            continue
        A = T[i - 1]
        w = pin.log3(A[:3, :3].T @ T[i][:3, :3])
        assert np.linalg.norm(T[i][:3, 3] - A[:3, 3]) <= params.step + 1e-9, (
            f"step {i}: translation"
        )
        assert np.linalg.norm(w) <= params.rot_step + 1e-9, (
            f"step {i}: rotation {np.degrees(np.linalg.norm(w))} deg"
        )
        dq = max(np.abs(QL[i] - QL[i - 1]).max(), np.abs(QR[i] - QR[i - 1]).max())
        assert dq <= params.max_joint_step + 1e-9, f"step {i}: joint step {np.degrees(dq):.2f} deg"
        q = (QL[i - 1], QR[i - 1])
        for k in range(1, fine + 1):  # geodesic sub-poses, each solved from the previous one
            s = k / fine
            M = np.eye(4)
            M[:3, :3] = A[:3, :3] @ pin.exp3(s * w)
            M[:3, 3] = A[:3, 3] + s * (T[i][:3, 3] - A[:3, 3])
            tt = float(t[i - 1] + s * (t[i] - t[i - 1]))
            sol = solve_dual(
                world, M, q, max_step=params.max_joint_step, check_clearance=False, t=tt
            )
            assert sol.ok, f"between steps {i - 1} and {i} (s = {s}): {sol.reason}"
            d = world.clearance(sol.q_left, sol.q_right, M, tt).distance
            assert d >= margin - GJK_TOL, f"between steps {i - 1} and {i} (s = {s}): clearance {d}"
            q = (sol.q_left, sol.q_right)
        np.testing.assert_allclose(
            q[0], QL[i], atol=1e-6, err_msg=f"left joints discontinuous before step {i}"
        )
        np.testing.assert_allclose(
            q[1], QR[i], atol=1e-6, err_msg=f"right joints discontinuous before step {i}"
        )


def _start_joints(world: World, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    cell = world.cell
    sol = solve_dual(world, T, (cell.left.q_home, cell.right.q_home), max_step=2 * math.pi)
    assert sol.ok, sol.reason
    return sol.q_left, sol.q_right


@pytest.fixture(scope="module")
def slot():
    cell, A, B = slot_field_cell()
    world = World(cell)
    return cell, world, A, B, _start_joints(world, A)


@pytest.fixture(scope="module")
def snake(slot):
    _cell, world, A, B, q0 = slot
    return rrt_connect(world, A, q0, B)  # default parameters, rng None = seed 0


# ----------------------------------------------------------------------------- the scenario
def test_slot_field_needs_rotation(slot):
    cell, world, A, B, q0 = slot
    margin = cell.safety_margin
    # start and goal are permitted
    assert world.clearance(*q0, A).distance >= margin
    qg = solve_dual(world, B, q0, max_step=2 * math.pi)
    assert qg.ok, qg.reason
    # the straight, fixed-orientation path is blocked (1 cm steps, step-by-step IK, scalar clearance)
    q, worst = q0, np.inf
    for T in interpolate_object(A, B, 49):
        sol = solve_dual(world, T, q, check_clearance=False)
        assert sol.ok, sol.reason
        q = (sol.q_left, sol.q_right)
        worst = min(worst, world.clearance(*q, T).distance)
    assert worst < margin - 0.003, f"straight path clearance {worst}: not blocked"
    # unrotated, the bar fits neither slot at any height or offset near it; yawed as the slot, it does
    c0 = (A @ cell.bar.T_object_bar)[:3, 3]
    for dz, yaw in ((-0.11, SLOT_YAW), (-0.37, -SLOT_YAW)):
        fits = {0.0: 0, yaw: 0}
        for psi in fits:
            R = rpy_to_rot([0.0, 0.0, psi]) @ A[:3, :3]
            for dx in np.arange(-0.1, 0.101, 0.05):
                for dy in np.arange(-0.06, 0.0601, 0.005):
                    for ddz in (-0.01, 0.0, 0.01):
                        T = np.eye(4)
                        T[:3, :3] = R
                        T[:3, 3] = (
                            c0
                            + (dx, dx * math.tan(psi) + dy, dz + ddz)
                            - R @ cell.bar.T_object_bar[:3, 3]
                        )
                        fits[psi] += solve_dual(world, T, q0, max_step=2 * math.pi).ok
        assert fits[0.0] == 0, f"the level bar fits the slot at dz {dz}"
        assert fits[yaw] > 0, f"the yawed bar fits no pose of the slot at dz {dz}"


def test_snaking_case_is_solved(slot, snake):
    cell, world, A, B, q0 = slot
    p = FallbackParams()
    assert snake.ok, snake.reason
    assert snake.reason == "" and snake.iterations >= 1 and snake.n_nodes >= 2 and snake.time_s > 0
    np.testing.assert_array_equal(snake.T_world_object[0], A)
    np.testing.assert_array_equal(snake.T_world_object[-1], B)
    np.testing.assert_array_equal(snake.q_left[0], q0[0])
    np.testing.assert_array_equal(snake.q_right[0], q0[1])
    np.testing.assert_array_equal(snake.t, np.zeros(len(snake.t)))
    assert_path_valid(world, snake, margin=cell.safety_margin, params=p)
    for name in ("T_world_object", "q_left", "q_right", "clearance", "t"):
        assert not getattr(snake, name).flags.writeable, name
    # snaking: where the bar's centre crosses each plate, its axis is turned the slot's way
    c0 = (A @ cell.bar.T_object_bar)[:3, 3]
    bars = snake.T_world_object @ cell.bar.T_object_bar
    for dz, sign in ((-0.11, 1.0), (-0.37, -1.0)):
        i = int(np.argmin(np.abs(bars[:, 2, 3] - (c0[2] + dz))))
        axis = bars[i, :3, 0]
        yaw = math.degrees(math.atan2(axis[1], axis[0]))
        yaw = (yaw + 90.0) % 180.0 - 90.0  # the bar is symmetric: its axis direction modulo 180 deg
        assert sign * yaw > 5.0, f"crossing the plate at dz {dz} with the axis at {yaw:.1f} deg"


def test_deterministic_for_a_seed(slot, snake):
    _cell, world, A, B, q0 = slot
    world.clearance(*q0, A)  # leave some other query state behind: must not matter
    again = rrt_connect(world, A, q0, B, FallbackParams(), np.random.default_rng(0))
    assert again.ok and again.iterations == snake.iterations and again.n_nodes == snake.n_nodes
    for name in ("T_world_object", "q_left", "q_right", "clearance", "t"):
        np.testing.assert_array_equal(getattr(again, name), getattr(snake, name), err_msg=name)


# ----------------------------------------------------------------------------- small problems
@pytest.fixture(scope="module")
def default():
    cell = Cell.default()
    return cell, World(cell), cell.T_world_object_start, (cell.left.q_home, cell.right.q_home)


def _box_in_the_way(cell: Cell, A: np.ndarray) -> tuple[Cell, np.ndarray]:
    """A 0.1 m box 0.5 m along -x from the bar's centre; the goal 0.25 m that way and 0.15 m up."""
    B = A.copy()
    B[:3, 3] += (-0.25, 0.0, 0.15)
    T = np.eye(4)
    T[:3, 3] = (A @ cell.bar.T_object_bar)[:3, 3] + (-0.5, 0.0, 0.0)
    return dataclasses.replace(cell, obstacles=(Obstacle("box", "box", [0.1, 0.1, 0.1], T),)), B


def test_detour_around_a_box(default):
    cell0, _, A, q0 = default
    cell, B = _box_in_the_way(cell0, A)
    world = World(cell)
    q, worst = q0, np.inf
    for T in interpolate_object(A, B, 40):  # the straight way: the bar's end runs into the box
        sol = solve_dual(world, T, q, check_clearance=False)
        q = (sol.q_left, sol.q_right)
        worst = min(worst, world.clearance(*q, T).distance)
    assert worst < 0.0
    p = FallbackParams(max_iterations=2000)
    res = rrt_connect(world, A, q0, B, p, 3)
    assert res.ok, res.reason
    np.testing.assert_array_equal(res.T_world_object[-1], B)
    assert_path_valid(world, res, margin=cell.safety_margin, params=p)


def test_moving_obstacle_is_checked_at_each_step_time(default):
    cell0, _, A, q0 = default
    B = A.copy()
    B[:3, 3] += (-0.30, 0.0, 0.0)
    bar = (A @ cell0.bar.T_object_bar)[:3, 3]
    T = np.eye(4)
    T[:3, 3] = bar + (-0.15, 0.30, 0.0)
    # a sphere crossing the straight way (-y at 1 m/s) while the bar would pass under it (t ~ 0.3 s)
    ob = Obstacle("crosser", "sphere", [0.05], T, velocity=[0.0, -1.0, 0.0], t_start=0.0, t_end=0.6)
    cell = dataclasses.replace(cell0, obstacles=(ob,))
    world = World(cell)
    straight = interpolate_object(A, B, 6)  # the direct path, one step per 0.1 s
    q, hit = q0, False
    for i, Ti in enumerate(straight, start=1):
        sol = solve_dual(world, Ti, q, check_clearance=False)
        q = (sol.q_left, sol.q_right)
        hit |= world.clearance(*q, Ti, 0.1 * i).distance < cell.safety_margin
    assert hit, "the crossing sphere should block the straight path at its real times"
    static = rrt_connect(world, A, q0, B, FallbackParams(), 0)  # step_time 0: every pose at t0 = 0
    # ... where the way is clear (since self-collision is checked, not the direct line any more: it
    # brings robot 2's wrist within 15 mm of its own pedestal) but the sphere hits it at real times
    assert static.ok
    at_real = [world.clearance(static.q_left[i], static.q_right[i], static.T_world_object[i], 0.1 * i).distance
               for i in range(len(static.t))]
    assert min(at_real) < cell.safety_margin
    p = FallbackParams(max_iterations=2000)
    res = rrt_connect(world, A, q0, B, p, 1, t0=0.0, step_time=0.1)
    assert res.ok, res.reason
    np.testing.assert_allclose(res.t, 0.1 * np.arange(len(res.t)), atol=1e-12)
    assert_path_valid(world, res, margin=cell.safety_margin, params=p)


def test_striving_margin_and_substeps_apply(default):
    _cell, world, A, q0 = default
    B = A.copy()
    B[:3, 3] += (-0.2, -0.1, 0.15)
    # 40 mm (was 50 mm): since self-collision is checked, the start itself is 46.5 mm clear (robot
    # 2's wrist to its own pedestal)
    striving = types.SimpleNamespace(margin=0.04, substeps=7)
    res = rrt_connect(world, A, q0, B, FallbackParams(), 0, striving=striving)
    assert res.ok, res.reason
    assert res.clearance.min() >= 0.04
    assert_path_valid(world, res, margin=0.04, params=FallbackParams(), fine=7)


# ----------------------------------------------------------------------------- honest failures
def test_goal_inside_an_obstacle(default):
    cell0, _, A, q0 = default
    B = A.copy()
    B[:3, 3] += (-0.3, -0.2, 0.2)
    T = np.eye(4)
    T[:3, 3] = (B @ cell0.bar.T_object_bar)[:3, 3]  # a sphere around the goal's bar centre
    cell = dataclasses.replace(cell0, obstacles=(Obstacle("block", "sphere", [0.08], T),))
    tic = time.perf_counter()
    res = rrt_connect(World(cell), A, q0, B, FallbackParams(), 0)
    assert not res.ok and res.reason.startswith("goal blocked") and "obstacle/block" in res.reason
    assert (
        res.iterations == 0 and res.T_world_object.shape == (0, 4, 4) and res.q_left.shape == (0, 6)
    )
    assert time.perf_counter() - tic < 2.0


def test_unreachable_goal(default):
    _cell, world, A, q0 = default
    B = A.copy()
    B[:3, 3] += (0.0, -3.0, 0.0)
    res = rrt_connect(world, A, q0, B, FallbackParams(), 0)
    assert not res.ok and res.reason.startswith("goal unreachable") and "unreachable" in res.reason


def test_invalid_start(default):
    _cell, world, A, q0 = default
    q_bad = (q0[0] + 0.1, q0[1])
    res = rrt_connect(world, A, q_bad, A, FallbackParams(), 0)
    assert not res.ok and res.reason.startswith("invalid start") and "left hand" in res.reason


def test_gives_up_after_max_iterations(slot):
    _cell, world, A, B, q0 = slot
    p = FallbackParams(max_iterations=150, max_rotation=1e-3, local_bias=0.0)  # hardly any rotation
    tic = time.perf_counter()
    res = rrt_connect(world, A, q0, B, p, 0)
    assert not res.ok and res.iterations == 150
    assert (
        res.reason.startswith("no path found in 150 iterations")
        and "most frequent refusals" in res.reason
    )
    assert time.perf_counter() - tic < 20.0


def test_time_limit_ends_a_search_that_finds_nothing(slot):
    _cell, world, A, B, q0 = slot
    p = FallbackParams(max_iterations=10_000_000, max_rotation=1e-3, local_bias=0.0, time_limit=0.5)
    tic = time.perf_counter()
    res = rrt_connect(world, A, q0, B, p, 0)  # hardly any rotation: no path, ever
    took = time.perf_counter() - tic
    assert not res.ok and 0 < res.iterations < 10_000_000
    assert res.reason.startswith(f"no path found within the time limit of 0.5 s ({res.iterations} iterations)")
    # checked before each iteration: it ends one iteration after the limit, not at max_iterations
    assert 0.5 <= res.time_s and took < 5.0


def test_a_time_limit_that_does_not_fire_changes_nothing(slot, snake):
    _cell, world, A, B, q0 = slot
    res = rrt_connect(world, A, q0, B, FallbackParams(time_limit=3600.0), 0)
    assert res.ok and res.iterations == snake.iterations
    np.testing.assert_array_equal(res.T_world_object, snake.T_world_object)
    np.testing.assert_array_equal(res.q_left, snake.q_left)


def _restarts_by(iterations: int, first: int) -> int:
    """Restarts within ``iterations`` when the search starts again after ``first`` iterations, then
    after twice as many more, four times as many more, ..."""
    runs, k = 0, 0
    while runs + first * 2**k < iterations:
        runs += first * 2**k
        k += 1
    return k


def test_the_search_restarts_from_new_trees_on_a_doubling_schedule(slot):
    cell, world, A, B, q0 = slot
    p = FallbackParams(max_iterations=150, max_rotation=1e-3, local_bias=0.0, restart_iterations=20)
    res = rrt_connect(world, A, q0, B, p, 0)  # hardly any rotation: no path; restarts after 20, 60, 140
    assert _restarts_by(150, 20) == 3
    assert not res.ok and res.iterations == 150 and res.restarts == 3
    assert res.reason.startswith("no path found in 150 iterations, 3 restart(s) from new trees")
    once = rrt_connect(world, A, q0, B, dataclasses.replace(p, restart_iterations=0), 0)
    assert not once.ok and once.restarts == 0 and "restart" not in once.reason
    assert res.n_nodes < once.n_nodes  # the last trees grew over 10 iterations, not 150
    # a search that restarted returns a path as valid as any (re-checked independently)
    p = FallbackParams(restart_iterations=40)
    res = rrt_connect(world, A, q0, B, p, 0)
    assert res.ok, res.reason
    assert res.restarts >= 1 and res.restarts == _restarts_by(res.iterations, 40)
    assert_path_valid(world, res, margin=cell.safety_margin, params=p)


# ----------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "kw",
    [
        {"max_iterations": 0},
        {"max_iterations": 2.5},
        {"step": 0.0},
        {"step": float("nan")},
        {"rot_step": -0.1},
        {"rot_step": 4.0},
        {"substeps": 0},
        {"max_joint_step": float("inf")},
        {"max_extend": 0.0},
        {"goal_bias": 1.5},
        {"local_bias": -0.1},
        {"goal_bias": 0.6, "local_bias": 0.6},
        {"bounds": ((0, 0, 0), (1, 1))},
        {"bounds": ((0, 0, 1), (1, 1, 0))},
        {"bounds_padding": -1.0},
        {"max_rotation": 0.0},
        {"rot_weight": float("nan")},
        {"connect_attempts": 0},
        {"restart_iterations": -1},
        {"restart_iterations": 1.5},
        {"shortcut_iterations": -1},
        {"min_shortcut_gain": -0.001},
        {"min_shortcut_gain": float("nan")},
        {"margin": -0.01},
        {"margin": "0.02"},
        {"max_iterations": True},
        {"time_limit": 0.0},
        {"time_limit": -1.0},
        {"time_limit": float("inf")},
        {"time_limit": 1e9},
        {"time_limit": "10"},
    ],
)
def test_bad_params(kw):
    with pytest.raises(ParameterError):
        FallbackParams(**kw)


def test_params_valid_and_frozen():
    p = FallbackParams(bounds=((0, 0, 0), (1, 1, 1)), margin=0.0, shortcut_iterations=0)
    assert p.bounds == ((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.step = 0.1  # type: ignore[misc]


def test_bad_inputs(default):
    cell, world, A, q0 = default
    with pytest.raises(ParameterError):
        rrt_connect(world, A, q0, A, params={"step": 0.1})  # type: ignore[arg-type]
    for rng in ("seed", -1, 2.5, True):
        with pytest.raises(ParameterError, match="rng: expected a numpy Generator, a seed"):
            rrt_connect(world, A, q0, A, FallbackParams(), rng=rng)  # type: ignore[arg-type]
    with pytest.raises(ParameterError):
        rrt_connect(world, A, q0, A, FallbackParams(), 0, step_time=-0.1)
    with pytest.raises(ParameterError):
        rrt_connect(cell, A, q0, A)  # type: ignore[arg-type]
    with pytest.raises(PoseError):
        rrt_connect(world, A[:3], q0, A)
    bad = A.copy()
    bad[0, 0] = 2.0
    with pytest.raises(PoseError):
        rrt_connect(world, A, q0, bad)
    with pytest.raises(JointError):
        rrt_connect(world, A, (q0[0][:5], q0[1]), A)


# ----------------------------------------------------------------------------- through plan()
@pytest.mark.parametrize("n", [7, 8])
def test_plan_hands_a_frozen_routine_to_the_fallback(n):
    from planner_checks import check_plan_valid

    from dualpuma import StrivingParams, plan
    from dualpuma.scenarios import routine

    r = routine(n)
    world = World(r.cell)
    A, goal = r.cell.T_world_object_start, r.legs[0][0]
    frozen = plan(r.cell, A, goal, StrivingParams(alternates=()), world=world)
    assert frozen.status == "frozen"
    p = plan(r.cell, A, goal, StrivingParams(alternates=(), fallback=True), world=world)
    assert p.status == "reached" and p.planner == "striving+rrt", p.reason
    np.testing.assert_array_equal(p.T_world_object[-1], goal)
    check_plan_valid(world, p, margin=r.cell.safety_margin)


def test_plan_snakes_through_the_slot_field(slot):
    from planner_checks import check_plan_valid

    from dualpuma import StrivingParams, plan

    cell, world, A, B, _ = slot
    assert plan(cell, A, B, StrivingParams(), world=world).status == "frozen"
    p = plan(cell, A, B, StrivingParams(fallback=True), world=world)
    assert p.status == "reached" and p.planner == "striving+rrt", p.reason
    np.testing.assert_array_equal(p.T_world_object[-1], B)
    check_plan_valid(world, p, margin=cell.safety_margin)


def test_a_plan_reports_the_searchs_restarts(slot):
    from planner_checks import check_plan_valid

    from dualpuma import StrivingParams, plan

    cell, world, A, B, _ = slot
    params = StrivingParams(fallback=True, fallback_params=FallbackParams(restart_iterations=40))
    p = plan(cell, A, B, params, world=world)
    assert p.status == "reached", p.reason
    (event,) = [e for e in p.events if e.startswith("fallback:")]
    m = re.fullmatch(r"fallback: \d+ steps, (\d+) iterations \((\d+) restart\(s\) from new trees\)", event)
    assert m is not None, event
    assert int(m[2]) == _restarts_by(int(m[1]), 40) >= 1
    check_plan_valid(world, p, margin=cell.safety_margin)


def _nearness(T: np.ndarray, B: np.ndarray, step: float, rot_step: float) -> float:
    """Steps from T to B (the larger of distance / step and rotation angle / rot_step), computed
    here with Pinocchio's log3, not the planner's own function."""
    return max(float(np.linalg.norm(B[:3, 3] - T[:3, 3])) / step,
               float(np.linalg.norm(pin.log3(T[:3, :3].T @ B[:3, :3]))) / rot_step)


def test_plan_hands_a_wandering_striving_to_the_fallback():
    """The default cell, goal 200 mm back and 100 mm up: the straight run passes 18-19 mm from the
    right wrist's own pedestal (margin 20 mm). Striving alone wanders on the seed's alternates for
    dozens of steps before it freezes; with the fallback on it hands over once ``handover_after``
    alternates in a row have left the bar no nearer the goal, found here from Striving's own run:
    the same path up to that refusal (deterministic), re-measured with an independent nearness."""
    import re

    from planner_checks import check_plan_valid

    from dualpuma import StrivingParams, plan

    cell = Cell.default()
    world = World(cell)
    A = cell.T_world_object_start
    B = A.copy()
    B[:3, 3] += (-0.2, 0.0, 0.1)
    alone = plan(cell, A, B, StrivingParams(), world=world)
    assert alone.status == "frozen" and alone.n_steps > 40  # the seed's recovery wanders far
    prm = StrivingParams(fallback=True)
    refused = [int(m.group(1)) for e in alone.events if (m := re.match(r"step (\d+): refused .*took AP", e))]
    nearest, stalled, expected = math.inf, 0, None
    for k in refused:  # the bar at the refusal of step k is at row k - 1
        r = _nearness(alone.T_world_object[k - 1], B, prm.step, prm.rot_step)
        nearest, stalled = (r, 0) if r < nearest else (nearest, stalled + 1)
        if stalled >= prm.handover_after:
            expected = k - 1
            break
    assert expected is not None and expected < 20
    p = plan(cell, A, B, prm, world=world)
    assert p.status == "reached" and p.planner == "striving+rrt", p.reason
    handed = [e for e in p.events if "Striving handed over (no progress" in e]
    assert len(handed) == 1 and handed[0].startswith(f"step {expected}: "), p.events
    np.testing.assert_array_equal(p.T_world_object[-1], B)
    check_plan_valid(world, p, margin=cell.safety_margin)
    # the old behaviour, still available: Striving recovers until it freezes, then the fallback
    late = plan(cell, A, B, StrivingParams(fallback=True, handover_after=0), world=world)
    assert late.status == "reached" and any(e.startswith(f"step {alone.n_steps}: Striving frozen") for e in late.events)


def test_the_fallback_keeps_strivings_joint_step_bound():
    """StrivingParams(max_joint_step=10 deg, fallback=True): the whole returned path keeps 10 deg
    per step (the fallback's own default is 20 deg; before, such plans had 13.5 deg steps)."""
    from planner_checks import check_plan_valid

    from dualpuma import StrivingParams, plan
    from dualpuma.scenarios import random_problems

    bound = math.radians(10.0)
    pr = random_problems(7, seed=3, max_obstacles=4)[6]
    world = World(pr.cell)
    p = plan(pr.cell, pr.start, pr.goal, StrivingParams(fallback=True, max_joint_step=bound), world=world)
    assert p.status == "reached" and p.planner == "striving+rrt", p.reason
    Q = np.hstack([p.q_left, p.q_right])
    assert np.abs(np.diff(Q, axis=0)).max() <= bound + 1e-12
    check_plan_valid(world, p, margin=pr.cell.safety_margin, max_joint_step=bound)


def test_trees_meeting_at_the_goal_add_no_repeated_row():
    """A random problem (found by the certified-motion property) where the start tree reaches the
    goal pose and the goal tree's root is joined to it by a zero-length edge: the path had its last
    row twice, and timing it failed inside toppra. Every step now moves, and the plan is timed."""
    from dualpuma import StrivingParams, example_cell, plan
    from dualpuma.planning import time_plan
    from dualpuma.scenarios import random_problem

    prob = random_problem(279, max_obstacles=4, base=example_cell("default"))
    world = World(prob.cell)
    params = StrivingParams(step=0.05, rot_step=math.radians(2.0), substeps=1, max_joint_step=math.radians(10.0),
                            alternates=(), max_recoveries=20, fallback=True,
                            fallback_params=FallbackParams(max_iterations=300, shortcut_iterations=20))
    p = plan(prob.cell, prob.start, prob.goal, params, world=world)
    assert p.status == "reached" and p.planner == "striving+rrt", p.reason
    moved = np.maximum(np.abs(np.diff(p.T_world_object, axis=0)).max(axis=(1, 2)),
                       np.abs(np.diff(np.hstack([p.q_left, p.q_right]), axis=0)).max(axis=1))
    assert moved.min() > 1e-9
    assert time_plan(p, world).certified
