"""Certified motion alone (group "planner"): ``certify_chords`` on 240 random 4-chord paths near
the obstacles of four hard-set problems (boxes, overhang, two slotted plates), every configuration
keeping the margin (joint chords: what ``time_plan`` certifies between samples), and on rows along
straight bar paths in the same cells certified along the bar's path (``closed_chain``: what the
planners certify) and, for the ratio, as joint chords. ``extra_info``: motions, motions certified
and configurations queried (a change of the bounds or the subdivision shows there)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dualpuma import World
from dualpuma.collision import clearance_batch
from dualpuma.planning.certify import certify_chords
from dualpuma.planning.reach import motion_bounds, pair_weights
from dualpuma.scenarios.hard import problems_from_json

FIXTURE = Path(__file__).parent / "fixtures" / "hard_set.json"
MARGIN = 0.02


def _cells():
    """Four hard-set problems (boxes, overhang, two slotted plates): (problem, World, reach, v_max)."""
    probs = {p.tag: p for p in problems_from_json(FIXTURE.read_text())}
    for tag in ("boxes-0", "overhang-3", "slot-0", "slot-6"):
        world = World(probs[tag].cell)
        pair_weights(world)  # built once per World (timed in the routine-8 cold benchmark)
        yield (probs[tag], world, *motion_bounds(world))


@pytest.fixture(scope="module")
def chord_paths():
    rng = np.random.default_rng(0)
    cases = []
    for p, world, reach, v in _cells():
        q0 = np.concatenate(p.q_start)
        n = 0
        while n < 60:
            Q = np.cumsum(np.vstack([q0 + rng.normal(0, 0.12, 12), rng.normal(0, 0.06, (4, 12))]), axis=0)
            d, _ = clearance_batch(world, Q[:, :6], Q[:, 6:], method="coal")
            if d.min() >= MARGIN:
                cases.append((world, Q, d, reach, v))
                n += 1
    return cases


def _certify_all(cases):
    out = [certify_chords(w, Q, d, np.arange(Q.shape[0], dtype=float), MARGIN, r, v) for w, Q, d, r, v in cases]
    return sum(c.n_ok for c in out), sum(c.queries for c in out)


@pytest.mark.benchmark(group="planner")
def test_certify_chords_hard_set_paths(benchmark, chord_paths):
    ok, queries = benchmark(_certify_all, chord_paths)
    benchmark.extra_info.update(chords=4 * len(chord_paths), certified=ok, queries=queries)
    assert 0 < ok < 4 * len(chord_paths)


@pytest.fixture(scope="module")
def bar_paths():
    """Rows 30 mm apart on straight bar paths from four hard-set problems' starts towards their
    goals (and goals moved by up to 60 mm, and 0.15 m-ish in random directions), both arms on their
    branches, up to the first row inside the margin: what the planners certify (the motion between
    rows along the bar's path)."""
    from dualpuma.kinematics import solve_path
    from dualpuma.lie import slerp

    rng = np.random.default_rng(1)
    cases = []
    for p, world, reach, v in _cells():
        for k in range(10):  # towards the goal, towards goals moved by up to 60 mm, and 0.15 m-ish anywhere
            goal = p.goal.copy() if k < 3 else p.start.copy()
            goal[:3, 3] += (rng.uniform(-0.06, 0.06, 3) if k else 0.0) if k < 3 else rng.normal(0, 0.15, 3)
            n = max(2, int(np.ceil(np.linalg.norm(goal[:3, 3] - p.start[:3, 3]) / 0.03)))
            sol = solve_path(world, slerp(p.start, goal, np.arange(1, n + 1) / n), p.q_start, max_step=0.35)
            Q = np.vstack([np.concatenate(p.q_start), np.hstack([sol.q_left, sol.q_right])[: sol.n_ok]])
            d, _ = clearance_batch(world, Q[:, :6], Q[:, 6:], method="coal")
            m = int(np.argmax(d < MARGIN)) if np.any(d < MARGIN) else len(d)
            if m >= 2:
                cases.append((world, Q[:m], d[:m], reach, v))
    return cases


def _certify_bar_paths(cases, closed_chain=True):
    out = [certify_chords(w, Q, d, np.zeros(Q.shape[0]), MARGIN, r, v, closed_chain=closed_chain)
           for w, Q, d, r, v in cases]
    return sum(c.n_ok for c in out), sum(c.queries for c in out)


@pytest.mark.benchmark(group="planner")
def test_certify_bar_paths_hard_set(benchmark, bar_paths):
    ok, queries = benchmark(_certify_bar_paths, bar_paths)
    n = sum(c[1].shape[0] - 1 for c in bar_paths)
    benchmark.extra_info.update(motions=n, certified=ok, queries=queries)
    assert 0 < ok <= n


@pytest.mark.benchmark(group="planner")
def test_certify_bar_paths_hard_set_as_joint_chords(benchmark, bar_paths):
    """The same rows certified as joint chords (what the planners did before 2026-11-27): the cost
    of solving the bar's path at the midpoints is the difference."""
    ok, queries = benchmark(_certify_bar_paths, bar_paths, False)
    benchmark.extra_info.update(motions=sum(c[1].shape[0] - 1 for c in bar_paths), certified=ok, queries=queries)
    assert ok > 0
