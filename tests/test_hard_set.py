"""The benchmark's hard set (dualpuma.scenarios.hard, benchmarks/fixtures/hard_set.json): it loads,
round-trips, holds every family, and its problems are what they claim — start and goal clear on the
start's branches, the straight run refused."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest
from planner_checks import check_plan_valid

from dualpuma import World, plan
from dualpuma.errors import ParameterError
from dualpuma.kinematics import solve_dual
from dualpuma.scenarios.hard import (
    FAMILIES,
    GENERAL_PARAMS,
    hard_problem,
    problems_from_json,
    problems_to_json,
)

FIXTURE = Path(__file__).parents[1] / "benchmarks" / "fixtures" / "hard_set.json"


@pytest.fixture(scope="module")
def problems():
    return problems_from_json(FIXTURE.read_text())


def test_fixture_loads_and_round_trips(problems):
    assert len(problems) >= 30
    assert {p.tag.split("-")[0] for p in problems} == set(FAMILIES)
    again = problems_from_json(problems_to_json(problems))
    assert [p.tag for p in again] == [p.tag for p in problems]
    with pytest.raises(ParameterError):
        problems_from_json('{"format": "x"}')


@pytest.mark.parametrize("family", FAMILIES)
def test_problems_are_hard_and_clear_at_both_ends(problems, family):
    p = next(x for x in problems if x.tag.startswith(family))
    world = World(p.cell)
    m = p.cell.safety_margin
    assert world.clearance(*p.q_start, p.start).distance >= m
    g = solve_dual(world, p.goal, p.q_start, max_step=2 * math.pi, check_clearance=False)
    assert g.ok and world.clearance(g.q_left, g.q_right, p.goal).distance >= m
    straight = plan(p.cell, p.start, p.goal, dataclasses.replace(GENERAL_PARAMS, fallback=False),
                    q_start=p.q_start, world=world)
    assert straight.status == "frozen"


def test_generator_refuses_unknown_families():
    with pytest.raises(ParameterError):
        hard_problem(0, "tunnel")
    assert hard_problem(1, "overhang") is None or hard_problem(1, "overhang").tag == "overhang"


def test_the_former_slot_family_was_hard_only_for_the_joint_chords():
    """A slot problem of the former family (0.15-0.17 m slots; the hard set's slot-4 until
    2026-11-27): Striving alone reaches the goal with the bar unrotated, 20.4 mm from a lip, and the
    arms holding the bar along its path between the rows keep the margin (each arm tracked with
    Pinocchio alone, 20 poses a step, the independent reference). It was 'frozen' only while the
    planners certified the joint chords between steps, which dip below the margin there; the
    family's slots are now 0.14-0.16 m wide, where the unrotated bar does not pass."""
    from motion_reference import MotionReference

    (p,) = problems_from_json((Path(__file__).parent / "data" / "slot_lip_problem.json").read_text())
    world, m = World(p.cell), p.cell.safety_margin
    straight = plan(p.cell, p.start, p.goal, dataclasses.replace(GENERAL_PARAMS, fallback=False),
                    q_start=p.q_start, world=world)
    assert straight.reached and m <= straight.min_clearance < m + 0.001
    assert MotionReference(p.cell).plan_path_min(straight, m, end_tol=1e-7)[0] >= m - 1e-9


def test_trees_meeting_with_a_wrist_wound_past_its_limits_are_not_joined(problems, monkeypatch):
    """boxes-8: the trees keep meeting where the right wrist has wound a whole turn the other way
    than the goal tree's, and the joined path, re-solved forward from the start, would take q4 or q6
    past its limits further on. Such a meeting is dropped when it is found; before, 284 of them
    were re-verified as whole paths and refused there (1.6 s of the search's 7-10 s). The search is
    otherwise the same (paired over 288 searches: the same paths bit for bit)."""
    from dualpuma.planning import rrt

    p = next(x for x in problems if x.tag == "boxes-8")
    refused: list[str] = []
    real = rrt.verify_run

    def recorded(ctx, way, q0, d0):
        out = real(ctx, way, q0, d0)
        if out[0] is None:
            refused.append(out[1].why)
        return out

    monkeypatch.setattr(rrt, "verify_run", recorded)
    world = World(p.cell)
    r = plan(p.cell, p.start, p.goal, GENERAL_PARAMS, q_start=p.q_start, world=world)
    assert r.reached, r.reason
    assert not [w for w in refused if "joint_limits" in w], refused[:3]
    check_plan_valid(world, r, margin=p.cell.safety_margin, max_joint_step=GENERAL_PARAMS.fallback_params.max_joint_step)
