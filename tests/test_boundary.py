"""The public boundary, case by case: the inputs the issue's fuzz found (and their kind) raise the
typed error that names the argument — never ValueError, TypeError, IndexError, KeyError,
AttributeError, Boost.Python ArgumentError, OverflowError or MemoryError — and silent wrong answers
are refused. (tests/test_fuzz_api.py generates such inputs for every public function.)"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dualpuma import Arm, Cell, StrivingParams, World, fk, ik, ik_all, plan
from dualpuma.collision import (
    ClearanceKernel,
    bar_major_dimension,
    clearance_batch,
    grown_obstacles,
    node_positions,
    node_search,
    object_point_clear,
    twisting,
)
from dualpuma.envelope import (
    contains_ideal,
    contains_real,
    contour_polylines,
    ideal_envelope,
    real_envelope,
    solve_real,
)
from dualpuma.errors import (
    CellError,
    DualpumaError,
    JointError,
    ParameterError,
    PoseError,
    RobotError,
)
from dualpuma.kinematics import continue_branch, hands_from_object, puma, solve_dual, solve_path
from dualpuma.model import Obstacle, cell_from_toml, cell_to_toml, example_cell, seed_units_to_world
from dualpuma.planning import (
    FallbackParams,
    Plan,
    chain,
    interpolate_object,
    orientation_joints,
    plan_many,
    robmov,
)
from dualpuma.scenarios import random_problem, random_problems

C = Cell.default()
W = World(C)
QL, QR = C.left.q_home, C.right.q_home
T0 = C.T_world_object_start
ARM = Arm.puma560()


def raises(error, words, fn, *args, **kwargs):
    with pytest.raises(error) as e:
        fn(*args, **kwargs)
    assert isinstance(e.value, DualpumaError)
    assert words in str(e.value), str(e.value)


@pytest.mark.parametrize("bad", ["abc", {"a": 1}, [[1, 2], [3]], None, {1, 2}, 1 + 2j, [1.0, "a"] * 3,
                                 np.array(["a"] * 6), np.array([object()] * 6, dtype=object),
                                 # numpy reads these as numbers; they were taken as joints (True = 1 rad)
                                 ["0.3", "-0.5", "-0.4", "0.7", "0.5", "-0.2"], [True] * 6, np.ones(6, dtype=bool),
                                 np.array([0.3, "0.5", 1.0, 2.0, 0.0, 1.0], dtype=object),
                                 [0.0, 0.0, 0.0, 0.0, 0.0, True], (0.1, 0.2, np.True_, 0.0, 0.0, 0.0)])
def test_arrays_that_are_not_numbers(bad):
    raises(JointError, "q", fk, bad)
    raises(JointError, "q", W.clearance, bad, QR)
    raises(PoseError, "T", ik_all, bad)
    raises(JointError, "q_left", W.clearance, bad, QR)
    raises(JointError, "q_near", solve_dual, W, T0, (bad, QR))
    raises(ParameterError, "points", contains_ideal, bad, np.zeros(3), np.ones(3), 1.0, 0.5)


def test_the_issues_examples():
    raises(JointError, "config", ik, fk(QL), config=1.0)
    raises(JointError, "q_near", ik, fk(QL), q_near=np.zeros(5))
    raises(JointError, "shape (6,)", W.clearance, np.stack([QL, QL]), np.stack([QR, QR]))  # a batch
    p = plan(None, T0, T0)
    assert p.status == "invalid_input" and "cell" in p.reason
    raises(ParameterError, "margin", StrivingParams, margin="a")
    raises(ParameterError, "substeps", StrivingParams, substeps=10**9)
    raises(ParameterError, "step", StrivingParams, step=10**400)  # an int beyond the float range
    raises(RobotError, "frame", ARM.fk, QL, frame=3)  # was a Boost.Python ArgumentError
    raises(RobotError, "frame", ARM.jacobian, QL, frame={})
    raises(ParameterError, "reach", ideal_envelope, 1e300, 2.5, 1.0)
    for max_step in (math.nan, 0.0, -1.0, math.inf, "0.3"):  # NaN used to disable the jump check
        raises(ParameterError, "max_step", solve_path, W, T0[None], (QL, QR), max_step=max_step)
        raises(ParameterError, "max_step", solve_dual, W, T0, (QL, QR), max_step=max_step)


def test_kinematics_boundary():
    raises(JointError, "shoulder", puma.config_to_branch, np.zeros((3, 3)), 1, 1)
    raises(ParameterError, "reference", ARM.jacobian, QL, reference={})
    raises(ParameterError, "tol", ARM.within_limits, QL, tol="abc")
    raises(ParameterError, "arm", continue_branch, "abc", fk(QL), QL)
    raises(JointError, "q_prev", continue_branch, ARM, fk(QL), [QL, QL])
    raises(ParameterError, "cell", hands_from_object, "abc", T0)
    raises(ParameterError, "world", solve_dual, "abc", T0, (QL, QR))
    raises(ParameterError, "world", solve_path, None, T0[None], (QL, QR))
    raises(ParameterError, "check_clearance", solve_dual, W, T0, (QL, QR), check_clearance=np.zeros(3))
    raises(JointError, "q_start", solve_path, W, T0[None], np.array(1.0))
    raises(JointError, "q_start", solve_path, W, T0[None], [[], [0.0]])


def test_model_boundary():
    raises(CellError, "floor_z", Cell, C.left, C.right, C.bar, C.grasp_left, C.grasp_right, T0, floor_z="a")
    raises(CellError, "safety_margin", Cell, C.left, C.right, C.bar, C.grasp_left, C.grasp_right, T0,
           safety_margin="a")
    raises(CellError, "obstacles", Cell, C.left, C.right, C.bar, C.grasp_left, C.grasp_right, T0, obstacles=None)
    raises(CellError, "obstacles[0]", Cell, C.left, C.right, C.bar, C.grasp_left, C.grasp_right, T0, obstacles=("abc",))
    raises(CellError, "left", Cell, "abc", C.right, C.bar, C.grasp_left, C.grasp_right, T0)
    raises(CellError, "name", Cell, C.left, C.right, C.bar, C.grasp_left, C.grasp_right, T0, name=5)
    raises(CellError, "t_end", Obstacle, "o", "box", [1, 1, 1], np.eye(4), t_end="x")
    raises(CellError, "t_start", Obstacle, "o", "box", [1, 1, 1], np.eye(4), t_start=None)
    raises(CellError, "shape", Obstacle, "o", np.zeros((3, 3)), [1, 1, 1], np.eye(4))
    raises(CellError, "robot", type(C.left), "left", np.zeros(3), np.eye(4))
    raises(ParameterError, "t", Obstacle("o", "box", [1, 1, 1], np.eye(4)).pose_at, "now")
    raises(ParameterError, "per_pair", W.clearance, QL, QR, per_pair=np.zeros(3))
    raises(ParameterError, "margin", W.permitted, QL, QR, margin={})
    raises(ParameterError, "unknown geometry", W.geometry, {})
    raises(ParameterError, "p", seed_units_to_world, "abc")
    raises(CellError, "Cell", cell_to_toml, "abc")
    raises(CellError, "TOML text", cell_from_toml, None)
    raises(CellError, "source", cell_from_toml, "", source=b"x")
    raises(CellError, "unknown name", example_cell, np.zeros(3))


def test_collision_boundary():
    raises(ParameterError, "method", clearance_batch, W, QL, QR, method=np.zeros(3))
    raises(ParameterError, "t", clearance_batch, W, QL, QR, t=[[1, 2], [3]])
    raises(ParameterError, "world", ClearanceKernel, "abc")
    raises(PoseError, "T_world_base", node_positions, None, QL)
    raises(ParameterError, "threshold", node_search, C.left.T_world_base, QL, C.right.T_world_base, QR, threshold="a")
    raises(ParameterError, "cell", bar_major_dimension, "abc")
    raises(ParameterError, "t", grown_obstacles, C, t=None)
    raises(PoseError, "T_world_object", object_point_clear, C, np.zeros((0, 4, 4)))
    raises(ParameterError, "d_prev", twisting, "abc", 0.1, 0.1)
    assert twisting(0.06, 0.05, 0.1) and not twisting(0.04, 0.05, 0.1) and not twisting(math.nan, 0.05, 0.1)  # NaN: no last step


def test_envelope_boundary():
    raises(ParameterError, "cell", contains_real, "abc", np.zeros(3))
    raises(ParameterError, "R_world_object", solve_real, C, np.zeros(3), R_world_object="abc")
    raises(ParameterError, "points", solve_real, C, {"x": 1})
    raises(ParameterError, "resolution", real_envelope, C, 2**64)
    raises(ParameterError, "floor", real_envelope, C, 0.2, floor=np.zeros(3))
    raises(ParameterError, "level", contour_polylines, np.zeros((2, 2)), [0, 1], [0, 1], level="abc")
    raises(ParameterError, "field", contour_polylines, "abc", [0, 1], [0, 1])


def test_planning_boundary():
    raises(ParameterError, "orientation", StrivingParams, orientation=np.zeros(3))
    raises(ParameterError, "goal_bias", FallbackParams, goal_bias="a")
    # a step longer than 25 m would be checked at more than 1000 poses: refused where it is given, not
    # accepted and then an `invalid_input` plan about `substeps`, a field the caller never set
    for P in (StrivingParams, FallbackParams):
        raises(ParameterError, f"{P.__name__}.step: expected a finite number in [0.0001, 25]", P, step=30.0)
        assert P(step=25.0).step == 25.0
    goal = T0.copy()
    goal[:3, 3] += (-0.1, -0.05, 0.05)
    long = plan(C, T0, goal, StrivingParams(step=25.0))
    assert long.status == "reached" and long.n_steps >= 1, long.reason
    assert plan(C, T0, T0, rng="abc").status == "invalid_input"
    raises(ParameterError, "method", interpolate_object, T0, T0, 3, method=np.zeros(3))
    raises(ParameterError, "n", interpolate_object, T0, T0, 10**7)  # 1.28 GB of poses: refused, not a MemoryError
    raises(PoseError, "R", orientation_joints, "abc", 0)
    raises(ParameterError, "branch", orientation_joints, np.eye(3), "abc")
    raises(ParameterError, "max_step", robmov, QL, QR, max_step=1e-300)  # was numpy's "Maximum allowed size exceeded"
    raises(ParameterError, "max_step", robmov, np.full(6, 1e308), np.full(6, -1e308))  # was an OverflowError
    raises(ParameterError, "status", Plan.failed, np.zeros(3), "x")
    raises(ParameterError, "first", chain, "abc", Plan.failed("frozen", "x"))
    raises(ParameterError, "problems", plan_many, None)
    raises(ParameterError, "executor", plan_many, [], executor="abc")
    raises(ParameterError, "T_world_object", Plan, "reached", "", "abc", QL[None], QR[None], np.zeros(1), (("a", "b"),),
           np.zeros(1))
    raises(ParameterError, "pair", Plan, "reached", "", T0[None], QL[None], QR[None], np.zeros(1), 5, np.zeros(1))


def test_scenarios_boundary():
    raises(ParameterError, "rng", random_problem, "abc")
    raises(ParameterError, "rng", random_problem, -1)
    raises(ParameterError, "base", random_problem, 0, base="abc")
    raises(ParameterError, "max_obstacles", random_problem, 0, max_obstacles=1000)  # minutes per problem before
    raises(ParameterError, "seed", random_problems, 1, seed="abc")
    raises(ParameterError, "n", random_problems, 10**6)
