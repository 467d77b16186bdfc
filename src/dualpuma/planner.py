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
handed to the SE(3) RRT-Connect of :mod:`dualpuma.fallback` (rotation included).

Speed: each straight run is evaluated in one call — the vectorised IK of the whole remaining line
(:func:`~dualpuma.coordination.solve_path`) and one batched clearance query
(:func:`~dualpuma.clearance.clearance_batch`) — not one pose at a time.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from . import puma
from .branch_path import branch_signs
from .coordination import solve_dual
from .errors import DualpumaError, ParameterError
from .paths import calc_rot, rpy_from_rot
from .plan_io import Plan
from .puma import validate_joints, validate_pose
from .segments import (  # noqa: F401
    _angle,
    _Ctx,
    _in_grown,
    _key,
    _Line,
    _line,
    _n_steps,
    _Segment,
    _solve_chains,
    _solve_lines,
    _try_segment,
)
from .world import World

__all__ = ["SEED_ALTERNATES", "UP_AND_OVER", "Plan", "StrivingParams", "plan"]

FloatArray = npt.NDArray[np.float64]

#: the seed's routine-8 alternates, cumulative from the refused point [m]: AP1 = +x 50 mm, +z 25 mm;
#: AP2 = AP1 - 75 mm z; AP3 = AP2 + 50 mm y (listing: px + 10, pz + 5; pz - 15; py + 10 units)
SEED_ALTERNATES = ((0.05, 0.0, 0.025), (0.05, 0.0, -0.05), (0.05, 0.05, -0.05))
#: routine 7's recovery: 50 mm straight up from the current point, repeated (listing: z + 10 units)
UP_AND_OVER = ((0.0, 0.0, 0.05),)
_ORIENTATIONS = ("slerp", "rpy", "puma")


@dataclass(frozen=True, slots=True)
class StrivingParams:
    """Parameters of :func:`plan` (frozen; validated on construction, SI units).

    Attributes:
        step: translation per step [m] (the seed: 10 screen units = 50 mm).
        rot_step: largest rotation per step [rad].
        min_step: the smallest step used when a step is refined because a joint would move more
            than ``max_joint_step`` [m].
        substeps: permission is checked at ``substeps`` evenly spaced poses per step (>= 1).
        max_joint_step: largest joint change per step [rad] (the seed's RobMov: 20 deg).
        margin: required clearance [m]; None = the cell's ``safety_margin``.
        orientation: ``slerp`` (geodesic), ``rpy`` (roll-pitch-yaw increments, eq. 5.7) or ``puma``
            (the seed's imaginary-PUMA joint angles, routine 3).
        alternates: recovery offsets (x, y, z) [m] tried in order when a pose is refused.
        alternates_from: ``refused`` (offsets from the refused pose, routine 8) or ``current``
            (from the last permitted pose, routine 7's up-and-over).
        mapping: also require the object origin outside every obstacle grown by the bar's major
            dimension (the seed's configuration mapping).
        max_steps: give up (frozen) after this many steps.
        max_recoveries: give up (frozen: wandering) after this many alternate positions taken.
        step_time: time per step [s] (moving obstacles are checked at each step's time).
        twist_buffer: twisting-collision detector (routine 6) [m]: while the bar rotates, refuse a
            step whose arm–arm clearance is below this buffer *and* closing — the arms spiralling into
            each other are stopped before contact, as the seed's node search did with its 175 mm
            threshold (0 = off).
        fallback: when Striving freezes, search SE(3) with RRT-Connect (dualpuma.fallback).
        fallback_params: parameters for that search (None = its defaults).
    """

    step: float = 0.05
    rot_step: float = math.radians(5.0)
    min_step: float = 0.005
    substeps: int = 5
    max_joint_step: float = math.radians(20.0)
    margin: float | None = None
    orientation: str = "slerp"
    alternates: tuple[tuple[float, float, float], ...] = SEED_ALTERNATES
    alternates_from: str = "refused"
    mapping: bool = False
    max_steps: int = 2000
    max_recoveries: int = 100
    step_time: float = 0.1
    twist_buffer: float = 0.0
    fallback: bool = False
    fallback_params: object | None = field(default=None)

    def __post_init__(self) -> None:
        def pos(name: str, v: float) -> None:
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ParameterError(f"StrivingParams.{name}: expected a finite value > 0, got {v!r}")

        for name in ("step", "rot_step", "min_step", "max_joint_step", "step_time"):
            pos(name, getattr(self, name))
        if self.min_step > self.step:
            raise ParameterError(f"StrivingParams.min_step ({self.min_step}) must be <= step ({self.step})")
        if not (isinstance(self.twist_buffer, (int, float)) and math.isfinite(self.twist_buffer) and self.twist_buffer >= 0):
            raise ParameterError(f"StrivingParams.twist_buffer: expected a finite value >= 0 [m], got {self.twist_buffer!r}")
        for name in ("substeps", "max_steps", "max_recoveries"):
            v = getattr(self, name)
            if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < 1:
                raise ParameterError(f"StrivingParams.{name}: expected an integer >= 1, got {v!r}")
        if self.margin is not None and not (math.isfinite(self.margin) and self.margin >= 0):
            raise ParameterError(f"StrivingParams.margin: expected None or a finite value >= 0 [m], got {self.margin!r}")
        if self.orientation not in _ORIENTATIONS:
            raise ParameterError(f"StrivingParams.orientation: expected one of {_ORIENTATIONS}, got {self.orientation!r}")
        if self.alternates_from not in ("refused", "current"):
            raise ParameterError(f"StrivingParams.alternates_from: expected 'refused' or 'current', got {self.alternates_from!r}")
        alts = np.asarray(self.alternates, dtype=float) if len(self.alternates) else np.zeros((0, 3))
        if alts.ndim != 2 or alts.shape[1] != 3 or not np.all(np.isfinite(alts)):
            raise ParameterError(f"StrivingParams.alternates: expected finite (x, y, z) offsets [m], got {self.alternates!r}")
        object.__setattr__(self, "alternates", tuple(tuple(float(v) for v in a) for a in alts))


class _Rows:
    """The growing plan (row 0 = start)."""

    def __init__(self, ctx: _Ctx, t_begin: float) -> None:
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

    def add_segment(self, seg: _Segment) -> None:
        names = self.ctx.world.pair_names
        for i in range(seg.n_acc):
            self.add(seg.P[i], seg.qL[i], seg.qR[i], seg.d[i], names[int(seg.idx[i])])

    def finish(self, status: str, reason: str, planner: str = "striving") -> Plan:
        P = np.array(self.T).reshape(-1, 4, 4)
        length = float(np.sum(np.linalg.norm(np.diff(P[:, :3, 3], axis=0), axis=1))) if len(P) > 1 else 0.0
        if reason:
            self.events.append(f"{status}: {reason}")
        n = len(P)
        return Plan(status, reason, P, np.array(self.qL).reshape(-1, 6), np.array(self.qR).reshape(-1, 6),
                    np.array(self.d), tuple(self.pair), np.arange(n) * self.ctx.p.step_time, tuple(self.events),
                    length, time.perf_counter() - self.t_begin, planner)


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

    Returns:
        :class:`~dualpuma.plan_io.Plan`. Bad input gives ``invalid_input`` / ``invalid_start`` /
        ``invalid_goal`` plans with a reason; only malformed ``params`` raise (ParameterError).
    """
    t_begin = time.perf_counter()
    params = StrivingParams() if params is None else params
    if not isinstance(params, StrivingParams):
        raise ParameterError(f"params: expected StrivingParams, got {type(params).__name__}")
    try:
        A = validate_pose(start, name="start")
        B = validate_pose(goal, name="goal")
        if A.shape != (4, 4) or B.shape != (4, 4):
            raise ParameterError("start and goal must be single poses of shape (4, 4)")
        world = World(cell) if world is None else world
        if world.cell is not cell:
            raise ParameterError("world: built from a different cell")
        world.reset()  # bit-identical results whatever the world computed before
        ctx = _Ctx(world, params)
        rpy_a = rpy_from_rot(A[:3, :3]) if start_rpy is None else _rpy(start_rpy, "start_rpy")
        rpy_b = rpy_from_rot(B[:3, :3]) if goal_rpy is None else _rpy(goal_rpy, "goal_rpy")
        if params.orientation == "rpy":
            for r, T, name in ((rpy_a, A, "start_rpy"), (rpy_b, B, "goal_rpy")):
                if not np.allclose(calc_rot(r), T[:3, :3], atol=1e-9):
                    raise ParameterError(f"{name}: its rotation differs from the pose's rotation")
        q0 = _start_joints(world, A, q_start)
    except DualpumaError as e:
        return _empty("invalid_input", str(e), t_begin)
    return _striving(ctx, A, rpy_a, q0, B, rpy_b, rng, t_begin)


def _rpy(v, name: str) -> FloatArray:
    a = np.asarray(v, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ParameterError(f"{name}: expected 3 finite angles [rad]")
    return a


def _start_joints(world: World, A: FloatArray, q_start) -> tuple[FloatArray, FloatArray]:
    cell = world.cell
    if q_start is not None:
        if len(q_start) != 2:
            raise ParameterError("q_start: expected (q_left, q_right)")
        return validate_joints(q_start[0], name="q_start[0]"), validate_joints(q_start[1], name="q_start[1]")
    home = (np.asarray(cell.left.q_home, float), np.asarray(cell.right.q_home, float))
    if np.allclose(A, cell.T_world_object_start, atol=1e-12):
        return home
    sol = solve_dual(world, A, home, max_step=2 * math.pi, check_clearance=False)
    if sol.q_left is None or sol.q_right is None:
        raise ParameterError(f"start: no IK solution on the home branches ({sol.reason})")
    return sol.q_left, sol.q_right


def _empty(status: str, reason: str, t_begin: float) -> Plan:
    return Plan(status, reason, np.zeros((0, 4, 4)), np.zeros((0, 6)), np.zeros((0, 6)), np.zeros(0), (), np.zeros(0),
                (f"{status}: {reason}",), 0.0, time.perf_counter() - t_begin)


def _striving(ctx: _Ctx, A, rpy_a, q0, B, rpy_b, rng, t_begin: float) -> Plan:
    w, p = ctx.world, ctx.p
    rows = _Rows(ctx, t_begin)
    d_start, k_start = w.min_distance(q0[0], q0[1], A, 0.0)
    rows.add(A, q0[0], q0[1], d_start, w.pair_names[k_start])
    hands = w.hand_poses(q0[0], q0[1])
    for s, H in zip(("left", "right"), hands):
        if not np.abs(H - A @ w.T_object_hand[s]).max() <= 1e-6:
            return rows.finish("invalid_start", f"{s} hand is not at its grasp of the start pose (q_start does not hold the bar)")
    for qq, side in zip(q0, ("left", "right")):
        lim = w.arms[side].limits
        if np.any(qq < lim[:, 0] - 1e-12) or np.any(qq > lim[:, 1] + 1e-12):
            return rows.finish("invalid_start", f"{side} arm start joints outside the joint limits")
    if d_start < ctx.margin:
        a, b = w.pair_names[k_start]
        return rows.finish("invalid_start", f"start clearance {d_start:.4f} m below {ctx.margin:.3f} m ({a} – {b})")
    if p.mapping and ctx.cell.obstacles and _in_grown(ctx, A[None, :3, 3], np.zeros(1))[0]:
        return rows.finish("invalid_start", "the object origin starts inside a grown obstacle (configuration mapping)")
    why = _goal_reason(ctx, B, q0)
    if why:
        return rows.finish("invalid_goal", why)

    cur, rpy_cur, q = A, rpy_a, q0
    visited: set = set()
    n_keyed = 0  # rows already in ``visited`` (keys are made only when an alternate is considered)
    recoveries = 0
    next_line = None  # the run on from a taken alternate, solved together with its approach
    while True:
        seg = _try_segment(ctx, cur, rpy_cur, q, B, rpy_b, len(rows.T) - 1, rows.d[-1], next_line)
        next_line = None
        rows.add_segment(seg)
        if seg.n_acc:
            cur, rpy_cur, q = seg.P[-1], seg.rpy[-1], (seg.qL[-1], seg.qR[-1])
        if seg.n_acc == seg.n:
            return rows.finish("reached", "")
        step_no = len(rows.T)
        if step_no - 1 >= p.max_steps:
            return _maybe_fallback(ctx, rows, q, B, rng, f"gave up after {p.max_steps} steps")
        aps = _alternates(ctx, cur, rpy_cur, B, rpy_b)
        if aps:  # every alternate's approach and the run on from it in one IK call; clearance in order
            _solve_chains(ctx, [(ap[3], ap[4]) for ap in aps], np.concatenate(q))
        took = ""
        tried: list[str] = []
        if aps:
            visited.update(_key(T) for T in rows.T[n_keyed:])
            n_keyed = len(rows.T)
        for name, T_ap, r_ap, line, onward in aps:
            if _key(T_ap) in visited:
                tried.append(f"{name} already visited")
                continue
            seg_ap = _try_segment(ctx, cur, rpy_cur, q, T_ap, r_ap, len(rows.T) - 1, rows.d[-1], line)
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


def _alternates(ctx: _Ctx, cur: FloatArray, rpy_cur, B: FloatArray, rpy_b) -> list:
    """The alternate positions from ``cur`` in order: (name, pose, rpy, line from cur, line on from
    there to B) each. Offsets apply to the refused point (the next step towards B) or to ``cur``
    (``alternates_from``)."""
    p = ctx.p
    if not p.alternates:
        return []
    if p.alternates_from == "refused":
        P_next, rpy_next = _line(ctx, cur, B, rpy_cur, rpy_b, _n_steps(ctx, cur, B, rpy_cur, rpy_b, p.step), 1)
        base, r_ap = P_next[0], rpy_next[0]
    else:
        base, r_ap = cur, rpy_cur
    out = []
    for j, off in enumerate(p.alternates):
        T_ap = base.copy()
        T_ap[:3, 3] = base[:3, 3] + np.asarray(off)
        name = f"AP{j + 1}" if p.alternates_from == "refused" else "up-and-over"
        line = _Line(ctx, cur, T_ap, rpy_cur, r_ap, p.step)
        out.append((name, T_ap, r_ap, line, _Line(ctx, line.P[-1], B, line.rpy[-1], rpy_b, p.step)))
    return out


def _goal_reason(ctx: _Ctx, B: FloatArray, q0) -> str:
    """Why the goal can never be reached on the start's branches: reach / joint limits ("" if it may be)."""
    w = ctx.world
    qs = []
    for k, s in enumerate(("left", "right")):
        arm = w.arms[s]
        T_bh = w.T_base_inv[s] @ B @ w.T_object_hand[s]
        if not arm.analytic:
            r = arm.ik(T_bh, q_near=q0[k])
            if not r.ok:
                return f"{s} arm cannot reach the goal: {r.reason}"
            qs.append(r.q)
            continue
        b = _branch_index(q0[k])
        sols, valid = puma._ik_all_scalar(T_bh, q0[k].tolist(), arm.limits[:, 0].tolist(), arm.limits[:, 1].tolist())
        ok = [c for c in (b, b ^ 1) if valid[c]]
        if not ok:
            why = "is outside its reach" if np.isnan(sols[b]).any() else "needs joints outside the limits on the start's branch"
            return f"{s} arm: the goal {why}"
        qs.append(sols[ok[0]])
    # Clearance at the goal is not judged here: it depends on the arrival time (moving obstacles)
    # and Striving reports a blocked goal as a refusal with its pair.
    return ""


def _branch_index(q: FloatArray) -> int:
    """``puma.branch_of`` for one trusted joint vector (plain floats)."""
    sh, el, flip = branch_signs(q)
    return 4 * (sh < 0) + 2 * (el < 0) + int(flip)


def _maybe_fallback(ctx: _Ctx, rows: _Rows, q, B, rng, reason: str) -> Plan:
    if not ctx.p.fallback:
        return rows.finish("frozen", reason)
    from .fallback import FallbackParams, rrt_connect

    fp = ctx.p.fallback_params if ctx.p.fallback_params is not None else FallbackParams()
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(0 if rng is None else rng)
    k0 = len(rows.T) - 1
    rows.events.append(f"step {k0}: Striving frozen ({reason}); fallback RRT-Connect in SE(3)")
    res = rrt_connect(ctx.world, rows.T[-1], q, B, fp, gen, t0=k0 * ctx.p.step_time, step_time=ctx.p.step_time,
                      striving=ctx.p)
    if not res.ok:
        return rows.finish("frozen", f"{reason}; fallback RRT-Connect failed: {res.reason}", "striving+rrt")
    for i in range(1, len(res.T_world_object)):
        d, k = ctx.world.min_distance(res.q_left[i], res.q_right[i], res.T_world_object[i], (k0 + i) * ctx.p.step_time)
        rows.add(res.T_world_object[i], res.q_left[i], res.q_right[i], d, ctx.world.pair_names[k])
    rows.events.append(f"fallback: {len(res.T_world_object) - 1} steps, {res.iterations} iterations")
    return rows.finish("reached", "", "striving+rrt")
