"""The held-bar screen (collision.held): upper bounds of the bar's clearance to the fixed geometry
from object poses alone, checked against coal (the bar placed by the object pose, one query per
pair), and its use by the fallback's edge checker: a whole edge whose bar certainly comes closer
than the margin is refused before any IK, and every edge it refuses, the full validation refuses
too."""

from __future__ import annotations

import re

import coal
import numpy as np
import pinocchio as pin
import pytest
from motion_reference import MotionReference
from planner_checks import count_edge_ik, rising_into_a_ball
from test_kernel import CELLS as KERNEL_CELLS

from dualpuma import Cell, World
from dualpuma.collision.held import held_screen
from dualpuma.kinematics.dual import solve_dual
from dualpuma.lie import slerp
from dualpuma.planning import FallbackParams
from dualpuma.planning.edges import EdgeChecker
from dualpuma.scenarios import slot_field_cell

CELLS = {**KERNEL_CELLS, "slot_field": slot_field_cell()[0]}  # moving obstacles, capsule and sphere bars, UR5 arms


def _poses(cell: Cell, rng: np.random.Generator, n: int) -> np.ndarray:
    """Object poses scattered over the cell: about the start and about each obstacle, any orientation."""
    centres = [cell.T_world_object_start[:3, 3]] + [o.T_world_obstacle[:3, 3] for o in cell.obstacles]
    P = np.tile(np.eye(4), (n, 1, 1))
    P[:, :3, 3] = np.array(centres)[rng.integers(0, len(centres), n)] + rng.normal(0.0, 0.25, (n, 3))
    P[:, :3, :3] = [pin.rpy.rpyToMatrix(*r) for r in rng.uniform(-np.pi, np.pi, (n, 3))]
    return P


def _coal_bar_distance(world: World, pair: int, T_world_object: np.ndarray) -> float:
    """coal's signed distance of one pair of the bar with a fixed geometry, the bar placed by the object pose."""
    gm, bar = world.geom_model, world.bar_id
    a, b = (int(v) for v in world.pair_ids[pair])
    other = gm.geometryObjects[b if a == bar else a]
    M = T_world_object @ np.asarray(world.T_object_bar)
    return float(coal.distance(gm.geometryObjects[bar].geometry, coal.Transform3s(M[:3, :3].copy(), M[:3, 3].copy()),
                               other.geometry, coal.Transform3s(other.placement.rotation, other.placement.translation),
                               coal.DistanceRequest(), coal.DistanceResult()))


@pytest.mark.parametrize("name", list(CELLS))
def test_the_screen_bounds_the_bar_pairs_with_static_geometry(name):
    """Its pairs are exactly the bar's pairs with a geometry on the universe joint that is not a
    moving obstacle; every bound is at least coal's distance where they are apart, and a bound
    below the margin means coal's distance is below it too."""
    cell = CELLS[name]
    world = World(cell)
    screen = held_screen(world)
    gm, bar = world.geom_model, world.bar_id
    moving = {gid for gid, _ in world.moving}
    expected = [k for k, (a, b) in enumerate(world.pair_ids) if bar in (a, b)
                and gm.geometryObjects[b if a == bar else a].parentJoint == 0 and (b if a == bar else a) not in moving]
    assert sorted(screen.pairs.tolist()) == expected and expected
    rng = np.random.default_rng(7)
    P = _poses(cell, rng, 150)
    ub = screen.bounds(P)
    margin = cell.safety_margin
    below = 0
    for g, k in enumerate(screen.pairs.tolist()):
        for i in range(P.shape[0]):
            d = _coal_bar_distance(world, k, P[i])
            if d >= 0.0:
                assert ub[g, i] >= d - 1e-6, (name, world.pair_names[k], i, ub[g, i], d)  # coal's GJK tolerance
            if ub[g, i] < margin:
                below += 1
                assert d < margin, (name, world.pair_names[k], i, ub[g, i], d)
    assert below > 20  # the poses do come close: the checks above are not vacuous


def test_a_box_bar_is_bounded_tightly_against_boxes():
    """Against box obstacles the box bar's bound is within a few millimetres of coal's distance
    (its edges' points): of the poses coal puts more than 5 mm inside the margin, the screen
    refuses nearly all."""
    cell = CELLS["slot_field"]
    world = World(cell)
    screen = held_screen(world)
    P = _poses(cell, np.random.default_rng(3), 300)
    ub = screen.bounds(P)
    boxes = [g for g, k in enumerate(screen.pairs.tolist()) if world.pair_names[k][1].startswith("obstacle/")]
    clear, caught, gaps = 0, 0, []
    for g in boxes:
        for i in range(P.shape[0]):
            d = _coal_bar_distance(world, int(screen.pairs[g]), P[i])
            if 0.0 <= d < 0.2:
                gaps.append(ub[g, i] - d)
            if d < cell.safety_margin - 0.005:
                clear += 1
                caught += ub[g, i] < cell.safety_margin
    assert clear > 20 and caught >= 0.9 * clear, (caught, clear)
    assert np.median(gaps) < 0.002 and max(gaps) < 0.03, (np.median(gaps), max(gaps))


def test_a_whole_edge_whose_bar_meets_an_obstacle_is_refused_before_any_ik(monkeypatch):
    """The bar rises into a ball: taken whole, the edge is refused without one IK call, for the
    first output pose whose bound is below the margin; the independent reference puts that pose
    below the margin. Taken as a prefix, the edge is solved up to that pose (the screen cuts off
    the rest) and stops short of the ball, no later than that pose."""
    cell, A, B, start = rising_into_a_ball(0.06)
    world, margin = World(cell), cell.safety_margin
    q0 = (start.q_left, start.q_right)
    ctx = EdgeChecker(world, FallbackParams(), A, 0.0, 0.0)
    ik_calls = count_edge_ik(monkeypatch)
    n = ctx.n_out(A, B)
    run, used = ctx.edge(A, q0, B, 0.0, d_a=start.clearance, whole=True)
    assert not ik_calls and used == n and run.m == 0
    assert run.why == "clearance bar – obstacle/ball" and "at most" in run.reason, run.reason
    k = int(re.match(r"output step (\d+):", run.reason).group(1))
    T_k = slerp(A, B, np.array([k / n]))[0]
    sol = solve_dual(world, T_k, q0, max_step=np.pi, check_clearance=False)
    assert sol.q_left is not None and sol.q_right is not None
    assert MotionReference(cell).clearance(sol.q_left, sol.q_right, 0.0, margin)[0] < margin
    prefix, m_out = ctx.edge(A, q0, B, 0.0, d_a=start.clearance)
    assert ik_calls and 0 < prefix.m < m_out and prefix.why == "clearance bar – obstacle/ball"
    assert prefix.m / m_out < k / n  # the exact clearance stops it no later than the bound did


def _random_edges(seed: int, count: int = 60):
    """Edges from the snaking slot field's start to random poses turned by up to ~0.3 rad:
    ``(checker, start joints, start solution, fine poses P, their times, output steps n)``."""
    cell, A, _ = slot_field_cell()
    world = World(cell)
    home = (np.asarray(cell.left.q_home, float), np.asarray(cell.right.q_home, float))
    start = solve_dual(world, A, home, max_step=np.pi)
    assert start.ok, start.reason
    q0 = (start.q_left, start.q_right)
    ctx = EdgeChecker(world, FallbackParams(), A, 0.0, 0.0)
    rng = np.random.default_rng(seed)
    for B in _poses(cell, rng, count):
        B[:3, :3] = A[:3, :3] @ pin.rpy.rpyToMatrix(*rng.normal(0.0, 0.3, 3))
        n = ctx.n_out(A, B)
        P = slerp(A, B, np.arange(1, n * ctx.sub + 1) / (n * ctx.sub))
        yield ctx, q0, start, P, np.zeros(P.shape[0]), n


def test_edges_refused_by_the_screen_are_refused_without_it_too():
    """Whole edges between random poses of an obstacle-rich cell: every one the screen refuses is
    refused by the full validation too (the screen only spares the work)."""
    screened = 0
    for ctx, q0, start, P, times, n in _random_edges(11):
        fast = ctx.validate(P, q0, times, (start.clearance, 0.0), whole=True, screen=True)
        full = ctx.validate(P, q0, times, (start.clearance, 0.0), whole=True, screen=False)
        if "at most" in fast.reason:
            screened += 1
            assert fast.m == 0 and full.m < n, (fast.reason, full.reason)
        else:
            assert (fast.m, fast.reason) == (full.m, full.reason)
    assert screened >= 5


def test_a_prefix_cut_at_the_screened_pose_is_the_whole_edges_prefix(monkeypatch):
    """Edges taken as a prefix (the search's extensions) between random poses of an obstacle-rich
    cell: with the screen, only the output steps up to the first pose whose bar is certainly too
    close are solved, and the run is the one the whole edge's validation gives (the same valid
    steps, joints, clearances and reason)."""
    from dualpuma.planning import edges

    solved: list[int] = []
    real = edges.solve_path_unchecked
    monkeypatch.setattr(edges, "solve_path_unchecked", lambda w, P, *a: solved.append(P.shape[0]) or real(w, P, *a))
    cut = 0
    for ctx, q0, start, P, times, _ in _random_edges(12):
        solved.clear()
        fast = ctx.validate(P, q0, times, (start.clearance, 0.0), screen=True)
        asked = sum(solved)
        full = ctx.validate(P, q0, times, (start.clearance, 0.0), screen=False)
        f = fast.m * ctx.sub
        assert (fast.m, fast.reason, fast.why) == (full.m, full.reason, full.why)
        for name in ("qL", "qR", "d", "pair"):
            assert np.array_equal(getattr(fast, name)[:f], getattr(full, name)[:f]), name
        cut += asked < P.shape[0]
    assert cut >= 5


def test_an_extension_refused_at_its_first_pose_is_decided_as_without_the_screen(monkeypatch):
    """The search's extensions in the hard set's slot-0 whose first output pose the screen finds too
    close: only that step's IK is solved. No step is valid, and whether the edge is cut finer (a
    joint step there) is decided as the unscreened validation of that step decides it; the reason
    is the same where the arms fail or a joint steps there, else the screen's clearance of the bar
    (where the unscreened one refuses a clearance or the motion between the poses)."""
    from pathlib import Path

    from dualpuma import plan
    from dualpuma.scenarios.hard import GENERAL_PARAMS, problems_from_json

    probs = problems_from_json((Path(__file__).parents[1] / "benchmarks" / "fixtures" / "hard_set.json").read_text())
    pr = next(p for p in probs if p.tag == "slot-0")
    seen: list[tuple] = []
    real = EdgeChecker.validate

    def spy(self, P, q0, times, start=None, certify=True, whole=False, finer=False, screen=False):
        run = real(self, P, q0, times, start, certify, whole, finer, screen)
        if screen and not whole and len(seen) < 400:
            k = self.held.first_below(P[self.sub - 1 :: self.sub], self.margin - 1e-9)[0]
            if k == 0:
                seen.append((self, P, q0, times, start, run))
        return run

    monkeypatch.setattr(EdgeChecker, "validate", spy)
    p = plan(pr.cell, pr.start, pr.goal, GENERAL_PARAMS, q_start=pr.q_start, world=World(pr.cell))
    monkeypatch.undo()
    assert p.reached and len(seen) >= 100
    kinds = set()
    for ctx, P, q0, times, start, run in seen:
        s = ctx.sub
        full = ctx.validate(P[:s], q0, times[:s], start, certify=False)
        assert run.m == full.m == 0 and run.qL.shape == (0, 6)
        assert (run.why == "joint step") == (full.why == "joint step")
        if "at most" in run.reason:
            kinds.add("screen")
            assert run.why.startswith("clearance bar –"), run.why
            assert full.why.startswith("clearance") or full.why in ("wrist swing", "between poses"), full.why
        else:
            kinds.add(run.why)
            assert (run.reason, run.why, run.ratio) == (full.reason, full.why, full.ratio)
    assert {"screen", "joint step"} <= kinds and len(kinds) >= 3, kinds
