"""Striving planner: validity (independent checks), determinism, I/O, bad input, moving obstacles."""

from __future__ import annotations

import dataclasses
import json
import math
import re

import numpy as np
import pytest
from planner_checks import check_plan_valid

from dualpuma import FallbackParams, Plan, StrivingParams, World, plan
from dualpuma.errors import FileError, ParameterError
from dualpuma.model import Obstacle
from dualpuma.units import display_text


def _shifted(T, dx=0.0, dy=0.0, dz=0.0):
    G = np.array(T, float).copy()
    G[:3, 3] += (dx, dy, dz)
    return G


def test_free_translation_reaches_and_is_valid(cell, world):
    A = cell.T_world_object_start
    # (-0.2, -0.05, 0.15) m (was (-0.2, 0, 0.1)): since self-collision is checked, straight -x from the
    # start brings robot 2's wrist within 15 mm of its own pedestal
    B = _shifted(A, -0.2, -0.05, 0.15)
    p = plan(cell, A, B, world=world)
    assert p.status == "reached" and p.reason == ""
    np.testing.assert_array_equal(p.T_world_object[0], A)
    np.testing.assert_array_equal(p.T_world_object[-1], B)
    steps = np.linalg.norm(np.diff(p.T_world_object[:, :3, 3], axis=0), axis=1)
    assert steps.max() <= 0.05 + 1e-12
    assert p.n_steps == math.ceil(np.linalg.norm([0.2, 0.05, 0.15]) / 0.05)
    assert p.path_length == pytest.approx(np.linalg.norm([0.2, 0.05, 0.15]), abs=1e-12)
    check_plan_valid(world, p, margin=cell.safety_margin)


def test_rotation_steps_bounded(cell, world):
    from dualpuma.lie import rot_to_rpy, rpy_to_rot

    A = cell.T_world_object_start
    B = _shifted(A, -0.1)
    B[:3, :3] = rpy_to_rot(rot_to_rpy(A[:3, :3]) + np.radians([0.0, 0.0, -20.0]))
    p = plan(cell, A, B, world=world)
    assert p.reached
    import pinocchio as pin

    ang = [np.linalg.norm(pin.log3(p.T_world_object[i, :3, :3].T @ p.T_world_object[i + 1, :3, :3])) for i in range(p.n_steps)]
    assert max(ang) <= np.radians(5.0) + 1e-9
    check_plan_valid(world, p, margin=cell.safety_margin)


def test_deterministic_and_pure(cell, world):
    A = cell.T_world_object_start
    B = _shifted(A, -0.15, 0.02, 0.08)
    before = (cell.T_world_object_start.copy(), cell.left.q_home.copy())
    p1 = plan(cell, A, B)
    p2 = plan(cell, A, B, world=world)
    p3 = plan(cell, A, B)
    assert p1.equals(p2) and p1.equals(p3)
    np.testing.assert_array_equal(before[0], cell.T_world_object_start)
    np.testing.assert_array_equal(before[1], cell.left.q_home)


def test_json_and_npz_round_trip(cell, world, tmp_path):
    # (-0.1, -0.05, 0.1) m (was (-0.1, 0, 0.05)): robot 2's wrist vs its own pedestal, see above
    p = plan(cell, cell.T_world_object_start, _shifted(cell.T_world_object_start, -0.1, -0.05, 0.1), world=world)
    q = Plan.from_json(p.to_json())
    assert q.equals(p, ignore_timing=False)
    path = tmp_path / "plan.npz"
    p.save_npz(path)
    assert Plan.load_npz(path).equals(p, ignore_timing=False)
    with pytest.raises(FileError, match="overwrite"):  # a DualpumaError (and an OSError)
        p.save_npz(path)
    p.save_npz(path, overwrite=True)
    d = json.loads(p.to_json())
    assert d["status"] == "reached" and len(d["steps"]) == p.n_steps + 1
    with pytest.raises(ParameterError):
        Plan.from_json("{not json")
    with pytest.raises(ParameterError):
        Plan.from_json(json.dumps({"format": "something else"}))
    d["steps"][0].pop("q_left")
    with pytest.raises(ParameterError):
        Plan.from_dict(d)


@pytest.mark.parametrize(
    "kw",
    [
        {"step": 0.0}, {"step": -1.0}, {"step": float("nan")}, {"rot_step": 0}, {"substeps": 0}, {"substeps": 1.5},
        {"max_steps": 0}, {"margin": -0.1}, {"orientation": "euler"}, {"alternates_from": "goal"},
        {"alternates": ((0.0, 0.0),)}, {"alternates": ((0.0, 0.0, float("inf")),)}, {"min_step": 0.1},
        {"twist_buffer": -1.0}, {"max_recoveries": 0}, {"handover_after": -1}, {"handover_after": 1.5},
    ],
)
def test_bad_params_raise(kw):
    with pytest.raises(ParameterError):
        StrivingParams(**kw)


def test_steps_too_small_to_plan_with_are_refused_not_allocated(cell, world):
    """A step of 1e-9 m made a straight run of 5e8 poses (numpy's MemoryError, 60 GiB): steps
    below 0.1 mm and rotation steps below 0.01 deg are refused, and a run with more than
    MAX_RUN_POSES poses to check (3000 steps x 1000 substeps here) is refused naming what to
    change. At the smallest step the plan runs (and gives up after max_steps: 0.3 m is 3000 steps)."""
    from dualpuma.planning.params import MAX_RUN_POSES, MIN_ROT_STEP, MIN_STEP

    assert (MIN_STEP, math.degrees(MIN_ROT_STEP)) == pytest.approx((1e-4, 0.01))
    for kw, name in (({"step": 1e-9, "min_step": 1e-9}, "StrivingParams.step"), ({"rot_step": 1e-9}, "StrivingParams.rot_step"),
                     ({"min_step": 1e-9}, "StrivingParams.min_step")):
        with pytest.raises(ParameterError, match=re.escape(name) + r": expected a finite number in \[0.0001"
                           if "rot" not in name else re.escape(name) + r": expected a finite number in \[0.000174"):
            StrivingParams(**kw)
    for kw in ({"step": 1e-9}, {"rot_step": 1e-9}):
        with pytest.raises(ParameterError, match="FallbackParams"):
            FallbackParams(**kw)
    A = cell.T_world_object_start
    B = A.copy()
    B[0, 3] -= 0.3
    with pytest.raises(ParameterError, match=r"takes 3000 steps of 1000 checked poses, more than 1,000,000"):
        plan(cell, A, B, StrivingParams(step=1e-4, min_step=1e-4, substeps=1000), world=world)
    assert 3000 * 1000 > MAX_RUN_POSES >= 3000 * 5
    p = plan(cell, A, B, StrivingParams(step=1e-4, min_step=1e-4, max_steps=50), world=world)
    assert p.status == "frozen" and p.reason == "gave up after 50 steps" and 0.0 < p.path_length < 0.3
    steps = np.linalg.norm(np.diff(p.T_world_object[:, :3, 3], axis=0), axis=1)
    assert steps.max() <= 1e-4 + 1e-12  # the rows it made are steps of at most 0.1 mm


def test_bad_input_gives_failed_plans(cell, world):
    A = cell.T_world_object_start
    bad = A.copy()
    bad[0, 3] = np.nan
    p = plan(cell, A, bad, world=world)
    assert p.status == "invalid_input" and "goal" in p.reason
    far = _shifted(A, 0.0, -3.0, 0.0)
    p = plan(cell, A, far, world=world)
    assert p.status == "invalid_goal" and "reach" in p.reason
    wrong = (cell.left.q_home + 0.1, cell.right.q_home)
    p = plan(cell, A, _shifted(A, -0.1), q_start=wrong, world=world)
    assert p.status == "invalid_start" and "grasp" in p.reason
    with pytest.raises(ParameterError):
        plan(cell, A, A, params={"step": 0.05})


def test_start_in_collision_is_invalid_start(cell):
    T = np.eye(4)
    T[:3, 3] = (cell.T_world_object_start @ cell.bar.T_object_bar)[:3, 3]  # the bar's centre
    c = dataclasses.replace(cell, obstacles=(Obstacle("block", "sphere", [0.05], T),))
    p = plan(c, c.T_world_object_start, _shifted(c.T_world_object_start, -0.1))
    assert p.status == "invalid_start" and "obstacle/block" in p.reason


def test_alternates_recover_and_plan_stays_valid(cell):
    """A box in the way: without alternates Striving freezes, with the seed's alternates it gets past."""
    from dualpuma.scenarios import routine

    r = routine(8)
    w = World(r.cell)
    goal = r.legs[0][0]
    frozen = plan(r.cell, r.cell.T_world_object_start, goal, StrivingParams(alternates=()), world=w)
    assert frozen.status == "frozen" and "refused" in frozen.reason
    ok = plan(r.cell, r.cell.T_world_object_start, goal, r.params, world=w)
    assert ok.reached
    assert any("took AP" in e for e in ok.events)
    check_plan_valid(w, ok, margin=r.params.margin)  # routine 8 plans with 10 mm (its deviation)


def test_moving_obstacle_checked_at_each_step_time(cell):
    """An AGV parked on the path blocks it; the same AGV driving away in time lets the bar through."""
    A = cell.T_world_object_start
    # (-0.3, -0.1, 0.1) m and the AGV 50 mm higher (was -0.3 m along x, AGV at z = 0.05 m): straight -x
    # from the start brings robot 2's wrist within 15 mm of its own pedestal (self-collision)
    B = _shifted(A, -0.3, -0.1, 0.1)
    T = np.eye(4)
    T[:3, 3] = (1.25, -0.2, 0.1)  # under the path of the bar's left end
    parked = Obstacle("agv", "box", [0.2, 0.2, 0.1], T)
    leaving = dataclasses.replace(parked, velocity=np.array([0.0, -1.0, 0.0]), t_start=0.0, t_end=2.0)
    p_static = plan(dataclasses.replace(cell, obstacles=(parked,)), A, B, StrivingParams(alternates=()))
    assert p_static.status == "frozen" and "obstacle/agv" in p_static.reason
    c_move = dataclasses.replace(cell, obstacles=(leaving,))
    p = plan(c_move, A, B, StrivingParams(alternates=()))
    assert p.reached
    check_plan_valid(World(c_move), p, margin=cell.safety_margin)
    # and the times matter: the plan's last pose is blocked at t = 0
    d0 = World(c_move).clearance(p.q_left[-1], p.q_right[-1], p.T_world_object[-1], 0.0).distance
    assert d0 < cell.safety_margin


@pytest.mark.parametrize("orientation", ["rpy", "puma", "slerp"])
def test_every_step_turns_at_most_rot_step(cell, world, orientation):
    """Issue 13: in rpy mode the bound applied to each angle, not to the rotation (5.7 deg steps with
    rot_step = 5 deg). Every mode's steps turn by at most rot_step (pinocchio's log3)."""
    import pinocchio as pin

    from dualpuma.lie import rot_to_rpy, rpy_to_rot

    A = cell.T_world_object_start
    r0 = rot_to_rpy(A[:3, :3])
    B = _shifted(A, 0.05, 0.0, 0.1)
    r1 = r0 + np.radians([-10.0, 10.0, 15.0])
    B[:3, :3] = rpy_to_rot(r1)
    kw = {"start_rpy": r0, "goal_rpy": r1} if orientation == "rpy" else {}
    p = plan(cell, A, B, StrivingParams(orientation=orientation, alternates=()), world=world, **kw)
    assert p.reached and p.n_steps >= 3
    ang = [np.linalg.norm(pin.log3(p.T_world_object[i, :3, :3].T @ p.T_world_object[i + 1, :3, :3]))
           for i in range(p.n_steps)]
    assert max(ang) <= np.radians(5.0) + 1e-9, np.degrees(max(ang))


def test_a_start_outside_the_joint_limits_names_the_joint_its_value_and_limits(cell, world):
    """q6 of the left arm one turn further (the same hand pose, outside [-266, 266] deg): the plan
    is ``invalid_start`` and the reason names q6, its value and the limits, read from the URDF by
    Pinocchio (the reason named no joint before)."""
    from pathlib import Path

    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(Path(__file__).resolve().parent.parent / "urdf" / "puma560.urdf"))
    lo, hi = model.lowerPositionLimit[5], model.upperPositionLimit[5]
    qL = np.array(cell.left.q_home, float)
    qL[5] += 2.0 * math.pi
    A = cell.T_world_object_start
    p = plan(cell, A, A, q_start=(qL, cell.right.q_home), world=world)
    assert p.status == "invalid_start"
    assert p.reason == (f"left arm start joints outside the joint limits: q6 = {qL[5]:.4f} rad not in "
                        f"[{lo:.4f}, {hi:.4f}] rad")  # SI in the API (it was in degrees); shown in degrees:
    assert display_text(p.reason).endswith(f"q6 = {math.degrees(qL[5]):.2f} deg not in "
                                           f"[{math.degrees(lo):.2f}, {math.degrees(hi):.2f}] deg")


def test_a_start_a_few_micrometres_off_the_cells_start_is_solved_not_refused(cell, world):
    """The cell's home joints stand for its start pose only at that pose (1e-12 m), not within
    numpy's default relative tolerance (~2e-5 m at x = 1.9 m): a start 5-18 um away was refused as
    invalid_start ("q_start does not hold the bar") though the user gave no q_start."""
    for d in (5e-6, 1.8e-5):
        A = cell.T_world_object_start.copy()
        A[0, 3] += d
        goal = A.copy()
        goal[2, 3] += 0.05
        p = plan(cell, A, goal, world=world)
        assert p.status == "reached", (d, p.reason)
        np.testing.assert_array_equal(p.T_world_object[0], A)
        check_plan_valid(world, p, margin=cell.safety_margin)
