"""Coordination benchmarks (group "coordination") on Cell.default().

* ``solve_dual`` for one object pose, with and without the clearance query;
* ``solve_path`` on a 100-pose path (vectorised IK), against the baseline of the same path solved
  pose by pose with ``solve_dual`` in a Python loop (the ratio is the figure);
* the closed-chain check of each result (both hands reach ``T_world_object @ T_object_hand``).

Run: .venv/bin/python -m pytest --benchmark-only -q benchmarks/bench_coordination.py
"""

import numpy as np
import pytest

from dualpuma import Cell, World, puma
from dualpuma.kinematics import solve_dual, solve_path
from dualpuma.planning import interpolate_object

CELL = Cell.default()
WORLD = World(CELL)
Q0 = (CELL.left.q_home, CELL.right.q_home)
T0 = CELL.T_world_object_start
T1 = T0.copy()
T1[:3, 3] += (-0.01, 0.0, 0.005)  # one 11 mm step from the start
T_GOAL = T0.copy()
T_GOAL[:3, 3] += (-0.2, 0.0, 0.1)  # 224 mm in 100 steps of 2.2 mm
PATH = interpolate_object(T0, T_GOAL, 100)


def _closed_chain(T_world_object, q_left, q_right) -> float:
    """Largest deviation of both hands from their grasp targets (closed-form FK) [m or rad-ish]."""
    err = 0.0
    for side, q in (("left", q_left), ("right", q_right)):
        target = T_world_object @ getattr(CELL, f"grasp_{side}").T_object_hand
        err = max(err, float(np.max(np.abs(getattr(CELL, side).T_world_base @ puma.fk(q) - target))))
    return err


@pytest.mark.benchmark(group="coordination")
@pytest.mark.parametrize("clearance", [False, True], ids=["no_clearance", "clearance"])
def test_solve_dual_per_pose(benchmark, clearance):
    sol = benchmark(solve_dual, WORLD, T1, Q0, check_clearance=clearance)
    assert sol.ok and _closed_chain(T1, sol.q_left, sol.q_right) < 1e-9
    assert np.isfinite(sol.clearance) == clearance


@pytest.mark.benchmark(group="coordination")
def test_solve_path_100_poses(benchmark):
    sol = benchmark(solve_path, WORLD, PATH, Q0)
    assert sol.n_ok == 100
    assert max(_closed_chain(T, a, b) for T, a, b in zip(PATH, sol.q_left, sol.q_right)) < 1e-9


@pytest.mark.benchmark(group="coordination")
def test_solve_dual_loop_100_poses_baseline(benchmark):
    """Baseline for solve_path: the same 100 poses, one solve_dual call each (no clearance)."""

    def loop():
        q = Q0
        out = []
        for T in PATH:
            s = solve_dual(WORLD, T, q, check_clearance=False)
            if not s.ok:
                break
            q = (s.q_left, s.q_right)
            out.append(q)
        return out

    qs = benchmark(loop)
    assert len(qs) == 100
    ref = solve_path(WORLD, PATH, Q0)
    np.testing.assert_allclose(np.array([q[0] for q in qs]), ref.q_left, atol=1e-9)
    np.testing.assert_allclose(np.array([q[1] for q in qs]), ref.q_right, atol=1e-9)
