"""The seed's Striving planner (§5.4, routines 7 and 8) as a pure function, plus a general fallback.

Striving steps the bar's frame along the straight line to the goal (translation in steps of
``step``, orientation interpolated alongside, no step turning more than ``rot_step``) and asks
permission for each next pose: both arms must have branch-continuous, in-limit IK (no joint moving
more than ``max_joint_step`` in one step) and every checked pair must keep ``margin`` of clearance
(arm–arm, arm–obstacle, bar–obstacle, arm–bar, floor). Permission is checked at the step poses and
``substeps - 1`` poses between them, so a plan is valid between its steps too. When a pose is
refused the planner tries the alternate positions in order (the seed's AP1–AP3, offsets from the
refused point, or routine 7's "up and over" from the current point), takes the first whose whole
approach is permitted and re-aims at the goal. It freezes with a reason when none is permitted, when
it would revisit a pose (a cycle) or after ``max_steps``. With ``fallback=True`` a frozen plan is
handed to the SE(3) RRT-Connect of :mod:`.rrt` (rotation included), and so is a run whose last
``handover_after`` alternates in a row left the bar no nearer the goal (it would wander on).

Speed: each straight run is evaluated in one call — the vectorised IK of the whole remaining line
(:func:`~dualpuma.kinematics.continuity.continue_paths`) and one batched clearance query
(:mod:`dualpuma.collision.batch`) — not one pose at a time (:mod:`.runs`).
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
import numpy.typing as npt

from ..checks import generator, joint_pair, validate_pose, vector
from ..collision.contact import contact_reason, self_contact
from ..errors import DualpumaError, ParameterError
from ..kinematics.dual import SIDES, solve_dual
from ..kinematics.providers import wrist_partner
from ..lie import angle, rot_to_rpy, rpy_to_rot
from ..model.world import World
from ..units import below_text
from .edges import ChordMemo, EdgeChecker
from .params import FallbackParams, StrivingParams, for_striving, start_time
from .plan import Plan
from .rrt import rrt_connect
from .runs import (
    Line,
    RunContext,
    Segment,
    in_grown,
    line_poses,
    line_rotation,
    n_line_steps,
    pose_key,
    pose_keys,
    solve_chains,
    try_segment,
)
from .smoothing import smooth, verify

__all__ = ["plan"]

FloatArray = npt.NDArray[np.float64]


class _Rows:
    """The growing plan (row 0 = start)."""

    def __init__(self, ctx: RunContext, t_begin: float) -> None:
        self.ctx, self.t_begin = ctx, t_begin
        self.T: list[FloatArray] = []
        self.qL: list[FloatArray] = []
        self.qR: list[FloatArray] = []
        self.d: list[float] = []
        self.pair: list[tuple[str, str]] = []
        self.events: list[str] = []

    def add(self, T, qL, qR, d, pair) -> None:
        self.T.append(T)
        self.qL.append(qL)
        self.qR.append(qR)
        self.d.append(float(d))
        self.pair.append(pair)

    def add_segment(self, seg: Segment) -> None:
        names = self.ctx.world.pair_names
        for i in range(seg.n_acc):
            self.add(seg.P[i], seg.qL[i], seg.qR[i], seg.d[i], names[int(seg.idx[i])])

    def finish(self, status: str, reason: str, planner: str = "striving") -> Plan:
        P = np.array(self.T).reshape(-1, 4, 4)
        length = float(np.sum(np.linalg.norm(np.diff(P[:, :3, 3], axis=0), axis=1))) if len(P) > 1 else 0.0
        if reason:
            self.events.append(f"{status}: {reason}")
        n = len(P)
        # the rows are the planner's own (checked as they were made): no second validation or copy
        return Plan.trusted(status, reason, P, np.array(self.qL).reshape(-1, 6), np.array(self.qR).reshape(-1, 6),
                            np.array(self.d), tuple(self.pair), self.ctx.t0 + np.arange(n) * self.ctx.p.step_time,
                            tuple(self.events),
                            length, time.perf_counter() - self.t_begin, planner, {"margin": self.ctx.margin})


# ----------------------------------------------------------------------------- public
def plan(
    cell,
    start: npt.ArrayLike,
    goal: npt.ArrayLike,
    params: StrivingParams | None = None,
    rng: np.random.Generator | int | None = None,
    *,
    q_start: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
    start_rpy: npt.ArrayLike | None = None,
    goal_rpy: npt.ArrayLike | None = None,
    world: World | None = None,
    t_start: float = 0.0,
) -> Plan:
    """Plan the held bar from ``start`` to ``goal`` with the Striving technique (pure, deterministic).

    Args:
        cell: the work cell (bases, grasps, bar, obstacles, margin).
        start, goal: object poses T_world_object (4, 4) [m].
        params: :class:`StrivingParams` (default: the seed's settings).
        rng: seed or Generator for the optional fallback search (None = seed 0: deterministic).
        q_start: start joints (left, right) [rad]; default: the cell's home joints when ``start`` is
            the cell's start pose, else the IK solution nearest to them.
        start_rpy, goal_rpy: explicit roll-pitch-yaw angles for ``orientation="rpy"`` (so a yaw of
            -180 deg can be commanded as such, as routine 6 does).
        world: a prebuilt World of ``cell`` (saves its construction; never modified beyond scratch).
        t_start: time of the start pose [s], in :data:`~.params.T_START_RANGE`: step ``i`` is at
            ``t_start + i * step_time`` (moving obstacles are checked at those times). A leg chained after another starts at the
            previous leg's end time (``plan.t[-1]``).

    Returns:
        :class:`~dualpuma.planning.plan.Plan`. Bad input gives ``invalid_input`` / ``invalid_start`` /
        ``invalid_goal`` plans with a reason; only malformed ``params`` raise (ParameterError).
    """
    t_begin = time.perf_counter()
    params = StrivingParams() if params is None else params
    if not isinstance(params, StrivingParams):
        raise ParameterError(f"params: expected StrivingParams, got {type(params).__name__}")
    try:
        generator(rng, "rng")  # checked here, used only if the fallback runs
        A = validate_pose(start, name="start")
        B = validate_pose(goal, name="goal")
        if A.shape != (4, 4) or B.shape != (4, 4):
            raise ParameterError("start and goal must be single poses of shape (4, 4)")
        world = World(cell) if world is None else world
        if not isinstance(world, World) or world.cell is not cell:
            raise ParameterError("world: built from a different cell")
        t0 = start_time(t_start)
        world.reset()  # bit-identical results whatever the world computed before
        ctx = RunContext(world, params, t0)
        # the angles steer only the rpy interpolation (the other modes never read them)
        extract = rot_to_rpy if params.orientation == "rpy" else _no_angles
        rpy_a = extract(A[:3, :3]) if start_rpy is None else vector(start_rpy, "start_rpy", 3, unit="rad")
        rpy_b = extract(B[:3, :3]) if goal_rpy is None else vector(goal_rpy, "goal_rpy", 3, unit="rad")
        if params.orientation == "rpy":
            for r, T, name in ((rpy_a, A, "start_rpy"), (rpy_b, B, "goal_rpy")):
                if not np.allclose(rpy_to_rot(r), T[:3, :3], rtol=0.0, atol=1e-9):
                    raise ParameterError(f"{name}: its rotation differs from the pose's rotation")
        q0 = _start_joints(world, A, q_start)
    except DualpumaError as e:
        return Plan.failed("invalid_input", str(e), time.perf_counter() - t_begin)
    return _striving(ctx, A, rpy_a, q0, B, rpy_b, rng, t_begin)


def _no_angles(R: FloatArray) -> FloatArray:
    return np.zeros(3)


def _start_joints(world: World, A: FloatArray, q_start) -> tuple[FloatArray, FloatArray]:
    cell = world.cell
    if q_start is not None:
        return joint_pair(q_start, "q_start")
    home = (np.asarray(cell.left.q_home, float), np.asarray(cell.right.q_home, float))
    if np.allclose(A, cell.T_world_object_start, rtol=0.0, atol=1e-12):
        return home
    sol = solve_dual(world, A, home, max_step=2 * math.pi, check_clearance=False)
    if sol.q_left is None or sol.q_right is None:
        raise ParameterError(f"start: no IK solution on the home branches ({sol.reason})")
    return sol.q_left, sol.q_right


def _striving(ctx: RunContext, A, rpy_a, q0, B, rpy_b, rng, t_begin: float) -> Plan:
    w, p = ctx.world, ctx.p
    rows = _Rows(ctx, t_begin)
    d_start, k_start = w.min_distance(q0[0], q0[1], A, ctx.t0)
    rows.add(A, q0[0], q0[1], d_start, w.pair_names[k_start])
    hands = w.hand_poses(q0[0], q0[1])
    for s, H in zip(("left", "right"), hands):
        if not np.abs(H - A @ w.T_object_hand[s]).max() <= 1e-6:
            return rows.finish("invalid_start", f"{s} hand is not at its grasp of the start pose (q_start does not hold the bar)")
    for qq, side in zip(q0, ("left", "right")):
        lim = w.arms[side].limits
        out = np.flatnonzero((qq < lim[:, 0] - 1e-12) | (qq > lim[:, 1] + 1e-12))
        if out.size:
            bad = "; ".join(f"q{j + 1} = {qq[j]:.4f} rad not in [{lim[j, 0]:.4f}, {lim[j, 1]:.4f}] rad"
                            for j in out.tolist())
            return rows.finish("invalid_start", f"{side} arm start joints outside the joint limits: {bad}")
    if d_start < ctx.margin:
        a, b = w.pair_names[k_start]
        return rows.finish("invalid_start", f"start clearance {below_text(d_start, ctx.margin)} m below {ctx.margin:.3f} m ({a} – {b})")
    touch = self_contact(w, q0[0], q0[1])[0]
    if touch is not None:
        return rows.finish("invalid_start", f"start: {contact_reason(*touch)}")
    if p.mapping and ctx.cell.obstacles and in_grown(ctx, A[None, :3, 3], np.zeros(1))[0]:
        return rows.finish("invalid_start", "the object origin starts inside a grown obstacle (configuration mapping)")
    why = _goal_reason(ctx, B, q0)
    if why:
        return rows.finish("invalid_goal", why)

    cur, rpy_cur, q = A, rpy_a, q0
    visited: set = set()
    n_keyed = 0  # rows already in ``visited`` (keys are made only when an alternate is considered)
    recoveries = 0
    nearest, stalled = math.inf, 0  # the bar's nearest approach to the goal at a refusal; alternates since
    next_line = None  # the run on from a taken alternate, solved together with its approach
    while True:
        seg = try_segment(ctx, cur, rpy_cur, q, B, rpy_b, len(rows.T) - 1, rows.d[-1], next_line)
        next_line = None
        rows.add_segment(seg)
        if seg.n_acc:
            cur, rpy_cur, q = seg.P[-1], seg.rpy[-1], (seg.qL[-1], seg.qR[-1])
        if seg.n_acc == seg.n:
            return rows.finish("reached", "")
        step_no = len(rows.T)
        if step_no - 1 >= p.max_steps:
            return _maybe_fallback(ctx, rows, q, B, rng, f"gave up after {p.max_steps} steps")
        if p.fallback and p.handover_after:
            near = _remoteness(ctx, cur, B)
            nearest, stalled = (near, 0) if near < nearest else (nearest, stalled + 1)
            if stalled >= p.handover_after:
                return _maybe_fallback(ctx, rows, q, B, rng, f"no progress: {stalled} alternate positions in a row "
                                       f"left the bar no nearer the goal (step {step_no} refused: {seg.reason})",
                                       "handed over")
        aps = _alternates(ctx, cur, rpy_cur, B, rpy_b)
        if aps:  # every alternate's approach and the run on from it in one IK call; clearance in order
            solve_chains(ctx, [(ap[3], ap[4]) for ap in aps], np.concatenate(q))
        took = ""
        tried: list[str] = []
        if aps:
            visited.update(pose_keys(rows.T[n_keyed:]))
            n_keyed = len(rows.T)
        for name, T_ap, r_ap, line, onward in aps:
            if pose_key(T_ap) in visited:
                tried.append(f"{name} already visited")
                continue
            seg_ap = try_segment(ctx, cur, rpy_cur, q, T_ap, r_ap, len(rows.T) - 1, rows.d[-1], line)
            if seg_ap.n_acc == seg_ap.n:
                rows.add_segment(seg_ap)
                cur, rpy_cur, q = seg_ap.P[-1], seg_ap.rpy[-1], (seg_ap.qL[-1], seg_ap.qR[-1])
                took = name
                next_line = onward if seg_ap.line is line else None  # not if the approach was refined
                break
            tried.append(f"{name} refused: {seg_ap.reason}")
        rows.events.append(f"step {step_no}: refused ({seg.reason}); " + "; ".join(tried + ([f"took {took}"] if took else ["no alternate permitted"])))
        recoveries += 1 if took else 0
        if took and recoveries > p.max_recoveries:
            return _maybe_fallback(ctx, rows, q, B, rng, f"wandering: {p.max_recoveries} alternate positions taken without reaching the goal")
        if not took:
            return _maybe_fallback(ctx, rows, q, B, rng, f"step {step_no} refused ({seg.reason}); no alternate position is permitted")


def _alternates(ctx: RunContext, cur: FloatArray, rpy_cur, B: FloatArray, rpy_b) -> list:
    """The alternate positions from ``cur`` in order: (name, pose, rpy, line from cur, line on from
    there to B) each. Offsets apply to the refused point (the next step towards B) or to ``cur``
    (``alternates_from``)."""
    p = ctx.p
    if not p.alternates:
        return []
    if p.alternates_from == "refused":
        P_next, rpy_next = line_poses(ctx, cur, B, rpy_cur, rpy_b, n_line_steps(ctx, cur, B, rpy_cur, rpy_b, p.step), 1)
        base, r_ap = P_next[0], rpy_next[0]
    else:
        base, r_ap = cur, rpy_cur
    out = []
    # every approach turns from cur to the alternates' common orientation, every run on from there
    # to B's: their turns are computed once
    rot_ap = rot_on = None
    for j, off in enumerate(p.alternates):
        T_ap = base.copy()
        T_ap[:3, 3] = base[:3, 3] + np.asarray(off)
        name = f"AP{j + 1}" if p.alternates_from == "refused" else "up-and-over"
        if rot_ap is None:
            rot_ap = line_rotation(ctx, cur, T_ap, rpy_cur, r_ap)
        line = Line(ctx, cur, T_ap, rpy_cur, r_ap, p.step, rot_ap)
        if rot_on is None:
            rot_on = line_rotation(ctx, line.P[-1], B, line.rpy[-1], rpy_b)
        out.append((name, T_ap, r_ap, line, Line(ctx, line.P[-1], B, line.rpy[-1], rpy_b, p.step, rot_on)))
    return out


def _remoteness(ctx: RunContext, T: FloatArray, B: FloatArray) -> float:
    """How far pose T is from the goal B in steps: the larger of distance / ``step`` and rotation
    angle / ``rot_step`` (unitless; what :func:`~.runs.n_line_steps` rounds up for a slerp run)."""
    p = ctx.p
    return max(math.dist(T[:3, 3].tolist(), B[:3, 3].tolist()) / p.step, angle(T[:3, :3], B[:3, :3]) / p.rot_step)


def _goal_reason(ctx: RunContext, B: FloatArray, q0) -> str:
    """Why the goal can never be reached on the start's branches: reach, joint limits, self-contact
    ("" if it may be)."""
    w = ctx.world
    for k, s in enumerate(SIDES):
        arm = w.arms[s]
        T_bh = w.T_base_inv[s] @ B @ w.T_object_hand[s]
        if not arm.analytic:
            r = arm.ik(T_bh, q_near=q0[k])
            if not r.ok and r.status != "not_found":  # not found by the numeric IK: the run may still reach it
                return f"{s} arm cannot reach the goal: {r.reason}"
            continue
        b = arm.branch_of(q0[k])
        sols, valid = arm.ik_all(T_bh, q_near=q0[k])
        if not (valid[b] or valid[wrist_partner(b)]):
            why = "is outside its reach" if np.isnan(sols[b]).any() else "needs joints outside the limits on the start's branch"
            return f"{s} arm: the goal {why}"
        touch = [self_contact(w, *((sols[c], q0[1]) if k == 0 else (q0[0], sols[c])))[0]
                 for c in (b, wrist_partner(b)) if valid[c]]
        if all(t is not None for t in touch):  # (the start is clear of self-contact: checked before)
            return f"at the goal {contact_reason(*touch[0])}"
    # Clearance at the goal is not judged here: it depends on the arrival time (moving obstacles)
    # and Striving reports a blocked goal as a refusal with its pair.
    return ""


def _maybe_fallback(ctx: RunContext, rows: _Rows, q, B, rng, reason: str, stopped: str = "frozen") -> Plan:
    if not ctx.p.fallback:
        return rows.finish("frozen", reason)
    fp = for_striving(ctx.p.fallback_params if ctx.p.fallback_params is not None else FallbackParams(), ctx.p)
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(0 if rng is None else rng)
    k0 = len(rows.T) - 1
    rows.events.append(f"step {k0}: Striving {stopped} ({reason}); fallback RRT-Connect in SE(3)")
    memo = ChordMemo()  # chords certified once for the search, the joined path and smoothing
    res = rrt_connect(ctx.world, rows.T[-1], q, B, dataclasses.replace(fp, shortcut_iterations=0), gen,
                      t0=ctx.t0 + k0 * ctx.p.step_time, step_time=ctx.p.step_time, certified=memo)
    if not res.ok:
        return rows.finish("frozen", f"{reason}; fallback RRT-Connect failed: {res.reason}", "striving+rrt")
    again = f" ({res.restarts} restart(s) from new trees)" if res.restarts else ""
    rows.events.append(f"fallback: {len(res.T_world_object) - 1} steps, {res.iterations} iterations{again}")
    # the whole path, Striving's prefix included, re-verified as one and smoothed
    w = ctx.world
    ec = EdgeChecker(w, fp, rows.T[0], ctx.t0, ctx.p.step_time, memo)
    q0 = (rows.qL[0], rows.qR[0])
    way = [(rows.T[0], 0)] + [(T, 1) for T in rows.T[1:]] + [(T, 1) for T in res.T_world_object[1:]]
    whole, _ = verify(ec, way, q0, rows.d[0])
    n_before = len(way) - 1
    if whole is not None and fp.shortcut_iterations:
        whole = smooth(ec, whole, q0, rows.d[0], gen)
    if whole is None:  # each part is valid on its own: keep them as found
        P, QL, QR = res.T_world_object[1:], res.q_left[1:], res.q_right[1:]
        rows.events.append("smoothing: the joined path did not re-verify as one; kept as found")
    else:
        del rows.T[1:], rows.qL[1:], rows.qR[1:], rows.d[1:], rows.pair[1:]
        P, QL, QR = whole.P[1:], whole.qL[1:], whole.qR[1:]
        rows.events.append(f"smoothed: the whole path, {n_before} -> {P.shape[0]} steps")
    for i in range(P.shape[0]):
        t = ctx.t0 + (len(rows.T)) * ctx.p.step_time
        d, k = w.min_distance(QL[i], QR[i], P[i], t)
        rows.add(P[i], QL[i], QR[i], d, w.pair_names[k])
    return rows.finish("reached", "", "striving+rrt")
