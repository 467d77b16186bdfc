"""General fallback beyond the seed: bidirectional RRT-Connect over object poses in SE(3).

When Striving freezes, the bar's frame is searched in SE(3) — rotation included, so the bar can
"snake" (weave by rotating) through a slot field, the seed's §7.3 wish. Each tree node holds an
object pose and both arms' joints. An edge between two poses is the SE(3) geodesic of the bar
(translation linear, rotation along the shortest arc), cut into ``n`` output steps no longer than
``step`` [m] and ``rot_step`` [rad]; it is *permitted* when every one of its ``n * substeps``
sub-poses has dual IK that continues the neighbour's joints (same IK branches, no joint moving more
than ``max_joint_step``, inside the limits) and clearance >= ``margin`` — and no joint moves more than
``max_joint_step`` between consecutive output steps (an edge that would is cut into more steps, up
to 8 times as many: near the wrist singularity q4 and q6 turn fast). The goal tree's roots are the
goal solved on the start's IK branches (and their wrist partners, which a path through q5 = 0
continues on), so a connected path keeps each arm's branch from start to goal. Trees meet where an
edge from one arrives at a node of the other with the same joints up to whole turns (q4 + 2 pi is
the same arm); the whole path is then re-solved forward, where the joint limits decide.

Search details: samples are uniform in a box around start and goal (oriented as the start or the
goal turned about a random axis, small turns more often: :func:`_sampler`), or (``local_bias``) Gaussian
around a random node of the growing tree, which keeps exploring narrow regions such as the space
between two plates; the other tree tries to connect to each new node from its nearest node in the
metric and from its nearest nodes by position alone. A search that has not met after
``restart_iterations`` starts again from new trees, then after twice as many iterations, and so on
(the iterations to a path are heavy-tailed: a tree grown into a dead end stays there; restarts cut
that tail, as Wedge and Branicky measured for RRTs in 2008).

The trees' edges are checked at their poses and between them as the search adds them; their
motion between output steps is certified lazily (``lazy``, the default): only when a found path
uses them. A found path is re-solved from the start joints as a whole and verified at its real
times, its motion certified; where the certificate refuses a step on a tree's edge, the node that
edge leads to is pruned from its tree with every node below it (:meth:`~.tree.Tree.prune`: never
extended from or connected to again) and the search goes on (a refused connecting edge is just
not taken). On the hard set at seed 0 the eager search's certificate refused 3 of 14,877 edges
and took a quarter of the search's time. A path that verifies is then shortened by random
shortcuts (straight SE(3) segments, each re-verified the same way, joints continuous with the rest
of the path) and returned at output-step resolution.

Moving obstacles: the pose at output index ``i`` of the final path is at time ``t0 + i * step_time``.
During the search the time of a start-tree pose is exact for its tree path (``t0`` + output steps
from the root × ``step_time``); a goal-tree pose has no known arrival index, so its time is
approximated by the earliest possible one — the number of output steps of the straight edge from the
start pose to it. Every candidate path (and shortcut) is re-verified at its real times, so this
approximation can cost a failed connection, never an invalid result.

Deterministic: the same inputs and rng seed give bit-identical results (``world.reset()`` first).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..checks import generator, joint_pair, real, validate_pose
from ..errors import ParameterError
from ..kinematics.dual import SIDES
from ..lie import slerp
from ..model.world import World
from ..values import value_class
from .edges import ChordMemo, EdgeChecker, Run
from .params import FallbackParams, for_striving
from .roots import root_checks
from .smoothing import JOINT_MATCH, Path, path_from_run, smooth, step_owner, verify_run
from .tree import Tree, joined

__all__ = ["FallbackResult", "rrt_connect"]

FloatArray = npt.NDArray[np.float64]


@value_class
@dataclass(frozen=True, slots=True)
class FallbackResult:
    """Result of :func:`rrt_connect` (arrays read-only; empty when ``ok`` is False).

    Attributes:
        ok: a permitted path from start to goal was found.
        T_world_object: object poses (N, 4, 4) [m]; row 0 = start, row N-1 = goal.
        q_left, q_right: joints (N, 6) [rad].
        clearance: minimum signed distance per pose (N,) [m].
        reason: why it failed ("" when ok).
        iterations: RRT-Connect iterations run (over all restarts).
        n_nodes: nodes in both trees (the last restart's).
        time_s: wall time [s].
        t: time of each pose (N,) [s]: ``t0 + i * step_time``.
        restarts: times the search started again from new trees (``restart_iterations``).
    """

    ok: bool
    T_world_object: FloatArray
    q_left: FloatArray
    q_right: FloatArray
    clearance: FloatArray
    reason: str
    iterations: int
    n_nodes: int
    time_s: float
    t: FloatArray = field(default_factory=lambda: np.zeros(0))
    restarts: int = 0

    def __post_init__(self) -> None:
        for name in ("T_world_object", "q_left", "q_right", "clearance", "t"):
            arr = np.array(getattr(self, name), dtype=np.float64)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)


# ----------------------------------------------------------------------------- search
#: the local sampler's standard deviation, a fraction of ``max_extend`` (0.5 before 2026-11-27; 0.2
#: measured best of 0.125-0.5 with ``local_bias`` 0.7: docs/performance.md, fifteenth session)
_LOCAL_SPREAD = 0.2


def _sampler(ctx: EdgeChecker, A: FloatArray, B: FloatArray, gen: np.random.Generator):
    """Object poses: origin uniform in the bounds, rotation the start's or the goal's (even odds)
    turned about a uniformly random axis by ``max_rotation * u**2`` (u uniform in [0, 1]): half the
    samples lie within a quarter of ``max_rotation`` of those orientations, where two arms holding a
    bar can mostly reach (measured against angles distributed as in a uniform ball, whose mass lies
    near ``max_rotation``: on the hard set over six seeds 56 % fewer iterations, 34 % less time, the
    slowest search 28 s -> 4 s, paths 1.7 % longer; on the snaking slot field 25 % less time, six of
    seeds 0-7 solved either way)."""
    p = ctx.p
    if p.bounds is None:
        lo = np.minimum(A[:3, 3], B[:3, 3]) - p.bounds_padding
        hi = np.maximum(A[:3, 3], B[:3, 3]) + p.bounds_padding
        lo[2] = max(lo[2], float(ctx.world.cell.floor_z))
        hi[2] = max(hi[2], lo[2] + 1e-3)
    else:
        lo, hi = np.array(p.bounds[0]), np.array(p.bounds[1])

    def sample() -> FloatArray:
        T = np.eye(4)
        T[:3, 3] = gen.uniform(lo, hi)
        axis = gen.normal(size=3)
        ang = p.max_rotation * gen.uniform() ** 2
        R0 = A[:3, :3] if gen.uniform() < 0.5 else B[:3, :3]
        T[:3, :3] = R0 @ pin.exp3(axis / max(float(np.linalg.norm(axis)), 1e-12) * ang)
        return T

    return sample


def _near(ctx: EdgeChecker, tree: Tree, gen: np.random.Generator) -> FloatArray:
    """A pose near a random node of ``tree`` (see ``FallbackParams.local_bias``): Gaussian, its
    standard deviation :data:`_LOCAL_SPREAD` ``* max_extend`` per axis in translation [m] and that
    over ``rot_weight`` about each axis in rotation [rad]."""
    T0 = tree.T[int(gen.integers(len(tree)))]
    T = np.eye(4)
    T[:3, 3] = T0[:3, 3] + gen.normal(scale=_LOCAL_SPREAD * ctx.p.max_extend, size=3)
    T[:3, :3] = T0[:3, :3] @ pin.exp3(
        gen.normal(scale=_LOCAL_SPREAD * ctx.p.max_extend / ctx.p.rot_weight, size=3)
    )
    return T


def _fail(reason: str, it: int, nodes: int, tic: float, restarts: int = 0) -> FallbackResult:
    e = np.zeros(0)
    return FallbackResult(
        False,
        np.zeros((0, 4, 4)),
        np.zeros((0, 6)),
        np.zeros((0, 6)),
        e,
        reason,
        it,
        nodes,
        time.perf_counter() - tic,
        e,
        restarts,
    )


def _trees(ctx: EdgeChecker, A: FloatArray, q0: tuple[FloatArray, FloatArray], d0: float, B: FloatArray,
           roots: list[tuple[FloatArray, FloatArray, float]]) -> tuple[Tree, Tree]:
    """New trees: the start tree at A with joints q0 (clearance d0), the goal tree at B with every root."""
    t_goal = float(ctx.t_lb(B[None])[0])
    trees = (Tree(A, q0[0], q0[1], ctx.t0, d0), Tree(B, roots[0][0], roots[0][1], t_goal, roots[0][2]))
    for qL, qR, dg in roots[1:]:
        trees[1].add(B, qL, qR, -1, 0, t_goal, dg)  # further roots: the same goal pose, other joints
    return trees


def rrt_connect(
    world: World,
    T_start: npt.ArrayLike,
    q_start: tuple[npt.ArrayLike, npt.ArrayLike],
    T_goal: npt.ArrayLike,
    params: FallbackParams = FallbackParams(),  # noqa: B008 - frozen, validated dataclass
    rng: np.random.Generator | int | None = None,
    *,
    t0: float = 0.0,
    step_time: float = 0.0,
    striving: object | None = None,
    certified: ChordMemo | None = None,
    lazy: bool = True,
) -> FallbackResult:
    """Bidirectional RRT-Connect over object poses in SE(3), then shortcut smoothing (module docstring).

    Args:
        world: the :class:`~dualpuma.world.World` of the cell (its scratch buffers are used).
        T_start: start object pose (4, 4) [m].
        q_start: (q_left, q_right) at the start [rad], each (6,); their IK branches are kept.
        T_goal: goal object pose (4, 4) [m].
        params: :class:`FallbackParams`.
        rng: a Generator (advanced), a seed, or None (= seed 0, deterministic).
        t0: time of the start pose [s] (moving obstacles).
        step_time: time per output step [s].
        striving: the frozen Striving run's :class:`~dualpuma.planner.StrivingParams` (optional): its
            margin applies when ``params.margin`` is None and validity is checked at least at its
            ``substeps``, so the result meets Striving's permission rule.
        certified: the calling plan's :class:`~.edges.ChordMemo` (chords it certified already), to
            share with its later checks of the same path (None: this search's own).
        lazy: certify the motion of the trees' edges only when a found path uses them (its
            verification certifies it as a whole; an edge it refuses is pruned from its tree with
            the nodes below it, and the search goes on); with moving obstacles only the start
            tree's (the goal tree's times are lower bounds, so its edges are certified as they
            are added and never pruned). False: certify every edge as the search adds it. The
            path returned is certified either way.

    Returns:
        :class:`FallbackResult`; an invalid start, an unreachable or blocked goal, or no path within
        ``max_iterations`` give ``ok=False`` with a reason (never an exception).

    Raises:
        ParameterError: params or certified of the wrong type, bad rng / t0 / step_time.
        PoseError, JointError: malformed poses or joints.
    """
    tic = time.perf_counter()
    if not isinstance(params, FallbackParams):
        raise ParameterError(f"params: expected FallbackParams, got {type(params).__name__}")
    if not isinstance(world, World):
        raise ParameterError(f"world: expected a dualpuma World, got {type(world).__name__}")
    if not isinstance(lazy, bool):
        raise ParameterError(f"lazy: expected True or False, got {lazy!r}")
    if certified is not None and not isinstance(certified, ChordMemo):
        raise ParameterError(f"certified: expected a ChordMemo or None, got {type(certified).__name__}")
    t0 = real(t0, "t0", unit="s")
    step_time = real(step_time, "step_time", lo=0.0, hi=3600.0, unit="s")
    A = validate_pose(T_start, name="T_start").copy()
    B = validate_pose(T_goal, name="T_goal").copy()
    if A.shape != (4, 4) or B.shape != (4, 4):
        raise ParameterError("T_start and T_goal must be single poses of shape (4, 4)")
    q0 = tuple(np.array(q) for q in joint_pair(q_start, "q_start"))
    if striving is not None:
        params = for_striving(params, striving)
    gen = generator(rng)
    world.reset()  # bit-identical distances whatever the world computed before
    ctx = EdgeChecker(world, params, A, float(t0), float(step_time), certified)
    why, d0, roots = root_checks(ctx, A, q0, B)
    if not roots:
        return _fail(why, 0, 0, tic)

    restarts = 0

    def done(path: Path, it: int, nodes: int) -> FallbackResult:
        if params.shortcut_iterations:
            path = smooth(ctx, path, q0, d0, gen)  # re-verified as a whole (else the unsmoothed path)
        n = path.P.shape[0]
        return FallbackResult(
            True,
            path.P,
            path.qL,
            path.qR,
            path.d,
            "",
            it,
            nodes,
            time.perf_counter() - tic,
            ctx.t0 + np.arange(n) * ctx.dt,
            restarts,
        )

    # the straight edge at its real times, certified (and cut finer where that needs it): taken whole
    run, n = ctx.edge(A, q0, B, ctx.t0, d_a=d0, whole=True)
    if run.m == n:
        return done(path_from_run(ctx, A, q0, d0, run), 0, 2)
    trees = _trees(ctx, A, q0, d0, B, roots)
    sample = _sampler(ctx, A, B, gen)
    failed_joins: list[str] = []
    pruned = 0
    it = 0
    restart_after = params.restart_iterations  # iterations run when the next restart comes
    deadline = math.inf if params.time_limit is None else tic + params.time_limit
    timed_out = False
    for it in range(1, params.max_iterations + 1):
        if time.perf_counter() >= deadline:
            timed_out, it = True, it - 1
            break
        if restart_after and it > restart_after:  # start again, then after twice as many iterations
            restarts += 1
            trees = _trees(ctx, A, q0, d0, B, roots)
            restart_after += params.restart_iterations << restarts
        ia = (it - 1) % 2
        ta, tb = trees[ia], trees[1 - ia]
        u = gen.uniform()
        S = (
            tb.T[0]
            if u < params.goal_bias
            else (_near(ctx, ta, gen) if u < params.goal_bias + params.local_bias else sample())
        )
        new = _extend(ctx, ta, ia == 0, S, _eager(ctx, lazy, ia == 0))
        if new < 0:
            continue
        hit = _connect(ctx, tb, ia == 1, (ta, new), (ta.qL[new], ta.qR[new]), _eager(ctx, lazy, ia == 1))
        if hit is None:
            continue
        j, n_conn = hit
        (ts, i_s), (tg_, i_g) = ((ta, new), (tb, j)) if ia == 0 else ((tb, j), (ta, new))
        way, edge_of = joined(ts, i_s, tg_, i_g, n_conn)
        path, run, n_out = verify_run(ctx, way, q0, d0)
        if path is not None:
            return done(path, it, len(ta) + len(tb))
        if lazy and run.why == "uncertified":  # a tree edge whose motion the certificate refuses
            w = step_owner(way, run.m)
            if w >= 0 and edge_of[w] is not None:
                tree, node = edge_of[w]
                if not _eager(ctx, lazy, tree is trees[0]):  # an eager tree's edges were certified as added
                    pruned += tree.prune(node)
        failed_joins.append(f"output step {run.m + 1} of {n_out}: {run.reason}")
    nodes = len(trees[0]) + len(trees[1])
    top = ", ".join(f"{k} ({v})" for k, v in ctx.stats.most_common(3))
    extra = (
        f"; {len(failed_joins)} connection(s) failed re-verification as one path at real times (first: {failed_joins[0]})"
        if failed_joins
        else ""
    ) + (f"; {pruned} tree node(s) pruned where a found path's motion was not certified" if pruned else "")
    again = f", {restarts} restart(s) from new trees" if restarts else ""
    within = f"within the time limit of {params.time_limit:g} s ({it} iterations)" if timed_out else f"in {it} iterations"
    return _fail(
        f"no path found {within}{again} ({len(trees[0])} start-tree, {len(trees[1])} goal-tree "
        f"nodes); most frequent refusals: {top or 'none'}{extra}",
        it,
        nodes,
        tic,
        restarts,
    )


def _eager(ctx: EdgeChecker, lazy: bool, forward: bool) -> bool:
    """Are the edges of the start tree (``forward``) or the goal tree certified as they are added?
    Not when lazy; with moving obstacles the goal tree's are anyway (its times are lower bounds:
    a found path's real times may be what refuses its edge, so it is not pruned for that)."""
    return not lazy or (ctx.timed and not forward)


def _node_time(ctx: EdgeChecker, tree: Tree, forward: bool, parent: int, m: int, T: FloatArray) -> float:
    return tree.t[parent] + m * ctx.dt if forward else float(ctx.t_lb(T[None])[0])


def _extend(ctx: EdgeChecker, tree: Tree, forward: bool, S: FloatArray, certify: bool) -> int:
    """Grow ``tree`` from its nearest node towards S by at most ``max_extend``; new node or -1
    (``certify``: the edge's motion between output steps, else that is the found path's)."""
    i, d = tree.nearest(S, ctx.p.rot_weight)[0]
    if d < 1e-9:
        return -1
    T = S if d <= ctx.p.max_extend else slerp(tree.T[i], S, np.array([ctx.p.max_extend / d]))[0]
    run, _ = ctx.edge(tree.T[i], (tree.qL[i], tree.qR[i]), T, tree.t[i] if forward else None, d_a=tree.d[i],
                      certify=certify)
    if run.m == 0:
        return -1
    k = run.m * ctx.sub - 1
    return tree.add(
        run.P[k], run.qL[k], run.qR[k], i, run.m, _node_time(ctx, tree, forward, i, run.m, run.P[k]), run.d[k]
    )


def _same_joints(run: Run, q: tuple[FloatArray, FloatArray]) -> bool:
    """Do the edge's last joints equal q up to whole turns? (q4 + 2 pi is the same arm geometry; the
    path is re-solved forward as a whole, where the joint limits decide.)"""
    gap = [
        np.abs((a[-1] - b + np.pi) % (2 * np.pi) - np.pi).max()
        for a, b in ((run.qL, q[0]), (run.qR, q[1]))
    ]
    return max(gap) <= JOINT_MATCH


def _winding_fits(ctx: EdgeChecker, run: Run, qX: tuple[FloatArray, FloatArray], tree: Tree, i: int,
                  forward: bool, other: tuple[Tree, int]) -> bool:
    """Can a path joined by ``run`` (from ``tree``'s node i to the other tree's node X, joints qX
    there, equal up to whole turns: :func:`_same_joints`) keep the joint limits on to the goal? The
    path is re-solved forward as a whole, so past the join every goal-side joint comes out shifted by
    the whole turns the forward side's differ by at X: a goal-side node then outside its limits
    dooms it. Such a join is dropped here (counted in the refusals) instead of being re-verified as a
    whole path and refused there; the search finds the same paths, bit for bit (boxes-8 of the hard
    set re-verified 284 such joins: 1.6 s; they recur, the trees meeting where a wrist has wound the
    other way)."""
    if forward:  # run: the start tree's joints; the goal side: the other tree from X to its root
        fwd, goal = (run.qL[-1], run.qR[-1]), qX
        sides = other[0].chain_joints(other[1])
    else:  # run: the goal tree's joints from node i towards X; the forward side at X: qX
        fwd, goal = qX, (run.qL[-1], run.qR[-1])
        chain = tree.chain_joints(i)
        sides = (np.vstack([run.qL, chain[0]]), np.vstack([run.qR, chain[1]]))
    for a, b, Q, side in zip(fwd, goal, sides, SIDES, strict=True):
        turns = np.round((a - b) / (2.0 * np.pi))
        if turns.any() and not ctx.world.arms[side].within_limits(Q + 2.0 * np.pi * turns).all():
            ctx.stats[f"{side} arm joint_limits past a join (wound a turn apart)"] += 1
            return False
    return True


def _connect(
    ctx: EdgeChecker, tree: Tree, forward: bool, other: tuple[Tree, int], qX: tuple[FloatArray, FloatArray],
    certify: bool,
) -> tuple[int, int] | None:
    """Grow ``tree`` straight towards pose X, node ``other`` = (the other tree, its node) with joints
    qX; ``certify``: as in :func:`_extend`.

    Returns (node of ``tree`` whose edge to X is fully permitted and arrives with joints qX up to whole
    turns, that edge's output steps); None after adding the permitted prefix as nodes every
    ``max_extend``, or at once for a join whose turns would leave the joint limits further on
    (:func:`_winding_fits`).
    """
    X = other[0].T[other[1]]
    order = tree.nearest(X, ctx.p.rot_weight)
    extra = [i for i, _ in tree.nearest(X, 0.0, ctx.p.connect_attempts) if i != order[0][0]][
        : ctx.p.connect_attempts - 1
    ]
    for i in extra:  # nearest by position (any orientation): a full, joint-continuous edge or nothing
        run, n = ctx.edge(tree.T[i], (tree.qL[i], tree.qR[i]), X, tree.t[i] if forward else None, d_a=tree.d[i],
                          whole=True, certify=certify)
        if run.m == n and _same_joints(run, qX):
            return (i, n) if _winding_fits(ctx, run, qX, tree, i, forward, other) else None
    i, d = order[0]
    run, n = ctx.edge(tree.T[i], (tree.qL[i], tree.qR[i]), X, tree.t[i] if forward else None, d_a=tree.d[i],
                      certify=certify)
    m = run.m
    if m == n:
        if _same_joints(run, qX):
            return (i, n) if _winding_fits(ctx, run, qX, tree, i, forward, other) else None
        m -= 1  # same pose, other joints (e.g. q4 + 2 pi): keep the prefix only
    every = max(1, int(ctx.p.max_extend / max(d / n, 1e-9)))
    parent, done = i, 0
    for k in list(range(every, m, every)) + ([m] if m else []):
        f = k * ctx.sub - 1
        parent = tree.add(
            run.P[f],
            run.qL[f],
            run.qR[f],
            parent,
            k - done,
            _node_time(ctx, tree, forward, parent, k - done, run.P[f]),
            run.d[f],
        )
        done = k
    return None
