"""Coordination benchmarks (group "coordination"): solve_dual per pose (with and without clearance)
and solve_path on a 100-pose path. Run: make bench."""

import numpy as np
import pytest

from dualpuma import Cell, World
from dualpuma.coordination import solve_dual, solve_path
from dualpuma.paths import interpolate_object

CELL = Cell.default()
WORLD = World(CELL)
Q0 = (CELL.left.q_home, CELL.right.q_home)
T0 = CELL.T_world_object_start
T1 = T0.copy()
T1[:3, 3] += (-0.01, 0.0, 0.005)
PATH = interpolate_object(T0, T0 @ np.diag([1, 1, 1, 1.0]) + np.pad(np.array([[-0.2], [0.0], [0.1]]), ((0, 1), (3, 0))), 100)


@pytest.mark.benchmark(group="coordination")
@pytest.mark.parametrize("clearance", [False, True])
def test_solve_dual_per_pose(benchmark, clearance):
    sol = benchmark(solve_dual, WORLD, T1, Q0, check_clearance=clearance)
    assert sol.ok


@pytest.mark.benchmark(group="coordination")
def test_solve_path_100_poses(benchmark):
    sol = benchmark(solve_path, WORLD, PATH, Q0)
    assert sol.n_ok == 100
