"""Branch continuity: following an arm's IK branch along a path of hand poses, or to one next pose.

An arm that moves keeps its IK branch (shoulder, elbow, wrist): a branch change would swing the arm
through a singular configuration. Along a path, each pose's closed-form solution on the start's
branch is unwrapped from the previous one (q +- 2 pi is the same arm, but the joint limits and the
joint's travel see the difference), then checked against the joint limits and the largest joint
change per pose. The first failure is reported with a status:

* ``unreachable`` — the pose is outside the arm's reach;
* ``joint_limits`` — continuing the branch leaves the joint limits;
* ``jump`` — a joint would move more than the step bound (``singular`` when next to q5 = 0).

The wrist-flip label is ill-defined at q5 = 0: a path through the wrist singularity continues on
the partner solution (flip bit toggled: q4 + pi, -q5, q6 + pi) when that is the nearer joint-space
continuation (:func:`wrist_tracks`). Away from q5 = 0 the partner is ~180 deg away in q4 and q6 and
is never chosen. Exactly at the singularity (|sin q5| < 1e-10) only q4 + q6 is defined and q4 is
taken from the start joints.

:func:`continue_paths` does this for arms with a closed-form IK (:mod:`.providers`: the PUMA, the
UR family) along many paths at once (one vectorised IK call per kind of arm: the planners' fast
path); :func:`continue_poses` for such arms at many poses at once, each from its own joints; and
:func:`continue_branch` for one arm (any provider) and one pose.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from ..checks import instance, validate_joints, validate_pose
from ..errors import JointError, PoseError
from .arm import Arm
from .ik import WRIST_SINGULAR, IKResult
from .limits import LIMIT_TOL
from .providers import wrist_partner

__all__ = ["SINGULAR_Q5", "continue_branch", "continue_paths", "continue_poses", "wrapped_gap", "wrist_tracks"]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

SINGULAR_Q5 = math.radians(5.0)  #: a jump within 5 deg of q5 = 0 is reported as ``singular`` [rad]
_TWO_PI = 2.0 * math.pi


def wrapped_gap(a: FloatArray, b: FloatArray) -> FloatArray:
    """Largest joint difference modulo 2 pi, over the last axis [rad] (NaN-propagating)."""
    return np.max(np.abs((a - b + np.pi) % _TWO_PI - np.pi), axis=-1)


def wrist_tracks(A: FloatArray, B: FloatArray, q0: FloatArray) -> tuple[FloatArray, BoolArray]:
    """Per pose, the continuation among a branch's solutions ``A`` (N, 6) and their wrist partners
    ``B`` (N, 6) (NaN rows = unreachable), starting from ``q0`` (6,).

    Returns ``(q (N, 6), on the partner (N,))``; the scan loops only over the poses where a switch
    is possible."""
    n = A.shape[0]
    with np.errstate(invalid="ignore"):
        # (unreachable NaN rows count as far: a switch never crosses them)
        far = not np.any(np.abs(A[:, 4]) <= 2 * SINGULAR_Q5) and abs(q0[4]) > 2 * SINGULAR_Q5
        # the partner differs by pi in q4 (mod 2 pi), so it is never nearer than a continuation that
        # moves every joint by less than pi / 2 (NaN gaps never switch either)
        smooth = not np.any(wrapped_gap(A, np.vstack([q0, A[:-1]])) >= 0.5 * np.pi)
    if far or smooth:
        return A, np.zeros(n, dtype=bool)
    with np.errstate(invalid="ignore"):
        dAA, dBB = wrapped_gap(A[1:], A[:-1]), wrapped_gap(B[1:], B[:-1])
        swA = wrapped_gap(B[1:], A[:-1]) < dAA  # on track A, B is the nearer continuation
        swB = wrapped_gap(A[1:], B[:-1]) < dBB
        cur = 1 if wrapped_gap(B[0], q0) < wrapped_gap(A[0], q0) and abs(q0[4]) <= SINGULAR_Q5 else 0
    track = np.empty(n, dtype=np.int64)
    last = 0
    for i in np.flatnonzero(swA | swB) + 1:
        if (swA if cur == 0 else swB)[i - 1]:
            track[last:i] = cur
            cur ^= 1
            last = i
    track[last:] = cur
    return np.where(track[:, None] == 0, A, B), track == 1


def continue_paths(
    solvers: list,
    T_bh: FloatArray,
    starts: npt.NDArray[np.int64],
    q0: FloatArray,
    limits: FloatArray,
    max_step: float,
) -> tuple[FloatArray, BoolArray, npt.NDArray[np.int64], list[list[tuple[str, str]]]]:
    """Arms with closed-form IK along several paths, each path starting from the same joints.

    Args:
        solvers: each arm's closed-form IK provider (:mod:`.providers`); arms with equal providers
            and limits are solved in one vectorised call.
        T_bh: hand targets in each arm's base frame, (A, M, 4, 4) [m]: A arms, the paths one after
            another (M poses in all). Trusted (validated poses).
        starts: (L,) first index of each path (``starts[0] == 0``, increasing).
        q0: (A, 6) start joints [rad]; each arm keeps their branch.
        limits: (A, 6, 2) joint limits [rad].
        max_step: largest joint change per pose [rad].

    Returns:
        ``(q (A, M, 6) unwrapped joints [rad], ok (A, M), first (A, L) index of each path's first
        failing pose relative to its start (its length if none), reasons)`` with ``reasons[a][l]``
        = (status, explanation) of arm a's first failure on path l (("ok", "") if none). Rows
        from a path's first failure on are not meaningful.
    """
    n_arms, M = T_bh.shape[0], T_bh.shape[1]
    L = starts.shape[0]
    ends = np.empty(L, dtype=np.int64)  # (np.append costs more than these)
    ends[:-1] = starts[1:]
    ends[-1] = M
    branches = [int(solvers[a].branch_of(q0[a])) for a in range(n_arms)]
    groups = _groups(solvers, limits)
    if len(groups) > 1:
        q, reach, h = np.empty((n_arms, M, 6)), np.empty((n_arms, M), dtype=bool), np.empty((n_arms, M))
    for group in groups:  # one IK call per kind of arm
        a0 = group[0]
        k = len(group)
        branch = np.repeat(np.array([branches[a] for a in group], dtype=np.int64), M)
        q_ref = np.repeat(q0[group], M, axis=0)
        qg, rg, hg = solvers[a0].ik_branch(T_bh[group].reshape(k * M, 4, 4), branch, q_ref, limits[a0])
        if len(groups) == 1:  # one kind of arm: the results as they are
            q, reach, h = qg.reshape(k, M, 6).copy(), rg.reshape(k, M), hg.reshape(k, M)
        else:
            q[group], reach[group], h[group] = qg.reshape(k, M, 6), rg.reshape(k, M), hg.reshape(k, M)
    start_q = q0[:, None]  # (A, 1, 6)
    prev = np.empty_like(q)
    prev[:, 1:] = q[:, :-1]
    prev[:, starts] = start_q
    delta = q - prev
    k = np.rint(delta * (1.0 / _TWO_PI))
    near = reach & (np.abs(q[..., 4]) <= 2 * SINGULAR_Q5)
    if (np.abs(q0[:, 4]) <= 2 * SINGULAR_Q5).any() or near.any():
        # the partner (pi away in q4) can only be the continuation where a path jumps by pi / 2 or
        # more between neighbours (see wrist_tracks); only such paths are tracked
        jump = np.abs(delta - _TWO_PI * k).max(axis=2) >= 0.5 * np.pi
        if jump.any():
            for arm in range(n_arms):
                for a, b in zip(starts, ends):
                    if jump[arm, a:b].any():
                        q[arm, a:b] = _track(solvers[arm], T_bh[arm, a:b], branches[arm], q0[arm], limits[arm],
                                             q[arm, a:b], reach[arm, a:b], h[arm, a:b])
            prev[:, 1:] = q[:, :-1]
            prev[:, starts] = start_q
            k = np.rint((q - prev) * (1.0 / _TWO_PI))
    turns = k.cumsum(axis=1)
    if L > 1:  # each path unwraps from q0: the cumulative corrections restart at every path's start
        before = np.zeros((n_arms, L, 6))
        before[:, 1:] = turns[:, starts[1:] - 1]
        turns -= before.repeat(ends - starts, axis=1)
    q_unw = q - _TWO_PI * turns
    lo, hi = limits[:, None, :, 0], limits[:, None, :, 1]
    inside = ((q_unw >= lo - LIMIT_TOL) & (q_unw <= hi + LIMIT_TOL)).all(axis=2)
    prev[:, 1:] = q_unw[:, :-1]
    prev[:, starts] = start_q
    step = np.abs(q_unw - prev).max(axis=2)
    ok = reach & inside & (step <= max_step)
    fail_at = np.where(ok, M, np.arange(M))
    first = np.minimum(np.minimum.reduceat(fail_at, starts, axis=1), ends) - starts  # (A, L)
    reasons: list[list[tuple[str, str]]] = []
    first_l, starts_l, ends_l = first.tolist(), starts.tolist(), ends.tolist()
    for arm in range(n_arms):
        row = []
        for li in range(L):
            i = first_l[arm][li]
            j = starts_l[li] + i
            if i == ends_l[li] - starts_l[li]:
                row.append(("ok", ""))
            elif not reach[arm, j]:
                row.append(("unreachable", "target not reachable on the arm's IK branch (a path keeps its branch; another may reach it)"))
            elif not inside[arm, j]:
                row.append(("joint_limits", "continuing the branch would leave the joint limits"))
            else:
                st = "singular" if abs(q_unw[arm, j, 4]) < SINGULAR_Q5 else "jump"
                row.append((st, f"a joint would move {step[arm, j]:.4f} rad in one step"))
        reasons.append(row)
    return q_unw, ok, first, reasons


def continue_poses(solvers: list, T_bh: FloatArray, q_near: FloatArray,
                   limits: FloatArray) -> tuple[FloatArray, BoolArray]:
    """Arms with closed-form IK at many hand poses, each pose continuing its own joints: what
    :func:`continue_branch` does for one pose, vectorised (one IK call per kind of arm).

    Args:
        solvers: each arm's closed-form IK provider; arms with equal providers and limits are
            solved in one call.
        T_bh: hand targets in each arm's base frame (A, M, 4, 4) [m]. Trusted.
        q_near: (A, M, 6) the joints each pose continues [rad]: their branch, the wrist partner where
            q5 is near 0 and the partner is the nearer, unwrapped to them.
        limits: (A, 6, 2) joint limits [rad].

    Returns:
        ``(q (A, M, 6) [rad], ok (A, M))``: ok where the pose is reached within the limits.
    """
    n_arms, M = T_bh.shape[0], T_bh.shape[1]
    q, ok = np.empty((n_arms, M, 6)), np.empty((n_arms, M), dtype=bool)
    near = math.sin(2.0 * SINGULAR_Q5)
    for group in _groups(solvers, limits):  # one IK call per kind of arm
        solver, lim = solvers[group[0]], limits[group[0]]
        T, qn = T_bh[group].reshape(-1, 4, 4), q_near[group].reshape(-1, 6)
        branch = solver.branches(qn)
        qg, reach, _ = solver.ik_branch(T, branch, qn, lim)
        qg -= _TWO_PI * np.rint((qg - qn) * (1.0 / _TWO_PI))
        swap = np.flatnonzero((np.abs(np.sin(qn[:, 4])) <= near) | (np.abs(np.sin(qg[:, 4])) <= near))
        if swap.size:  # near q5 = 0 the wrist's partner may be the continuation
            qs = qn[swap]
            qp, rp, _ = solver.ik_branch(T[swap], branch[swap] ^ 1, qs, lim)
            qp -= _TWO_PI * np.rint((qp - qs) * (1.0 / _TWO_PI))
            better = rp & (~reach[swap] | (np.abs(qp - qs).max(axis=1) < np.abs(qg[swap] - qs).max(axis=1)))
            qg[swap[better]], reach[swap[better]] = qp[better], True
        inside = ((qg >= lim[:, 0] - LIMIT_TOL) & (qg <= lim[:, 1] + LIMIT_TOL)).all(axis=1)
        q[group], ok[group] = qg.reshape(len(group), M, 6), (reach & inside).reshape(len(group), M)
    return q, ok


def _groups(solvers: list, limits: FloatArray) -> list[list[int]]:
    """Arms with equal IK providers and limits, grouped (indices)."""
    groups: list[list[int]] = []
    for a in range(len(solvers)):
        for g in groups:
            if solvers[g[0]] == solvers[a] and bool((limits[g[0]] == limits[a]).all()):  # (same shapes)
                g.append(a)
                break
        else:
            groups.append([a])
    return groups


def _track(solver, T: FloatArray, branch: int, q0: FloatArray, limits: FloatArray, q: FloatArray,
           reach: BoolArray, h: FloatArray) -> FloatArray:
    """One arm's path on its branch (``q``, raw) continued through q5 = 0 onto the wrist partner
    where that is the nearer continuation (:func:`wrist_tracks`)."""
    n = T.shape[0]
    qb, rb, _ = solver.ik_branch(T, np.full(n, wrist_partner(branch), dtype=np.int64), np.tile(q0, (n, 1)), limits)
    A = np.where(reach[:, None], q, np.nan)
    B = np.where((reach & rb)[:, None], qb, np.nan)
    B = np.where((h < WRIST_SINGULAR)[:, None], A, B)  # exactly singular: the two labels coincide
    return np.nan_to_num(wrist_tracks(A, B, q0)[0])


def continue_branch(arm, T_bh: FloatArray, q_prev: FloatArray) -> IKResult:
    """One arm's IK for its next hand pose ``T_bh`` (4, 4) [m], continuing the branch of ``q_prev``
    (6,) [rad]: a closed-form arm keeps its branch (and its wrist label, unless ``q_prev`` is near
    q5 = 0 and the partner is the nearer continuation); a numeric arm seeds its IK with ``q_prev``.

    Args:
        arm: a :class:`~dualpuma.kinematics.arm.Arm`.

    Raises:
        ParameterError: ``arm`` is not an Arm. PoseError, JointError: malformed ``T_bh``, ``q_prev``.
    """
    instance(arm, Arm, "arm")
    T_bh = validate_pose(T_bh, name="T_bh")
    q_prev = validate_joints(q_prev, name="q_prev")
    if T_bh.shape != (4, 4):
        raise PoseError(f"T_bh: expected one pose (4, 4), got {T_bh.shape}")
    if q_prev.shape != (6,):
        raise JointError(f"q_prev: expected one joint vector (6,), got {q_prev.shape}")
    if not arm.analytic:
        return arm.ik(T_bh, q_near=q_prev)
    b = arm.branch_of(q_prev)
    first = arm.ik(T_bh, config=b, q_near=q_prev)
    if abs(q_prev[4]) > 2 * SINGULAR_Q5:
        return first  # far from the wrist singularity: the partner is never the continuation
    other = arm.ik(T_bh, config=wrist_partner(b), q_near=q_prev)
    if other.ok and (not first.ok or wrapped_gap(other.q, q_prev) < wrapped_gap(first.q, q_prev)):
        return other
    return first
