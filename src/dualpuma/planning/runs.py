"""Straight runs of the object frame for the Striving planner (:mod:`.striving`): interpolation,
batched permission checks (vectorised dual IK and batched clearance per chunk), step refinement on
joint jumps, and the twisting detector.

A *run* from pose A towards B is ``m`` steps of ``substeps`` poses each (:class:`Line`); both arms'
IK along all of them is one vectorised call (:func:`solve_lines`), their clearance one batched query
(:func:`permitted_prefix`), and :func:`try_segment` returns how many whole steps are permitted.
"""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import numpy.typing as npt

from ..collision.batch import min_clearance
from ..collision.seed import arm_arm_distance, bar_major_dimension, point_distance, twisting
from ..errors import ParameterError
from ..kinematics.bar_path import first_unfollowed
from ..kinematics.continuity import continue_paths
from ..kinematics.dual import SIDES, solve_path_unchecked
from ..lie import angle, n_steps, rpy_to_rot, slerp
from ..units import below_text
from .certify import between_clearance, certify_chords
from .interpolation import interpolate_object
from .params import MAX_RUN_POSES, checked_substeps
from .reach import motion_bounds

__all__ = ["Line", "RunContext", "Segment", "in_grown", "line_poses", "line_rotation", "n_line_steps", "pose_key",
           "pose_keys", "solve_chains", "solve_lines", "try_segment"]

FloatArray = npt.NDArray[np.float64]
_BOUNDS = "planning.run_bounds"  # WorldCache key
_ONE_START = np.zeros(1, dtype=np.int64)


class _Bounds:
    """What the runs need of a World beyond its queries (built once per World, read-only): both
    arms' limits and frames stacked for the vectorised IK."""

    def __init__(self, world) -> None:
        self.closed_form = all(world.arms[s].analytic for s in SIDES)
        self.solvers = [world.arms[s].solver for s in SIDES]
        self.limits = np.stack([world.arms[s].limits for s in SIDES])  # (2, 6, 2)
        self.base_inv = np.stack([world.T_base_inv[s] for s in SIDES])[:, None]  # (2, 1, 4, 4)
        self.object_hand = np.stack([world.T_object_hand[s] for s in SIDES])[:, None]


class RunContext:
    """One :func:`~.striving.plan` call's state: the World, the parameters and what follows from
    them (never shared between calls)."""

    def __init__(self, world, params, t0: float = 0.0) -> None:
        self.world = world
        self.cell = world.cell
        # the parameters as checked: at least one pose between steps, the bar's path checked every 25 mm / 2.5 deg
        sub = checked_substeps(params.substeps, params.step, params.rot_step)
        self.p = params if sub == params.substeps else dataclasses.replace(params, substeps=sub)
        self.t0 = t0  # time of the plan's first row [s]
        self.margin = world.covered(world.cell.safety_margin if params.margin is None else params.margin)
        fp = params.fallback_params if params.fallback else None
        if fp is not None and fp.margin is not None:  # refused up front, not when Striving first freezes
            world.covered(fp.margin, "fallback_params.margin")
        self.rho = bar_major_dimension(world.cell) if params.mapping else 0.0
        self.last_aa = math.nan  # arm–arm clearance of the last accepted step (twist detector)
        b = world.cache.shared(_BOUNDS, lambda: _Bounds(world))
        self.reach, self.v_max = motion_bounds(world)  # (12,) [m], [m/s]: see .certify
        self.closed_form, self.solvers = b.closed_form, b.solvers
        self.limits, self.base_inv, self.object_hand = b.limits, b.base_inv, b.object_hand
        self._rows: dict[int, FloatArray] = {}
        self._between: dict[int, tuple] = {}

    def step_rows(self, m: int) -> npt.NDArray[np.int64]:
        """Rows of the first ``m`` step poses in a run of ``substeps`` poses per step (read-only)."""
        rows = self._rows.get(m)
        if rows is None:
            rows = self._rows[m] = np.arange(1, m + 1) * self.p.substeps - 1
            rows.flags.writeable = False
        return rows

    def between_rows(self, m: int) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
        """Rows of the poses between the first ``m`` steps' poses, and the step each belongs to."""
        out = self._between.get(m)
        if out is None:
            sub = self.p.substeps
            fine = np.arange(m * sub)
            fine = fine[fine % sub != sub - 1]
            k = fine // sub
            fine.flags.writeable = k.flags.writeable = False
            out = self._between[m] = (fine, k)
        return out


def line_rotation(ctx: RunContext, A: FloatArray, B: FloatArray, rpy_a, rpy_b) -> float:
    """The turn of a run A -> B that its step count is first based on [rad]: the largest rpy
    increment (``rpy`` mode), else the rotation angle from A to B."""
    if ctx.p.orientation == "rpy":
        return float(np.max(np.abs(rpy_b - rpy_a)))
    return 0.0 if (A[:3, :3] == B[:3, :3]).all() else angle(A[:3, :3], B[:3, :3])


def n_line_steps(ctx: RunContext, A: FloatArray, B: FloatArray, rpy_a, rpy_b, step: float,
                 rot: float | None = None) -> int:
    """Steps of a run A -> B: no step longer than ``step`` [m] nor turning more than ``rot_step``
    (the rotation angle between consecutive step poses, whatever the orientation mode: the ``rpy``
    and ``puma`` interpolations do not turn at a constant rate, so the steps are counted on the
    poses themselves and increased until every step's angle is within ``rot_step``). ``rot``: the
    run's :func:`line_rotation` when the caller knows it (runs between the same orientations)."""
    dist = math.dist(A[:3, 3].tolist(), B[:3, 3].tolist())
    mode = ctx.p.orientation
    if rot is None:
        rot = line_rotation(ctx, A, B, rpy_a, rpy_b)
    m = n_steps(dist, rot, step, ctx.p.rot_step)
    if mode == "slerp" or rot == 0.0:
        return m
    for _ in range(32):
        R = np.concatenate([A[None, :3, :3], line_poses(ctx, A, B, rpy_a, rpy_b, m)[0][:, :3, :3]])
        cos = (np.einsum("kij,kij->k", R[:-1], R[1:]) - 1.0) / 2.0
        worst = float(np.arccos(np.clip(cos, -1.0, 1.0)).max())
        if worst <= ctx.p.rot_step + 1e-12:
            break
        m = max(m + 1, math.ceil(m * worst / ctx.p.rot_step))
    return m


def line_poses(ctx: RunContext, A: FloatArray, B: FloatArray, rpy_a, rpy_b, m: int,
               count: int | None = None) -> tuple[FloatArray, FloatArray]:
    """``m`` poses after A ending exactly at B, and their rpy angles (rpy mode; else zeros); with
    ``count``, only the first ``count`` of them."""
    n = m if count is None else count
    s = np.arange(1, n + 1) / m
    if ctx.p.orientation == "rpy":
        rpy = rpy_a + s[:, None] * (rpy_b - rpy_a)
        P = np.tile(np.eye(4), (n, 1, 1))
        P[:, :3, 3] = A[:3, 3] + s[:, None] * (B[:3, 3] - A[:3, 3])
        P[:, :3, :3] = rpy_to_rot(rpy)
        if n == m:
            P[-1, :3, :3] = B[:3, :3]
        return P, rpy
    if ctx.p.orientation == "slerp":
        return slerp(A, B, s), np.zeros((n, 3))
    return interpolate_object(A, B, m, ctx.p.orientation)[:n], np.zeros((n, 3))


class Line:
    """A candidate straight run: its poses (``m`` steps of ``substeps`` poses), their rpy angles,
    and both arms' IK along it (filled by :func:`solve_lines`): joints Q (n, 12), left then
    right, valid for the first ``n_ok`` poses (else ``reason``)."""

    __slots__ = ("P", "Q", "m", "n_ok", "reason", "rpy")

    def __init__(self, ctx: RunContext | None = None, A=None, B=None, rpy_a=None, rpy_b=None, step: float = 0.0,
                 rot: float | None = None):
        if ctx is not None:
            self.m = n_line_steps(ctx, A, B, rpy_a, rpy_b, step, rot)
            if self.m * ctx.p.substeps > MAX_RUN_POSES:
                raise ParameterError(
                    f"a straight run of {math.dist(A[:3, 3].tolist(), B[:3, 3].tolist()):.3f} m takes {self.m} steps of "
                    f"{ctx.p.substeps} checked poses, more than {MAX_RUN_POSES:,}: take a longer step or rot_step, or "
                    f"fewer substeps")
            self.P, self.rpy = line_poses(ctx, A, B, rpy_a, rpy_b, self.m * ctx.p.substeps)


def solve_lines(ctx: RunContext, lines: list[Line], q0: FloatArray) -> None:
    """Both arms' IK along every line from the joints ``q0`` (12,): one vectorised call for all of
    them when both arms have the closed form, else the general path solver per line."""
    if not ctx.closed_form:
        for ln in lines:
            sol = solve_path_unchecked(ctx.world, ln.P, (q0[:6], q0[6:]), ctx.p.max_joint_step)
            ln.Q, ln.n_ok = np.hstack([sol.q_left, sol.q_right]), sol.n_ok
            ln.reason = re.sub(r" at step \d+", "", sol.reason)
        return
    for ln, (Q, n_ok, reason) in zip(lines, _closed_form_paths(ctx, [ln.P for ln in lines], [1] * len(lines), q0)):
        ln.Q, ln.n_ok, ln.reason = Q, n_ok, reason


def _closed_form_paths(ctx: RunContext, parts: list[FloatArray], per_path: list[int], q0: FloatArray) -> list:
    """Both arms' closed-form IK along paths from ``q0`` (12,) in one vectorised call: the pose
    arrays ``parts`` one after another, each path made of the next ``per_path[i]`` of them. Per
    path (joints (n, 12), valid rows, reason)."""
    T = parts[0] if len(parts) == 1 else np.concatenate(parts)
    if len(per_path) == 1:
        starts = _ONE_START
    else:
        firsts, at = [], 0
        for P, k in zip(parts, [j for n in per_path for j in range(n)]):
            if k == 0:  # the first part of a path
                firsts.append(at)
            at += P.shape[0]
        starts = np.array(firsts, dtype=np.int64)
    T_bh = ctx.base_inv @ T[None] @ ctx.object_hand  # (2, M, 4, 4): both hands' targets
    q, _ok, first, reasons = continue_paths(ctx.solvers, T_bh, starts, q0.reshape(2, 6), ctx.limits, ctx.p.max_joint_step)
    Q = np.concatenate([q[0], q[1]], axis=1)  # (M, 12): left then right
    ends = starts[1:].tolist() + [T.shape[0]]
    out = []
    for li, (a, b) in enumerate(zip(starts.tolist(), ends)):
        fails = [(int(first[k, li]), f"{s} arm: {reasons[k][li][0]}: {reasons[k][li][1]}")
                 for k, s in enumerate(SIDES) if reasons[k][li][0] != "ok"]
        out.append((Q[a:b], int(first[:, li].min()), min(fails)[1] if fails else ""))
    return out


def solve_chains(ctx: RunContext, chains: list[tuple[Line, Line]], q0: FloatArray) -> None:
    """Solve (approach, continuation) pairs of lines in one IK call: each pair as one path from
    ``q0`` (the continuation starts where its approach ends, so it is solved exactly as it would
    be from the approach's last joints), then split back into the two lines."""
    if ctx.closed_form:
        solved = _closed_form_paths(ctx, [P for a, b in chains for P in (a.P, b.P)], [2] * len(chains), q0)
    else:
        joined = []
        for a, b in chains:
            ln = Line()
            ln.P = np.concatenate([a.P, b.P])
            joined.append(ln)
        solve_lines(ctx, joined, q0)
        solved = [(ln.Q, ln.n_ok, ln.reason) for ln in joined]
    for (a, b), (Q, n_ok, reason) in zip(chains, solved):
        n1 = a.P.shape[0]
        a.Q, b.Q = Q[:n1], Q[n1:]
        a.n_ok, a.reason = min(n_ok, n1), (reason if n_ok < n1 else "")
        b.n_ok, b.reason = max(n_ok - n1, 0), reason


def _permitted_prefix(ctx: RunContext, P: FloatArray, Q: FloatArray, n_ok: int, reason: str, q0: FloatArray,
                      t0: float, k_per_pose: float, d0: float):
    """How many leading poses of P (whole steps of ``substeps`` poses) are permitted, given both
    arms' joints along P (Q (n, 12), valid for the first ``n_ok`` poses, else ``reason``) from
    ``q0`` (12,) with clearance ``d0``; their clearances and the refusal reason.

    Clearance is queried at every step pose, and at a pose between steps only when a rigorous
    lower bound from its neighbouring step poses cannot already clear it
    (:func:`~.certify.between_clearance`).
    """
    w = ctx.world
    sub = ctx.p.substeps
    margin = ctx.margin
    n = P.shape[0]
    d = np.full(n, np.inf)
    idx = np.zeros(n, dtype=np.int64)
    m = n_ok // sub  # whole steps with IK
    if m == 0:
        return n_ok, d, idx, reason
    times = t0 + k_per_pose * np.arange(1, n + 1)
    coarse = ctx.step_rows(m)
    # the bar is placed by the left hand's chain: IK holds the grasp exactly, so no poses are passed
    d_c, idx[coarse] = min_clearance(w, Q[coarse], times[coarse])
    d[coarse] = d_c
    bad_c = d_c < margin
    if bad_c.any():  # poses after the first refused step pose cannot matter
        m = int(bad_c.argmax()) + 1
        coarse, d_c = coarse[:m], d_c[:m]
    # certified motion: the bar's path between consecutive step poses (the arms holding it) keeps the margin
    m_pose = m - int(bad_c[m - 1])
    # the motions' ends: q0 then the step poses, with their clearances and times (row 0 = the start)
    Qe = np.empty((m + 1, Q.shape[1]))
    Qe[0], Qe[1:] = q0, Q[coarse]
    de = np.empty(m + 1)
    de[0], de[1:] = d0, d_c
    te = np.empty(m + 1)
    te[0], te[1:] = t0, times[coarse]
    cert = certify_chords(w, Qe[: m_pose + 1], de[: m_pose + 1], te[: m_pose + 1], margin, ctx.reach, ctx.v_max,
                         closed_chain=True)
    cut = None
    if cert.n_ok < m_pose:
        m = cert.n_ok + 1
        coarse, d_c = coarse[:m], d_c[:m]
        cut = cert.n_ok * sub
        if cert.pair >= 0:
            idx[cut] = cert.pair
    if sub > 1:
        fine, k = ctx.between_rows(m)  # the poses between steps, and the step each belongs to
        d_f, p_f = between_clearance(w, Qe, de, te, Q[fine], times[fine], k, margin, ctx.reach, ctx.v_max)
        hit = p_f >= 0
        d[fine[hit]], idx[fine[hit]] = d_f[hit], p_f[hit]
    bad = d[: m * sub] < ctx.margin
    if ctx.p.mapping and ctx.cell.obstacles:
        bad |= in_grown(ctx, P[: m * sub, :3, 3], times[: m * sub])
    if cut is not None and not bad[:cut].any():
        return cut, d, idx, f"the motion into the step is not certified: {cert.reason}"
    if not bad.any():
        return (min(m * sub, n_ok)), d, idx, reason
    first = int(bad.argmax())
    if d[first] < ctx.margin:
        a, b = w.pair_names[idx[first]]
        reason = f"clearance {below_text(float(d[first]), ctx.margin)} m below {ctx.margin:.3f} m ({a} – {b})"
    else:
        reason = "object origin inside a grown obstacle (configuration mapping)"
    return first, d, idx, reason


def in_grown(ctx: RunContext, p: FloatArray, times: FloatArray) -> npt.NDArray[np.bool_]:
    """Configuration mapping: which object origins p (N, 3) [m] at times (N,) [s] are inside an
    obstacle grown by the bar's major dimension."""
    out = np.zeros(p.shape[0], dtype=bool)
    for ob in ctx.cell.obstacles:
        size = tuple(float(v) for v in np.atleast_1d(ob.size))
        if np.any(ob.velocity != 0):
            dist = np.array([point_distance(ob.shape, size, ob.pose_at(t), pi) for pi, t in zip(p, times)])
        else:
            dist = point_distance(ob.shape, size, ob.T_world_obstacle, p)
        out |= dist < ctx.rho
    return out


def _permitted_lazy(ctx: RunContext, ln: Line, q0: FloatArray, t0: float, dt: float, first: int, d0: float):
    """:func:`_permitted_prefix` over a solved line in two chunks (``first`` poses, then the rest):
    a refusal near the start (the common case after a recovery) costs only the first chunk's
    clearance queries. Only the permitted poses' clearances and pair indices are meaningful."""
    n = ln.P.shape[0]
    D, I = (None, None) if n else (np.zeros(0), np.zeros(0, dtype=np.int64))
    start, chunk, q = 0, max(1, first), q0
    while start < n:
        end = min(n, start + chunk)
        n_ik = min(max(ln.n_ok - start, 0), end - start)
        why = ln.reason if ln.n_ok < end else ""
        n_ok, d, idx, reason = _permitted_prefix(ctx, ln.P[start:end], ln.Q[start:end], n_ik, why, q,
                                                 t0 + start * dt, dt, d0)
        if start == 0 and (end == n or n_ok < end):  # one chunk decided it: its arrays are the answer
            return n_ok, d, idx, (reason if n_ok < end else "")
        if D is None:
            D, I = np.full(n, np.nan), np.zeros(n, dtype=np.int64)
        D[start : start + n_ok], I[start : start + n_ok] = d[:n_ok], idx[:n_ok]
        if n_ok < end - start:
            return start + n_ok, D, I, reason
        q = ln.Q[end - 1]
        d0 = float(d[n_ok - 1])
        start, chunk = end, n  # the first chunk survived: the rest in one go
    return n, D, I, ""


class Segment:
    """Result of trying to move from the current pose towards a target: the ``n_acc`` accepted
    steps' poses ``P``, rpy angles, joints, clearances and pair indices; ``n`` steps were asked
    for; ``reason`` tells why the rest was refused; ``line`` is the (solved) run tried."""

    __slots__ = ("P", "d", "idx", "line", "n", "n_acc", "qL", "qR", "reason", "rpy")


def try_segment(ctx: RunContext, A, rpy_a, q, B, rpy_b, k0: int, d0: float, line: Line | None = None) -> Segment:
    """Move A -> B in steps; returns how many whole steps are permitted (with refinement on jumps).
    ``q`` = (q_left, q_right) at A, ``d0`` the clearance there (step k0) [m]; ``line``: A -> B at
    the default step, already solved from q (see :func:`solve_lines`)."""
    p = ctx.p
    step = p.step
    sub = p.substeps
    q12 = np.concatenate(q)
    while True:
        if line is None:
            line = Line(ctx, A, B, rpy_a, rpy_b, step)
            solve_lines(ctx, [line], q12)
        P, rpy, m, Q = line.P, line.rpy, line.m, line.Q
        n_fine, d, idx, reason = _permitted_lazy(ctx, line, q12, ctx.t0 + k0 * p.step_time, p.step_time / sub, 2 * sub, d0)
        n_acc = n_fine // sub
        rows = ctx.step_rows(n_acc)
        # the seed's RobMov bound holds per step: refine the step when a joint would move too far
        Qs = Q[rows]
        if n_acc:
            Qp = np.empty_like(Qs)  # each step's previous joints
            Qp[0], Qp[1:] = q12, Qs[:-1]
            too_far = np.flatnonzero(np.abs(Qs - Qp).max(axis=1) > p.max_joint_step)
        else:
            too_far = rows
        if too_far.size and step > p.min_step:
            step = max(p.min_step, step / 2)
            line = None
            continue
        if too_far.size:
            n_acc = int(too_far[0])
            rows, Qs = rows[:n_acc], Qs[:n_acc]
            reason = f"a joint would move more than {p.max_joint_step:.4f} rad in one step"
        k, why = first_unfollowed(ctx.world, P, Q[:, :6], Q[:, 6:], q12, A, sub, n_acc)
        if k < n_acc:  # finer steps would not help: the same path swings a wrist or leaves a joint limit
            n_acc, rows, Qs = k, rows[:k], Qs[:k]
            reason = why
        if p.twist_buffer > 0 and n_acc and angle(A[:3, :3], B[:3, :3]) > 1e-9:
            n_acc, rows, reason = _twist_check(ctx, P, Q, rows, n_acc, reason)
            Qs = Qs[:n_acc]
        seg = Segment()
        seg.P, seg.rpy = P[rows], rpy[rows]
        seg.qL, seg.qR = Qs[:, :6], Qs[:, 6:]
        seg.d, seg.idx = d[rows], idx[rows]
        seg.n_acc, seg.n, seg.reason, seg.line = n_acc, m, reason, line
        return seg


def _twist_check(ctx: RunContext, P, Q, rows, n_acc: int, reason: str):
    """Twisting detector over the accepted steps (see StrivingParams.twist_buffer)."""
    buf = ctx.p.twist_buffer
    prev = ctx.last_aa
    for i, r in enumerate(rows[:n_acc]):
        d, pair = arm_arm_distance(ctx.world, Q[r, :6], Q[r, 6:], P[r])
        if twisting(prev, d, buf):
            why = (f"twisting collision ahead: arm–arm clearance {d:.4f} m ({pair[0]} – {pair[1]}) is inside the "
                   f"{buf:.3f} m buffer and closing by {prev - d:.4f} m per step while the bar rotates")
            ctx.last_aa = prev
            return i, rows[:i], why
        prev = d
    ctx.last_aa = prev
    return n_acc, rows, reason


def pose_key(T: FloatArray) -> tuple[int, ...]:
    """Visited-pose key: position to 1 mm, rotation matrix entries to 1e-3."""
    return _rounded_keys(T[None, :3])[0]


def pose_keys(Ts: list[FloatArray]) -> list[tuple[int, ...]]:
    """:func:`pose_key` of each pose in ``Ts`` (one vectorised rounding)."""
    return _rounded_keys(np.array(Ts)[:, :3]) if len(Ts) else []


def _rounded_keys(P: FloatArray) -> list[tuple[int, ...]]:
    """The keys of the poses' top rows P (K, 3, 4): position, then the rotation row by row."""
    k = np.round(np.concatenate((P[:, :, 3], P[:, :, :3].reshape(-1, 9)), axis=1) * 1e3).astype(np.int64)
    return list(map(tuple, k.tolist()))
