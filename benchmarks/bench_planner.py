"""Planner benchmarks (group "planner"): every routine, a 100-step Striving run, and plan_many on
200 random problems (process pool on this machine's cores). Run: make bench."""

import os

import numpy as np
import pytest

from dualpuma import Cell, StrivingParams, World, plan, plan_many
from dualpuma.scenarios import ROUTINES, random_problems, routine, run_routine


@pytest.mark.benchmark(group="planner")
@pytest.mark.parametrize("n", sorted(ROUTINES))
def test_routine(benchmark, n):
    world = World(routine(n).cell) if n != 1 else None
    p = benchmark(run_routine, n, world=world)
    benchmark.extra_info.update(status=p.status, steps=p.n_steps)
    assert p.status == {1: "limit_exceeded", 6: "frozen"}.get(n, "reached")


@pytest.mark.benchmark(group="planner")
def test_striving_100_steps(benchmark):
    cell = Cell.default()
    world = World(cell)
    A = cell.T_world_object_start
    B = A.copy()
    # 250 mm back, 100 mm up and 50 mm away from the robots: the straight -x motion from the seed's
    # start brings robot 2's wrist within 20 mm of its own pedestal (docs/planner.md, routines 2, 5, 8)
    B[:3, 3] += (-0.25, -0.05, 0.1)
    params = StrivingParams(step=float(np.linalg.norm([0.25, 0.05, 0.1])) / 100, min_step=0.001)
    p = benchmark(plan, cell, A, B, params, world=world)
    assert p.reached and p.n_steps == 100


@pytest.mark.benchmark(group="planner")
def test_plan_many_200_random(benchmark):
    probs = random_problems(200, seed=3)
    out = benchmark.pedantic(plan_many, args=(probs,), kwargs={"progress": False}, rounds=3, iterations=1, warmup_rounds=1)
    assert len(out) == 200 and sum(p.reached for p in out) > 50
    benchmark.extra_info["problems_per_s"] = 200 / benchmark.stats.stats.median
    benchmark.extra_info["workers"] = os.cpu_count()


@pytest.mark.benchmark(group="planner")
def test_routine8_cold(benchmark):
    """Routine 8 as a user calls it: a fresh World and its first plan (run_routine builds it)."""
    p = benchmark.pedantic(run_routine, args=(8,), rounds=15, iterations=1)
    assert p.reached
    benchmark.extra_info["steps"] = p.n_steps


@pytest.mark.benchmark(group="planner")
def test_routine8_warm(benchmark):
    """Routine 8 with a reused World (the figure the routine benchmark above reports)."""
    world = World(routine(8).cell)
    p = benchmark(run_routine, 8, world=world)
    assert p.reached


@pytest.mark.benchmark(group="planner")
def test_time_plan_routine4(benchmark):
    """Timing a plan for execution (toppra, closed chain, certified): routine 4's two legs."""
    from dualpuma.planning import time_plan

    world = World(routine(4).cell)
    p = run_routine(4, world=world)
    time_plan(p, world)  # toppra's import and first call
    tr = benchmark(time_plan, p, world)
    assert tr.certified
    benchmark.extra_info.update(samples=tr.n_samples, duration_s=tr.duration, closure_error_m=tr.closure_error)


@pytest.mark.benchmark(group="planner")
def test_time_plan_on_a_controller_clock(benchmark):
    """The same plan timed on a 250 Hz controller's clock (every sample 4 ms apart: 2.5x the samples
    to check and certify)."""
    from dualpuma.planning import time_plan

    world = World(routine(4).cell)
    p = run_routine(4, world=world)
    time_plan(p, world)  # toppra's import and first call
    tr = benchmark(time_plan, p, world, period=0.004)
    assert tr.certified and tr.period == 0.004
    benchmark.extra_info.update(samples=tr.n_samples, duration_s=tr.duration, closure_error_m=tr.closure_error)


@pytest.mark.benchmark(group="planner")
def test_time_plan_waits_for_a_moving_ball(benchmark):
    """Timing a plan whose fastest timing meets a moving ball (rising through the bar's path at
    t = 0.5..1.0 s): the fastest timing, its refusal, the wait's certification and the candidates
    up to the first certified one (a wait at the start)."""
    from dualpuma.planning import time_plan
    from dualpuma.scenarios import rising_ball_cell

    cell, A, B = rising_ball_cell(0.5, 1.0)
    world = World(cell)
    p = plan(cell, A, B, world=world)
    time_plan(p, world)
    tr = benchmark(time_plan, p, world)
    assert tr.certified and tr.start_delay > 0
    fastest = time_plan(p, world, max_wait=0.0, max_slowdown=1.0)
    assert not fastest.certified
    benchmark.extra_info.update(start_delay_s=tr.start_delay, time_scale=tr.time_scale, duration_s=tr.duration)
