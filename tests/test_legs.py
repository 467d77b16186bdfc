"""Time across chained legs (issue 13, item 3): plan(t_start=...) places moving obstacles at the
plan's real times, and chained callers (run_legs / run_routine) pass the elapsed time on. Checked
with the scalar coal query at each row's own time."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dualpuma import Cell, StrivingParams, World, plan
from dualpuma.errors import ParameterError
from dualpuma.model import Obstacle
from dualpuma.planning import chain, time_plan, with_trajectory
from dualpuma.scenarios import run_legs


@pytest.fixture(scope="module")
def crossing():
    """A ball that is far from the bar during the first leg (t <= 0.2 s) and arrives (t = 0.3 s)
    where the second leg takes the bar: up 100 mm, then 100 mm along -y."""
    c0 = Cell.default()
    A = c0.T_world_object_start
    T = np.eye(4)
    T[:3, 3] = (1.886, -0.9, 0.207)
    ball = Obstacle("ball", "sphere", [0.05], T, velocity=(0.0, 2.0, 0.0), t_start=0.0, t_end=0.3)
    cell = dataclasses.replace(c0, obstacles=(ball,))
    B1 = A.copy()
    B1[:3, 3] += (0.0, 0.0, 0.1)
    B2 = B1.copy()
    B2[:3, 3] += (0.0, -0.1, 0.0)
    return cell, World(cell), A, B1, B2


def _clearance_at_own_times(world, p):
    return np.array([world.clearance(p.q_left[i], p.q_right[i], p.T_world_object[i], float(p.t[i])).distance
                     for i in range(p.t.shape[0])])


def test_second_leg_sees_the_ball_at_its_real_times(crossing):
    cell, world, A, B1, B2 = crossing
    params = StrivingParams(alternates=())
    p = run_legs(cell, A, [(B1, None), (B2, None)], params, world=world)
    np.testing.assert_allclose(p.t, 0.1 * np.arange(p.t.shape[0]), atol=1e-12)
    d = _clearance_at_own_times(world, p)
    assert d.min() >= cell.safety_margin - 1e-9, d
    assert not p.reached and "obstacle/ball" in p.reason  # the ball blocks the second leg
    # the same legs planned each from t = 0 (the old behaviour) report success ...
    l1 = plan(cell, A, B1, params, world=world)
    l2 = plan(cell, B1, B2, params, q_start=(l1.q_left[-1], l1.q_right[-1]), world=world)
    old = chain(l1, l2)
    assert old.reached and old.min_clearance >= cell.safety_margin
    assert any("planned from t = 0" in e for e in old.events)
    # ... but at their real times the bar is inside the ball
    assert _clearance_at_own_times(world, old).min() < 0.0


def test_t_start_shifts_the_plan_times(crossing):
    cell, world, A, B1, _ = crossing
    p = plan(cell, A, B1, t_start=1.5, world=world)
    assert p.reached
    np.testing.assert_allclose(p.t, 1.5 + 0.1 * np.arange(p.t.shape[0]), atol=1e-12)
    # at t >= 0.3 s the ball waits at y = -0.3 m: far from this leg
    assert _clearance_at_own_times(world, p).min() >= cell.safety_margin


def test_chain_keeps_times_and_refuses_a_gap(crossing):
    cell, world, A, B1, B2 = crossing
    l1 = plan(cell, A, B1, world=world)
    l2 = plan(cell, B1, B2, StrivingParams(alternates=()), q_start=(l1.q_left[-1], l1.q_right[-1]),
              world=world, t_start=float(l1.t[-1]))
    both = chain(l1, l2)
    np.testing.assert_array_equal(both.t, np.concatenate([l1.t, l2.t[1:]]))
    late = plan(cell, B1, B2, q_start=(l1.q_left[-1], l1.q_right[-1]), world=world, t_start=5.0)
    with pytest.raises(ParameterError):
        chain(l1, late)


@pytest.fixture(scope="module")
def rising():
    """A 40 mm ball rising at 0.5 m/s from t = 1 s through where the second leg takes the bar (up
    100 mm, then 100 mm along -y): the first leg's plan clock ends at 0.2 s, its timed motion at
    about 1.2 s."""
    c0 = Cell.default()
    A = c0.T_world_object_start
    B1 = A.copy()
    B1[:3, 3] += (0.0, 0.0, 0.1)
    B2 = B1.copy()
    B2[:3, 3] += (0.0, -0.1, 0.0)
    T = np.eye(4)
    T[:3, 3] = (1.886, -0.36, -0.293)
    ball = Obstacle("ball", "sphere", [0.04], T, velocity=(0.0, 0.0, 0.5), t_start=1.0, t_end=2.6)
    cell = dataclasses.replace(c0, obstacles=(ball,))
    world = World(cell)
    l1 = plan(cell, A, B1, world=world)
    l2 = plan(cell, B1, B2, q_start=(l1.q_left[-1], l1.q_right[-1]), t_start=float(l1.t[-1]), world=world)
    assert l1.reached and l2.reached
    return cell, world, l1, l2


def _timed_clearance(world, tr, sub=4):
    """Scalar coal clearance of a trajectory at its samples and at ``sub - 1`` joint-linear points
    between consecutive samples, each at its own time (the bar where the left hand holds it)."""
    Q = np.hstack([tr.q_left, tr.q_right])
    s = np.arange(sub) / sub
    Qs = (Q[:-1, None] + s[None, :, None] * (Q[1:] - Q[:-1])[:, None]).reshape(-1, 12)
    ts = (tr.t[:-1, None] + s[None] * np.diff(tr.t)[:, None]).ravel()
    Qs, ts = np.vstack([Qs, Q[-1:]]), np.append(ts, tr.t[-1])
    return np.array([world.clearance(q[:6], q[6:], None, float(t)).distance for q, t in zip(Qs, ts)])


def test_legs_timed_one_after_the_other_keep_the_margin(rising):
    """Each leg timed on its own plan clock overlaps the first's motion in time (leg 2 'starts' at
    0.2 s, leg 1 ends at ~1.2 s); run back to back, the bar entered the rising ball. Timed from
    when the previous trajectory ends (t_start), leg 2 meets the ball at its real times."""
    cell, world, l1, l2 = rising
    tr1 = time_plan(l1, world)
    own = time_plan(l2, world)
    assert own.t[0] == pytest.approx(l2.t[0]) and own.t[0] < tr1.t[-1]  # the plan's clock: overlapping
    assert _timed_clearance(world, dataclasses.replace(own, t=own.t + (tr1.t[-1] - own.t[0]))).min() < 0.0
    tr2 = time_plan(l2, world, t_start=float(tr1.t[-1]))
    assert tr2.t[0] == tr1.t[-1]
    assert tr1.certified and tr2.certified
    assert _timed_clearance(world, tr2).min() >= cell.safety_margin - 1e-9
    with pytest.raises(ParameterError, match="starts at its first time"):
        with_trajectory(l2, world, t_start=float(tr1.t[-1]))
    # or chain the plans first and time them once
    both = time_plan(chain(l1, l2), world)
    assert both.certified and _timed_clearance(world, both).min() >= cell.safety_margin - 1e-9


@pytest.mark.parametrize("t_start", [-1.0, 1e17, float("nan"), float("inf")])
def test_start_times_outside_the_range_are_refused(crossing, t_start):
    cell, world, A, B1, _ = crossing
    p = plan(cell, A, B1, t_start=t_start, world=world)
    assert p.status == "invalid_input" and "t_start" in p.reason
    ok = plan(cell, A, B1, world=world)
    with pytest.raises(ParameterError, match="t_start"):
        time_plan(ok, world, t_start=t_start)


def _default_and_goals(*offsets):
    """The default cell, its World, its start pose and the start moved by each offset [m]."""
    cell = Cell.default()
    A = cell.T_world_object_start
    goals = []
    for d in offsets:
        G = A.copy()
        G[:3, 3] += d
        goals.append(G)
    return cell, World(cell), A, goals


def test_a_chained_plan_keeps_the_margin_its_legs_kept():
    """chain() dropped meta: a chain planned with a 30 mm margin was timed against the cell's 20 mm."""
    cell, world, A, (B0, B1) = _default_and_goals((0.0, 0.0, 0.05), (0.0, -0.05, 0.05))
    p = run_legs(cell, A, [(B0, None), (B1, None)], StrivingParams(margin=0.03), world=world)
    assert p.reached and p.meta["margin"] == 0.03
    l1 = plan(cell, A, B0, StrivingParams(margin=0.03), world=world)
    l2 = plan(cell, B0, B1, StrivingParams(margin=0.025), q_start=(l1.q_left[-1], l1.q_right[-1]), world=world,
              t_start=float(l1.t[-1]))
    assert chain(l1, l2).meta == {"margin": 0.025}
    assert chain(l1, dataclasses.replace(l2, meta={})).meta == {}


def test_a_chain_whose_last_leg_failed_is_timed_up_to_where_it_stopped():
    """run_legs chains the failed leg: the chained plan's status is the last leg's (invalid_goal)
    while its rows move the bar through the first leg; it is timed, as a frozen plan is."""
    cell, world, A, (B0, far) = _default_and_goals((0.0, 0.0, 0.05), (5.0, 0.0, 0.0))
    p = run_legs(cell, A, [(B0, None), (far, None)], world=world)
    assert p.status == "invalid_goal" and p.T_world_object.shape[0] > 1
    tr = time_plan(p, world)
    assert tr.certified and tr.duration > 0.0
    np.testing.assert_allclose(tr.q_left[-1], p.q_left[-1], atol=1e-12)
