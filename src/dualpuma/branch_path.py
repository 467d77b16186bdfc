"""The planner's fast path through :func:`dualpuma.coordination.solve_path`: both PUMAs, one branch.

Striving keeps each arm on the branch it starts on, so a straight run needs one of the eight
closed-form solutions per pose, not all of them. :func:`ik_branch` evaluates exactly that branch
for a stack of poses (both arms in one array, per-row branch signs); :func:`solve_path_branch`
then unwraps the angles along the path from the start joints and checks limits and per-step jumps
with the same rules, statuses and reasons as the general path.

Near the wrist singularity the continuation may swap to the wrist partner (see
:func:`_wrist_tracks`, shared with the general path); exactly at it (|sin q5| < 1e-10, where the
general path takes q4 from the previous joints) :func:`solve_path_branch` returns ``None``. It is internal and trusts its input (the planner's
own validated poses and joints); tests compare it with the general path and with Pinocchio.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from .puma_kernels import _GAMMA, _K_OFFSET, _REACH_TOL, _RHO3_SQ, A2, A3, D2, D4, _wrist_terms

FloatArray = npt.NDArray[np.float64]

_RHO3 = math.sqrt(_RHO3_SQ)
_CG, _SG = D4 / _RHO3_SQ, A3 / _RHO3_SQ
_TWO_PI = 2.0 * math.pi
_LIMIT_TOL = 1e-12  # [rad], as the general path
_SINGULAR_Q5 = math.radians(5.0)  # a jump within 5 deg of q5 = 0 is reported as "singular"
_WRIST_SING = 1e-10  # |sin q5| below this: exactly singular (the general path picks q4 from q_near)


def _wrapped_gap(a: FloatArray, b: FloatArray) -> FloatArray:
    """Largest joint difference modulo 2 pi, over the last axis [rad] (NaN-propagating)."""
    return np.max(np.abs((a - b + np.pi) % (2 * np.pi) - np.pi), axis=-1)


def _wrist_tracks(A: FloatArray, B: FloatArray, q0: FloatArray) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """Per pose, the continuation among a branch's solutions ``A`` (N, 6) and their wrist partners
    ``B`` (N, 6) (flip bit toggled; NaN rows = unreachable), starting from ``q0``.

    The wrist-flip label is ill-defined at q5 = 0: a path through the wrist singularity continues
    on the partner when that is the nearer joint-space continuation. Away from q5 = 0 the partner
    is ~180 deg away in q4 and q6 and never chosen. Returns ``(q (N, 6), on the partner (N,))``;
    the scan loops only over the poses where a switch is possible.
    """
    n = A.shape[0]
    with np.errstate(invalid="ignore"):
        # (unreachable NaN rows count as far, as in solve_lines_branch: a switch never crosses them)
        far = not np.any(np.abs(A[:, 4]) <= 2 * _SINGULAR_Q5) and abs(q0[4]) > 2 * _SINGULAR_Q5
        # the partner differs by pi in q4 (mod 2 pi), so it is never nearer than a continuation that
        # moves every joint by less than pi / 2 (NaN gaps never switch either)
        smooth = not np.any(_wrapped_gap(A, np.vstack([q0, A[:-1]])) >= 0.5 * np.pi)
    if far or smooth:
        return A, np.zeros(n, dtype=bool)
    with np.errstate(invalid="ignore"):
        dAA, dBB = _wrapped_gap(A[1:], A[:-1]), _wrapped_gap(B[1:], B[:-1])
        swA = _wrapped_gap(B[1:], A[:-1]) < dAA  # on track A, B is the nearer continuation
        swB = _wrapped_gap(A[1:], B[:-1]) < dBB
        cur = 1 if _wrapped_gap(B[0], q0) < _wrapped_gap(A[0], q0) and abs(q0[4]) <= _SINGULAR_Q5 else 0
    track = np.empty(n, dtype=np.int64)
    last = 0
    for i in np.flatnonzero(swA | swB) + 1:
        if (swA if cur == 0 else swB)[i - 1]:
            track[last:i] = cur
            cur ^= 1
            last = i
    track[last:] = cur
    return np.where(track[:, None] == 0, A, B), track == 1


def branch_signs(q: FloatArray) -> tuple[float, float, bool]:
    """(shoulder sign of r, elbow sign, wrist flipped) of one joint vector, as ``puma.branch_of``."""
    q2, q3, q5 = float(q[1]), float(q[2]), float(q[4])
    r = A2 * math.cos(q2) + A3 * math.cos(q2 + q3) - D4 * math.sin(q2 + q3)
    return (-1.0 if r < 0 else 1.0), (-1.0 if math.cos(_GAMMA - q3) < 0 else 1.0), math.sin(q5) < 0


def ik_branch(T: FloatArray, s_sh: FloatArray, s_el: FloatArray, flip: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Closed-form IK on one branch per pose.

    Args:
        T: target ``T_base_wrist`` poses (M, 4, 4) [m].
        s_sh, s_el: (M,) +1 / -1 shoulder and elbow signs (see :func:`branch_signs`).
        flip: (M,) bool, wrist flipped.

    Returns:
        ``(q, reach, h)``: raw angles (M, 6) [rad] (not wrapped into any range), (M,) reachability
        and |sin q5| (M,). Unreachable rows hold finite garbage; where h ~ 0 (the wrist singularity)
        q4 is arbitrary.
    """
    r00, r01, r02, px, r10, r11, r12, py, r20, r21, r22, pz = T.reshape(-1, 16).T[:12]
    rho2 = px * px + py * py
    disc1 = rho2 - D2 * D2
    K = (rho2 + pz * pz - _K_OFFSET) * (0.5 / A2)
    disc3 = _RHO3_SQ - K * K
    reach = (disc1 > -_REACH_TOL) & (disc3 > -_REACH_TOL)
    q = np.empty((6, px.shape[0]))
    r = s_sh * np.sqrt(np.maximum(disc1, 0.0))
    q[0] = np.arctan2(py, px) - np.arctan2(D2, r)
    inv = 1.0 / np.where(rho2 > 0.0, rho2, 1.0)
    c1 = (r * px + D2 * py) * inv
    s1 = (r * py - D2 * px) * inv
    sq = s_el * np.sqrt(np.maximum(disc3, 0.0))
    q[2] = _GAMMA - np.arctan2(K, sq)
    P = A2 * (_CG * sq + _SG * K) + A3
    Q = A2 * (_SG * sq - _CG * K) - D4
    ys = Q * r - P * pz
    xs = P * r + Q * pz
    q[1] = np.arctan2(ys, xs) - q[2]
    n23 = 1.0 / np.hypot(ys, xs)
    c23, s23 = xs * n23, ys * n23
    w00, w01, w02, w10, w11, w12, w22 = _wrist_terms(c1, s1, c23, s23, (r00, r01, r02, r10, r11, r12, r20, r21, r22))
    h = np.hypot(w02, w12)
    inv_h = 1.0 / np.where(h > 0.0, h, 1.0)
    c4, s4 = -w02 * inv_h, -w12 * inv_h
    f = np.where(flip, math.pi, 0.0)
    q[3] = np.arctan2(-w12, -w02) + f
    q[4] = np.where(flip, -1.0, 1.0) * np.arctan2(h, w22)
    q[5] = np.arctan2(-s4 * w00 + c4 * w10, -s4 * w01 + c4 * w11) + f
    return q.T, reach, h


def solve_path_branch(T_bh: tuple[FloatArray, FloatArray], q0: tuple[FloatArray, FloatArray], limits: FloatArray,
                      max_step: float):
    """Both PUMAs along one path, each on its start branch (continued through the wrist
    singularity onto the partner solution, as the general path does).

    Args:
        T_bh: each arm's hand targets in its base frame (N, 4, 4) [m].
        q0: start joints (left, right) (6,) [rad].
        limits: joint limits shared by both arms (6, 2) [rad].
        max_step: largest joint change per pose [rad].

    Returns:
        ``(Q (N, 12) left then right joints [rad], ok (2, N), first (2,) first failing index or N,
        status, why)`` (per arm where paired), or ``None`` when a pose is exactly wrist-singular
        (left to the general path). Rows from the first failure on are not meaningful.
    """
    out = solve_lines_branch(T_bh, np.zeros(1, dtype=np.int64), q0, limits, max_step)
    return None if out is None else out[0]


def solve_lines_branch(T_bh: tuple[FloatArray, FloatArray], starts: npt.NDArray[np.int64],
                       q0: tuple[FloatArray, FloatArray], limits: FloatArray, max_step: float):
    """:func:`solve_path_branch` for several paths from the same start joints, in one IK call.

    ``T_bh`` (left, right; or an array (2, M, 4, 4)) holds the paths one after another (M poses); ``starts`` (L,) are their first
    indices (``starts[0] == 0``). Returns a list of L per-path results as
    :func:`solve_path_branch`'s (views), or ``None`` if any pose is exactly wrist-singular.
    """
    M = T_bh[0].shape[0]
    (s0, e0, f0), (s1, e1, f1) = branch_signs(q0[0]), branch_signs(q0[1])
    sh, el, fl = np.empty(2 * M), np.empty(2 * M), np.empty(2 * M, dtype=bool)
    sh[:M], sh[M:], el[:M], el[M:], fl[:M], fl[M:] = s0, s1, e0, e1, f0, f1
    q, reach, h = ik_branch(np.reshape(T_bh, (2 * M, 4, 4)), sh, el, fl)
    q, reach = q.reshape(2, M, 6), reach.reshape(2, M)
    L = starts.shape[0]
    ends = np.append(starts[1:], M) if L > 1 else np.array([M])
    start_q = np.array([q0[0], q0[1]])[:, None]  # (2, 1, 6)
    # each path unwraps from q0: cumulative 2 pi corrections restarted at every path's start
    # (unreachable rows hold finite values; they fail on ``reach`` below)
    prev = np.empty_like(q)
    prev[:, 1:] = q[:, :-1]
    prev[:, starts] = start_q
    delta = q - prev
    k = np.rint(delta * (1.0 / _TWO_PI))
    near = reach & (np.abs(q[..., 4]) <= 2 * _SINGULAR_Q5)
    if abs(q0[0][4]) <= 2 * _SINGULAR_Q5 or abs(q0[1][4]) <= 2 * _SINGULAR_Q5 or near.any():
        if (reach.ravel() & (h < _WRIST_SING)).any():
            return None
        # the partner (pi away in q4) can only be the continuation where a path jumps by pi / 2 or
        # more between neighbours (see _wrist_tracks); only such paths are tracked
        jump = np.abs(delta - _TWO_PI * k).max(axis=2) >= 0.5 * np.pi
        if jump.any():
            for arm in range(2):
                for a, b in zip(starts, ends):
                    if jump[arm, a:b].any():
                        A = np.where(reach[arm, a:b, None], q[arm, a:b], np.nan)
                        B = A + (0.0, 0.0, 0.0, math.pi, 0.0, math.pi)
                        B[:, 4] = -A[:, 4]
                        q[arm, a:b] = np.nan_to_num(_wrist_tracks(A, B, q0[arm])[0])
            prev[:, 1:] = q[:, :-1]
            prev[:, starts] = start_q
            k = np.rint((q - prev) * (1.0 / _TWO_PI))
    turns = k.cumsum(axis=1)
    if L > 1:
        before = np.zeros((2, L, 6))
        before[:, 1:] = turns[:, starts[1:] - 1]
        turns -= before.repeat(ends - starts, axis=1)
    q_unw = q - _TWO_PI * turns
    inside = ((q_unw >= limits[:, 0] - _LIMIT_TOL) & (q_unw <= limits[:, 1] + _LIMIT_TOL)).all(axis=2)
    prev[:, 1:] = q_unw[:, :-1]
    prev[:, starts] = start_q
    step = np.abs(q_unw - prev).max(axis=2)
    ok = reach & inside & (step <= max_step)
    if L == 1:
        first = np.where(ok.all(axis=1), M, ok.argmin(axis=1))[:, None]
    else:
        fail_at = np.where(ok, M, np.arange(M))
        first = np.minimum(np.minimum.reduceat(fail_at, starts, axis=1), ends) - starts  # (2, L)
    Q = np.concatenate([q_unw[0], q_unw[1]], axis=1)  # (M, 12): left then right joints
    out = []
    for li, (a, b) in enumerate(zip(starts, ends)):
        n = b - a
        status, why = ["ok", "ok"], ["", ""]
        for k in range(2):
            i = int(first[k, li])
            if i == n:
                continue
            j = a + i
            if not reach[k, j]:
                status[k], why[k] = "unreachable", "target outside the arm's reach"
            elif not inside[k, j]:
                status[k], why[k] = "joint_limits", "continuing the branch would leave the joint limits"
            else:
                status[k] = "singular" if abs(q_unw[k, j, 4]) < _SINGULAR_Q5 else "jump"
                why[k] = f"a joint would move {np.rad2deg(step[k, j]):.1f} deg in one step"
        out.append((Q[a:b], ok[:, a:b], first[:, li], status, why))
    return out
