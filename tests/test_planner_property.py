"""Property: in random obstacle fields every plan's steps — and 5x finer poses between them — are
permitted, keep the grasp, and a reached plan starts and ends at the given poses."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from planner_checks import check_plan_valid

from dualpuma import World, plan
from dualpuma.scenarios import random_problem

_seen: dict[str, int] = {}


@settings(max_examples=100, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(min_value=0, max_value=2**32 - 1))
def test_every_step_permitted(seed):
    prob = random_problem(seed, max_obstacles=4)
    w = World(prob.cell)
    p = plan(prob.cell, prob.start, prob.goal, world=w)
    _seen[p.status] = _seen.get(p.status, 0) + 1
    assert p.status in ("reached", "frozen", "invalid_goal")
    np.testing.assert_array_equal(p.T_world_object[0], prob.start)
    check_plan_valid(w, p, margin=prob.cell.safety_margin, fine=5)
    if p.reached:
        np.testing.assert_allclose(p.T_world_object[-1], prob.goal, atol=1e-12)
    else:
        assert p.reason


def test_property_sample_covered_outcomes():
    """Guard against a vacuous property: the sample above must include reached and frozen plans."""
    assert _seen.get("reached", 0) >= 5 and _seen.get("frozen", 0) >= 1, _seen
