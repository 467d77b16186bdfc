"""Certified edges of the fallback (planning.edges): the plan's memo of certified chords
(``ChordMemo``: a path checked again — the found path, the joined path, the smoothed path — does not
certify the same chord twice, and plans are bit-identical with and without it), an edge whose
joint chords cannot be certified at its default resolution is cut finer instead of refused, and an
edge taken whole is not cut finer past a pose of its path below the margin."""

from __future__ import annotations

import dataclasses
import itertools
import re

import numpy as np
import pytest
from test_fallback_quality import _overhang

from dualpuma import StrivingParams, World, plan
from dualpuma.collision.held import held_screen
from dualpuma.errors import ParameterError
from dualpuma.planning import FallbackParams, edges
from dualpuma.planning.edges import ChordMemo, EdgeChecker
from dualpuma.planning.rrt import rrt_connect
from dualpuma.planning.smoothing import verify


@pytest.fixture(scope="module")
def problem():
    cell, A, B = _overhang()
    return cell, A, B


def _counting(monkeypatch) -> list[int]:
    """Count certify_chords calls (and the chords they cover) made through the edge checker."""
    calls: list[int] = []
    real = edges.certify_chords

    def counted(world, Q, *a, **k):
        calls.append(Q.shape[0] - 1)
        return real(world, Q, *a, **k)

    monkeypatch.setattr(edges, "certify_chords", counted)
    return calls


def test_a_path_verified_twice_is_certified_once(problem, monkeypatch):
    cell, A, B = problem
    world = World(cell)
    p = plan(cell, A, B, StrivingParams(), world=world)  # Striving alone: a certified start and goal joints
    q0 = (p.q_left[0], p.q_right[0])
    res = rrt_connect(world, A, q0, B, FallbackParams(shortcut_iterations=0), 0)
    assert res.ok
    ctx = EdgeChecker(world, FallbackParams(), A, 0.0, 0.0)
    way = [(res.T_world_object[0], 0)] + [(T, 1) for T in res.T_world_object[1:]]
    calls = _counting(monkeypatch)
    first, why = verify(ctx, way, q0, float(res.clearance[0]))
    assert first is not None, why
    n_chords = len(way) - 1
    assert sum(calls) == n_chords  # every chord certified once
    calls.clear()
    second, _ = verify(ctx, way, q0, float(res.clearance[0]))
    assert calls == []  # ... and not again
    for a, b in zip(dataclasses.astuple(first), dataclasses.astuple(second)):
        np.testing.assert_array_equal(a, b)
    # a chord that differs in one joint by a hair is a different chord: certified anew
    moved = [(T.copy(), n) for T, n in way]
    moved[3][0][0, 3] += 1e-7
    calls.clear()
    third, _ = verify(ctx, moved, q0, float(res.clearance[0]))
    assert third is not None and 1 <= sum(calls) <= 4


def test_plans_are_identical_without_the_memo(problem, monkeypatch):
    cell, A, B = problem
    params = StrivingParams(fallback=True, fallback_params=FallbackParams(shortcut_iterations=30))
    with_memo = plan(cell, A, B, params, world=World(cell))
    assert with_memo.reached and with_memo.planner == "striving+rrt"

    class Forgetful(ChordMemo):  # remembers nothing: every chord is certified every time
        def add(self, *a, **k) -> None:
            pass

    monkeypatch.setattr(edges, "ChordMemo", Forgetful)
    from dualpuma.planning import rrt, striving

    monkeypatch.setattr(striving, "ChordMemo", Forgetful)
    monkeypatch.setattr(rrt, "ChordMemo", Forgetful)
    calls = _counting(monkeypatch)
    without = plan(cell, A, B, params, world=World(cell))
    assert calls  # the forgetful run did certify
    for f in ("T_world_object", "q_left", "q_right", "clearance"):
        np.testing.assert_array_equal(getattr(with_memo, f), getattr(without, f))


def test_a_memo_serves_one_world_and_margin(problem):
    cell, A, _ = problem
    memo = ChordMemo()
    EdgeChecker(World(cell), FallbackParams(), A, 0.0, 0.0, memo)
    with pytest.raises(ParameterError, match="one World and margin"):
        EdgeChecker(World(cell), FallbackParams(), A, 0.0, 0.0, memo)
    w = World(cell)
    memo2 = ChordMemo()
    EdgeChecker(w, FallbackParams(), A, 0.0, 0.0, memo2)
    with pytest.raises(ParameterError, match="one World and margin"):
        EdgeChecker(w, FallbackParams(margin=0.03), A, 0.0, 0.0, memo2)


def test_an_edge_is_certified_along_the_bars_path_not_its_joint_chords():
    """A yawed slot (the hard set's slot-4 until 2026-11-27, tests/data/slot_lip_problem.json): at
    its default resolution the straight edge from start to goal has joint-space chords between
    output steps that dip below the margin at the slot's lip (found by an independent dense
    reference), but the arms holding the bar on its straight path, which is what they execute (a
    timed trajectory follows it), keep the margin: a Pinocchio-only tracking of both hands, 20 poses
    per output step, and the same reference. The certificate is about that path, so the edge is
    accepted as it is (it was cut finer until the chords kept the margin before)."""
    from pathlib import Path

    from motion_reference import MotionReference

    from dualpuma.scenarios.hard import problems_from_json

    (p,) = problems_from_json((Path(__file__).parent / "data" / "slot_lip_problem.json").read_text())
    world, ref, margin = World(p.cell), MotionReference(p.cell), p.cell.safety_margin
    ctx = EdgeChecker(world, FallbackParams(), p.start, 0.0, 0.0)
    q0 = tuple(np.asarray(q, float) for q in p.q_start)
    d0 = world.clearance(q0[0], q0[1], p.start).distance

    def lowest(Q) -> float:
        return min(ref.clearance(*np.split(q, 2), 0.0, margin)[0] for q in Q)

    coarse = ctx.n_out(p.start, p.goal)
    run, n = ctx.edge(p.start, q0, p.goal, 0.0, d_a=d0)
    assert n == coarse and run.m == n, run.reason
    rows = np.arange(1, n + 1) * ctx.sub - 1
    Q = np.vstack([np.concatenate(q0), np.hstack([run.qL[rows], run.qR[rows]])])
    chords = [a + s * (b - a) for a, b in itertools.pairwise(Q) for s in np.linspace(0.0, 1.0, 21)]
    assert lowest(chords) < margin  # the joint chords do dip below the margin
    path = ref.bar_path(p.start, p.goal, Q[0], 20 * n)
    np.testing.assert_allclose(path[19::20], Q[1:], atol=1e-7)  # the tracking passes the edge's output steps
    assert lowest(path) >= margin - 1e-9


def test_a_whole_edge_is_not_cut_finer_past_a_pose_below_the_margin(monkeypatch):
    """An edge whose joints move more than ``max_joint_step`` in an output step is cut finer and
    tried again. One taken whole (a shortcut, a connection) whose path further on holds an output
    pose below the margin is refused at once for that pose, after one IK call. Here the bar rises
    0.15 m under a ball. The refusing pose is below the margin by the independent reference. The
    same edge taken as a prefix is still cut finer, and the finer edge stops short of the ball
    too."""
    from motion_reference import MotionReference
    from planner_checks import count_edge_ik, rising_into_a_ball

    from dualpuma.kinematics.dual import solve_dual
    from dualpuma.lie import slerp

    # 12 mm above the bar's top face at the end: the last output poses are below the margin, but
    # not below the bound the held-bar screen has for a ball (its inscribed cube), so the edge does
    # get to the IK
    cell, A, B, start = rising_into_a_ball(0.0895)
    world, margin = World(cell), cell.safety_margin
    assert held_screen(world).first_below(slerp(A, B, np.linspace(0.0, 1.0, 200)), margin)[0] == -1
    q0 = (start.q_left, start.q_right)
    ctx = EdgeChecker(world, FallbackParams(max_joint_step=np.radians(2.0)), A, 0.0, 0.0)
    ik_calls = count_edge_ik(monkeypatch)
    n = ctx.n_out(A, B)
    run, used = ctx.edge(A, q0, B, 0.0, d_a=start.clearance, whole=True)
    assert len(ik_calls) == 1 and used == n  # not cut finer
    assert run.m < n and run.why == "clearance bar – obstacle/ball", run.reason
    k = int(re.match(r"output step (\d+):", run.reason).group(1))
    T_k = slerp(A, B, np.array([k / n]))[0]
    sol = solve_dual(world, T_k, q0, max_step=np.pi, check_clearance=False)
    assert sol.q_left is not None and sol.q_right is not None
    assert MotionReference(cell).clearance(sol.q_left, sol.q_right, 0.0, margin)[0] < margin
    ik_calls.clear()
    prefix, finer = ctx.edge(A, q0, B, 0.0, d_a=start.clearance)
    assert len(ik_calls) > 1 and finer > n  # a prefix is still cut finer for its joint steps ...
    assert prefix.m < finer and prefix.why == "clearance bar – obstacle/ball"  # ... and stops short of the ball
