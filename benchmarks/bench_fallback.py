"""Fallback benchmarks (group "planner"): RRT-Connect in SE(3) on the snaking slot field
(dualpuma.scenarios.slot_field_cell) for a few seeds, the same search without shortcut smoothing,
and — the baseline it falls back from — Striving on the same problem (which freezes at the first
plate). A seed that finds no path in the 5000-iteration budget is timed for the whole budget, and
``extra_info["ok"]`` says so (seed 2 did from self-collision checking until the false wrist crossings
were refused, 2026-11-26; over seeds 0-19, 18 of 20 succeeded either way, and 20 of 20 since the
local sampler of 2026-11-27).

Run: .venv/bin/python -m pytest benchmarks/bench_fallback.py --benchmark-only
"""

import math

import pytest

from dualpuma import StrivingParams, World, plan
from dualpuma.kinematics import solve_dual
from dualpuma.planning import FallbackParams, rrt_connect
from dualpuma.scenarios import slot_field_cell


@pytest.fixture(scope="module")
def slot():
    cell, A, B = slot_field_cell()
    world = World(cell)
    sol = solve_dual(world, A, (cell.left.q_home, cell.right.q_home), max_step=2 * math.pi)
    assert sol.ok, sol.reason
    return cell, world, A, B, (sol.q_left, sol.q_right)


@pytest.mark.benchmark(group="planner")
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fallback_slot_field(benchmark, slot, seed):
    _cell, world, A, B, q0 = slot
    params = FallbackParams()
    res = benchmark.pedantic(rrt_connect, args=(world, A, q0, B, params, seed), rounds=3, iterations=1)
    # the time of a failed search is the time of its whole budget; the outcome goes with the figure
    assert res.ok or res.iterations == params.max_iterations, res.reason
    benchmark.extra_info.update(
        ok=res.ok, iterations=res.iterations, nodes=res.n_nodes, steps=len(res.T_world_object) - 1
    )


@pytest.mark.benchmark(group="planner")
def test_fallback_slot_field_no_smoothing(benchmark, slot):
    _cell, world, A, B, q0 = slot
    params = FallbackParams(shortcut_iterations=0)
    res = benchmark.pedantic(rrt_connect, args=(world, A, q0, B, params, 0), rounds=3, iterations=1)
    assert res.ok, res.reason
    benchmark.extra_info.update(iterations=res.iterations, steps=len(res.T_world_object) - 1)


@pytest.mark.benchmark(group="planner")
def test_striving_slot_field_baseline(benchmark, slot):
    cell, world, A, B, _q0 = slot
    p = benchmark(plan, cell, A, B, StrivingParams(), world=world)
    assert p.status == "frozen"
    benchmark.extra_info["status"] = p.status
