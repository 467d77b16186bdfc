"""Property: in random obstacle fields every plan's steps — and 5x finer poses between them — are
permitted, keep the grasp, and a reached plan starts and ends at the given poses; for the three
pairings (two PUMAs, a PUMA and a UR5, two UR5s: the shipped cells with random obstacles added)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from planner_checks import PROPERTY_RANDOM, PROPERTY_SCALE, check_plan_valid

from dualpuma import World, example_cell, plan
from dualpuma.scenarios import random_problem

_seen: dict[str, dict[str, int]] = {}
PAIRINGS = {"default": 100 * PROPERTY_SCALE, "mixed_puma_ur5": 40 * PROPERTY_SCALE,  # examples per pairing
            "ur5_pair": 40 * PROPERTY_SCALE}


def _property(name: str):
    base = example_cell(name)

    @settings(max_examples=PAIRINGS[name], deadline=None, derandomize=not PROPERTY_RANDOM, database=None,
              suppress_health_check=[HealthCheck.too_slow])
    @given(st.integers(min_value=0, max_value=2**32 - 1))
    def check(seed):
        prob = random_problem(seed, max_obstacles=4, base=base)
        w = World(prob.cell)
        p = plan(prob.cell, prob.start, prob.goal, world=w)
        seen = _seen.setdefault(name, {})
        seen[p.status] = seen.get(p.status, 0) + 1
        assert p.status in ("reached", "frozen", "invalid_goal")
        np.testing.assert_array_equal(p.T_world_object[0], prob.start)
        check_plan_valid(w, p, margin=prob.cell.safety_margin, fine=5)
        if p.reached:
            np.testing.assert_allclose(p.T_world_object[-1], prob.goal, atol=1e-12)
        else:
            assert p.reason

    return check


@pytest.mark.parametrize("name", list(PAIRINGS))
def test_every_step_permitted(name):
    _property(name)()


@pytest.mark.parametrize("name", list(PAIRINGS))
def test_property_sample_covered_outcomes(name):
    """Guard against a vacuous property: each pairing's sample includes reached and frozen plans."""
    seen = _seen.get(name, {})
    assert seen.get("reached", 0) >= 5 and seen.get("frozen", 0) >= 1, seen

