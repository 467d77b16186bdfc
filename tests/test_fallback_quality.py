"""Fallback path quality (issue 13, item 5): the whole returned path is smoothed — Striving's
wandering prefix included — and stays certified (independent reference at 20 joint-linear
sub-poses per step)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from motion_reference import MotionReference

from dualpuma import Cell, StrivingParams, World, plan
from dualpuma.model import Obstacle


def _pose(yaw_cos, yaw_sin, p):
    T = np.eye(4)
    T[:2, :2] = [[yaw_cos, -yaw_sin], [yaw_sin, yaw_cos]]
    T[:3, 3] = p
    return T


def _overhang():
    """Routine 8's slab and post, moved and turned (hard set problem overhang-4): Striving's seed
    alternates wander around the slab for 20 steps before the fallback takes over."""
    slab = Obstacle("slab", "box", [0.32, 0.08, 0.22],
                    _pose(0.9922314787103635, -0.1244053562200816, (1.7617009153786085, -0.48271629033668667, 0.4152314682138549)))
    post = Obstacle("post", "box", [0.19, 0.08, 0.33],
                    _pose(0.9959594367111378, 0.0898042338981461, (1.7795472746591963, -0.4924316880673294, 0.165)))
    cell = dataclasses.replace(Cell.default(), obstacles=(slab, post))
    A = cell.T_world_object_start
    B = A.copy()
    B[:3, 3] = (1.5626001333624198, -0.23178530363748473, 0.5129983072254353)
    return cell, A, B


def test_whole_path_is_smoothed_and_certified():
    cell, A, B = _overhang()
    world = World(cell)
    p = plan(cell, A, B, StrivingParams(fallback=True), world=world)
    assert p.reached and p.planner == "striving+rrt"
    assert any("took AP" in e for e in p.events)  # Striving did wander before the fallback
    straight = float(np.linalg.norm(B[:3, 3] - A[:3, 3]))
    assert p.path_length <= 1.15 * straight, (p.path_length, straight)  # the prefix's detour is gone
    ref = MotionReference(cell)
    Q = np.hstack([p.q_left, p.q_right])
    for i in range(p.n_steps):
        for s in np.linspace(0.0, 1.0, 21):
            q = Q[i] + s * (Q[i + 1] - Q[i])
            assert ref.clearance(q[:6], q[6:], float(p.t[i]), 0.02)[0] >= 0.02 - 1e-6


def test_a_shortcut_shorter_by_less_than_the_minimum_gain_is_not_tried(monkeypatch):
    """A path with a kink 5.5 mm to the side of its straight line: the straight shortcut shortens it
    by about 0.5 mm (computed here from the poses). With the default ``min_shortcut_gain`` (1 mm)
    it is not tried (no edge is validated); with 0.1 mm it is, and the path becomes the straight one."""
    from dualpuma.kinematics.dual import solve_dual
    from dualpuma.planning import FallbackParams, edges
    from dualpuma.planning.edges import EdgeChecker
    from dualpuma.planning.smoothing import try_shortcut, verify

    cell = Cell.default()
    world = World(cell)
    A = cell.T_world_object_start
    M, B = A.copy(), A.copy()
    M[:3, 3] += (0.0, 0.0055, 0.06)
    B[:3, 3] += (0.0, 0.0, 0.12)
    home = (np.asarray(cell.left.q_home, float), np.asarray(cell.right.q_home, float))
    start = solve_dual(world, A, home)
    assert start.ok, start.reason
    q0 = (start.q_left, start.q_right)
    gain = 2 * np.linalg.norm(M[:3, 3] - A[:3, 3]) - np.linalg.norm(B[:3, 3] - A[:3, 3])
    assert 0.0004 < gain < 0.0006
    tried: list[int] = []
    real = edges.EdgeChecker.edge

    def counted(self, *a, **k):
        tried.append(1)
        return real(self, *a, **k)

    monkeypatch.setattr(edges.EdgeChecker, "edge", counted)
    for min_gain, expect in ((FallbackParams().min_shortcut_gain, False), (0.0001, True)):
        ctx = EdgeChecker(world, FallbackParams(min_shortcut_gain=min_gain), A, 0.0, 0.0)
        path, why = verify(ctx, [(A, 0), (M, 2), (B, 2)], q0, start.clearance)
        assert path is not None, why
        tried.clear()
        short = try_shortcut(ctx, path, 0, path.P.shape[0] - 1)
        assert bool(tried) == expect and (short is not None) == expect
        if short is not None:
            assert float(short.seg.sum()) == pytest.approx(float(path.seg.sum()) - gain, abs=1e-9)


def test_lazy_smoothing_certifies_the_final_path_and_redoes_eagerly_where_that_fails(monkeypatch):
    """Smoothing certifies the shortcuts' motion lazily, once, in the final verification. On the hard
    set's slot-3 (rng 0) that verification refuses the lazily smoothed path (a shortcut kept whose
    motion between rows is not certified), so smoothing is done again with every shortcut certified
    as it is made: the plan is exactly the one eager smoothing gives, and the bar's path between its
    rows keeps the margin by the independent reference (both arms tracked with Pinocchio alone)."""
    import functools
    from pathlib import Path

    from dualpuma.planning import smoothing, striving
    from dualpuma.scenarios.hard import GENERAL_PARAMS, problems_from_json

    fixture = Path(__file__).parents[1] / "benchmarks" / "fixtures" / "hard_set.json"
    p = next(x for x in problems_from_json(fixture.read_text()) if x.tag == "slot-3")
    outcomes: list[bool] = []  # the final verifications inside smooth: did each certify its path?
    real_verify = smoothing.verify

    def spied(*a, **k):
        path, why = real_verify(*a, **k)
        outcomes.append(path is not None)
        return path, why

    monkeypatch.setattr(smoothing, "verify", spied)
    plans = {}
    for lazy in (True, False):
        monkeypatch.setattr(striving, "smooth", functools.partial(smoothing.smooth, lazy=lazy))
        outcomes.clear()
        plans[lazy] = plan(p.cell, p.start, p.goal, GENERAL_PARAMS, q_start=p.q_start, world=World(p.cell), rng=0)
        assert plans[lazy].reached and any(e.startswith("smoothed") for e in plans[lazy].events)
        assert outcomes == ([False, True] if lazy else [True]), (lazy, outcomes)
    assert np.array_equal(plans[True].q_left, plans[False].q_left)
    assert np.array_equal(plans[True].q_right, plans[False].q_right)
    assert np.array_equal(plans[True].T_world_object, plans[False].T_world_object)
    d, pair, step, s = MotionReference(p.cell).plan_path_min(plans[True], 0.02)
    assert d >= 0.02 - 1e-9, (d, pair, step, s)
