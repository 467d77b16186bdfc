"""Lazy certification in the fallback's search (planning.rrt, ``lazy=True``, the default): the
trees' edges are checked at their poses and between them as the search adds them, and their motion
is certified only when a found path uses them (its verification certifies the path as a whole). An
edge that verification refuses is pruned from its tree with every node below it, and the search
goes on; the path returned is certified either way."""

from __future__ import annotations

import numpy as np
import pytest
from test_fallback_quality import _overhang

from dualpuma import StrivingParams, World, plan
from dualpuma.errors import ParameterError
from dualpuma.planning import FallbackParams, edges
from dualpuma.planning.certify import Certificate
from dualpuma.planning.rrt import rrt_connect
from dualpuma.planning.tree import Tree


@pytest.fixture(scope="module")
def problem():
    cell, A, B = _overhang()
    world = World(cell)
    p = plan(cell, A, B, StrivingParams(), world=world)  # Striving alone: certified start joints
    return world, A, B, (p.q_left[0], p.q_right[0])


def _spy_certify(monkeypatch, refuse_at: float | None = None) -> list[int]:
    """Record the chords of every certify_chords call through the edge checker; optionally refuse
    the first call that covers more than three chords (a found path's verification: the lazy search
    certifies no edge of its own) at the chord at fraction ``refuse_at`` of it."""
    calls: list[int] = []
    real = edges.certify_chords

    def spy(world, Q, *a, **k):
        n = Q.shape[0] - 1
        calls.append(n)
        if refuse_at is not None and n > 3 and not any(c > 3 for c in calls[:-1]):
            return Certificate(int(refuse_at * n), "refused by the test", float("nan"), -1, 0)
        return real(world, Q, *a, **k)

    monkeypatch.setattr(edges, "certify_chords", spy)
    return calls


def test_lazy_and_eager_searches_return_the_same_path_when_nothing_is_refused(problem, monkeypatch):
    world, A, B, q0 = problem
    fp = FallbackParams(shortcut_iterations=30)
    calls = _spy_certify(monkeypatch)
    lazy = rrt_connect(world, A, q0, B, fp, 0)
    lazy_chords = sum(calls)
    calls.clear()
    eager = rrt_connect(world, A, q0, B, fp, 0, lazy=False)
    assert lazy.ok and eager.ok
    for f in ("T_world_object", "q_left", "q_right", "clearance", "t"):
        np.testing.assert_array_equal(getattr(lazy, f), getattr(eager, f))
    assert lazy_chords < sum(calls)  # the trees' edges off the path were never certified


@pytest.mark.parametrize("where", ["tree edge", "connecting edge"])
def test_an_edge_the_certificate_refuses_is_pruned_and_the_search_goes_on(problem, monkeypatch, where):
    """The first path found here is the start tree's first edge (2 output steps) and the edge that
    connects it to the goal (9 steps): its first chord lies on the tree's edge, its middle one on the
    connecting edge, which is no tree's (nothing is pruned; that connection is just not taken). The
    search is pinned to ``local_bias`` 0.5, whose first path this is (the default finds another)."""
    world, A, B, q0 = problem
    calls = _spy_certify(monkeypatch, refuse_at=0.0 if where == "tree edge" else 0.5)
    pruned: list[tuple[Tree, set[int]]] = []
    real_prune, real_nearest, real_add = Tree.prune, Tree.nearest, Tree.add
    after: list[tuple[Tree, int]] = []  # nodes returned as nearest, or used as parents, after a prune

    def prune(self, i):
        below = {i}  # the subtree, from the parent links (children come after their parents)
        for j in range(i + 1, len(self)):
            if self.parent[j] in below:
                below.add(j)
        pruned.append((self, below))
        return real_prune(self, i)

    def nearest(self, T, w, k=1):
        out = real_nearest(self, T, w, k)
        after.extend((self, i) for i, _ in out if pruned)
        return out

    def add(self, T, qL, qR, parent, n, t, d=float("nan")):
        if pruned and parent >= 0:
            after.append((self, parent))
        return real_add(self, T, qL, qR, parent, n, t, d)

    monkeypatch.setattr(Tree, "prune", prune)
    monkeypatch.setattr(Tree, "nearest", nearest)
    monkeypatch.setattr(Tree, "add", add)
    res = rrt_connect(world, A, q0, B, FallbackParams(shortcut_iterations=0, local_bias=0.5), 0)
    assert res.ok, res.reason
    assert any(c > 3 for c in calls)  # the refusal happened
    assert res.iterations >= 2  # and the search went on
    if where == "connecting edge":
        assert pruned == []
        return
    assert len(pruned) == 1  # the tree's edge was pruned ...
    tree, below = pruned[0]
    assert after
    assert not [i for t, i in after if t is tree and i in below]  # ... and never used again


def test_a_tree_prunes_a_subtree_and_never_returns_it():
    T = np.eye(4)
    tree = Tree(T, np.zeros(6), np.zeros(6), 0.0)
    poses = []
    for x, parent in ((0.1, 0), (0.2, 1), (0.3, 2), (0.05, 0), (0.25, 1)):
        P = np.eye(4)
        P[0, 3] = x
        poses.append(P)
        tree.add(P, np.zeros(6), np.zeros(6), parent, 1, 0.0)
    assert tree.prune(2) == 2  # node 2 and its child 3
    assert tree.prune(3) == 0  # already pruned
    near = tree.nearest(poses[2], 1.0, k=10)  # the pose of node 3 itself
    assert [i for i, _ in near] == [5, 1, 4, 0]  # alive only (x = 0.25, 0.2, 0.05, 0), nearest first
    assert all(np.isfinite(d) for _, d in near)
    with pytest.raises(ParameterError, match="root"):
        tree.prune(0)


def test_lazy_must_be_a_bool(problem):
    world, A, B, q0 = problem
    with pytest.raises(ParameterError, match="lazy"):
        rrt_connect(world, A, q0, B, FallbackParams(), 0, lazy="yes")


@pytest.mark.parametrize("step_time", [0.0, 0.1])
def test_with_moving_obstacles_the_goal_trees_edges_are_certified_as_they_are_added(monkeypatch, step_time):
    """A sphere crossing the way at 1 m/s (tests/test_fallback.py): with the plan's clock
    (step_time 0.1 s) the goal tree's times are lower bounds, so its edges are certified as the
    search adds them (and never pruned for a found path's refusal); the start tree's, whose times
    are exact, lazily. Without the clock (every pose at t0) both trees' edges are lazy."""
    import dataclasses

    from dualpuma import Cell
    from dualpuma.model import Obstacle
    from dualpuma.planning.edges import EdgeChecker

    cell0 = Cell.default()
    A = cell0.T_world_object_start
    B = A.copy()
    B[:3, 3] += (-0.30, 0.0, 0.0)
    T = np.eye(4)
    T[:3, 3] = (A @ cell0.bar.T_object_bar)[:3, 3] + (-0.15, 0.30, 0.0)
    ob = Obstacle("crosser", "sphere", [0.05], T, velocity=[0.0, -1.0, 0.0], t_start=0.0, t_end=0.6)
    cell = dataclasses.replace(cell0, obstacles=(ob,))
    calls: list[tuple[bool, bool]] = []  # (goal tree, certified as added)
    real = EdgeChecker.edge

    def spy(self, A_, q0, B_, t_a, n=None, d_a=None, whole=False, certify=True):
        calls.append((t_a is None, certify))
        return real(self, A_, q0, B_, t_a, n, d_a, whole, certify)

    monkeypatch.setattr(EdgeChecker, "edge", spy)
    res = rrt_connect(World(cell), A, (cell.left.q_home, cell.right.q_home), B, FallbackParams(shortcut_iterations=0),
                      1, t0=0.0, step_time=step_time)
    assert res.ok, res.reason
    search = calls[1:]  # after the straight edge from start to goal (certified: it is returned whole)
    assert calls[0] == (False, True)
    goal = {c for g, c in search if g}
    start = {c for g, c in search if not g}
    assert goal and start
    assert start == {False}
    assert goal == ({True} if step_time > 0 else {False})
