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
from dualpuma.planning import chain
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
