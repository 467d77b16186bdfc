"""Resolved position control of the held bar (the seed's eq. 5.6, procedure NexTran).

The object frame drives both hands through the rigid grasps::

    T_base_hand(rob, t) = inv(T_world_base(rob)) @ T_world_object(t) @ T_object_hand(rob)

(the printed eq. 5.6 omits ``inv(T_world_base)``; the seed's NexTran multiplies by ``Tinvrb`` first,
which is what is implemented). ``T_object_hand = inv(T_world_object(0)) @ T_world_base @
T_base_hand(0)`` is eq. 5.5.

:func:`solve_dual` solves both arms for one object pose with branch continuity; :func:`solve_path`
does a whole path in one call (vectorised IK for the PUMA).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from . import puma
from .branch_path import _SINGULAR_Q5, _wrapped_gap, _wrist_tracks, solve_path_branch
from .errors import ParameterError
from .puma import validate_joints, validate_pose

__all__ = [
    "DEFAULT_MAX_JOINT_STEP",
    "DualSolution",
    "PathSolution",
    "grasp_from_joints",
    "hands_from_object",
    "solve_dual",
    "solve_path",
]

FloatArray = npt.NDArray[np.float64]
SIDES = ("left", "right")
DEFAULT_MAX_JOINT_STEP = float(np.deg2rad(20.0))  #: the seed's RobMov step bound (20 deg) [rad]


def hands_from_object(cell, T_world_object: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Both hands' targets in their arms' base frames for object pose(s) (eq. 5.6).

    Args:
        cell: the Cell (bases and grasps).
        T_world_object: (4, 4) or (..., 4, 4) [m].

    Returns:
        ``(T_base_hand_left, T_base_hand_right)``, each shaped like ``T_world_object``.

    Raises:
        PoseError: malformed pose.
    """
    T = validate_pose(T_world_object, name="T_world_object")
    out = []
    for s in SIDES:
        Tb_inv = np.linalg.inv(np.asarray(getattr(cell, s).T_world_base, float))
        Toh = np.asarray(getattr(cell, f"grasp_{s}").T_object_hand, float)
        out.append(Tb_inv @ T @ Toh)
    return out[0], out[1]


def grasp_from_joints(T_world_object0: npt.ArrayLike, T_world_base: npt.ArrayLike, T_base_hand0: npt.ArrayLike) -> FloatArray:
    """Rigid grasp from an initial configuration (eq. 5.5): inv(T_wo(0)) @ T_wb @ T_bh(0)."""
    return np.linalg.inv(validate_pose(T_world_object0)) @ validate_pose(T_world_base) @ validate_pose(T_base_hand0)


@dataclass(frozen=True, slots=True)
class DualSolution:
    """Both arms' joints for one object pose.

    Attributes:
        ok: both arms solved, inside limits, no jump beyond ``max_step`` (and permitted, if checked).
        q_left, q_right: joints [rad] (6,) — the solution found even when ``ok`` is False because
            of a jump or collision; ``None`` when unreachable / outside the limits.
        status: per arm (left, right): ``ok``, ``unreachable``, ``joint_limits``, ``jump``,
            ``singular`` (a jump next to the wrist singularity) or ``collision``.
        reason: human-readable explanation of the first failure ("" when ok).
        jump: per arm the largest joint change from ``q_near`` [rad].
        clearance: minimum signed distance [m] if a World checked it, else NaN.
        pair: the closest pair's names when checked.
    """

    ok: bool
    q_left: FloatArray | None
    q_right: FloatArray | None
    status: tuple[str, str]
    reason: str
    jump: tuple[float, float]
    clearance: float = float("nan")
    pair: tuple[str, str] = ("", "")


def _pick(arm, T_bh: FloatArray, q_prev: FloatArray, branch: int | None):
    """One arm: keep the shoulder/elbow branch of ``q_prev`` (PUMA) or seed numeric IK with it.

    The wrist-flip label is ill-defined at q5 = 0: a path that passes through the wrist singularity
    continues on the partner solution (flip bit toggled) when that is the joint-space continuation,
    i.e. nearer to ``q_prev``. Away from q5 = 0 the partner is ~180 deg away in q4 and q6 and is
    never chosen, so the branch is kept.
    """
    if not arm.analytic:
        return arm.ik(T_bh, q_near=q_prev)
    b = branch if branch is not None else int(puma.branch_of(q_prev))
    first = puma.ik(T_bh, config=b, q_near=q_prev, limits=arm.limits)
    if branch is not None or abs(q_prev[4]) > 2 * _SINGULAR_Q5:
        return first  # far from the wrist singularity: the partner is never the continuation
    other = puma.ik(T_bh, config=b ^ 1, q_near=q_prev, limits=arm.limits)
    if other.ok and (not first.ok or _wrapped_gap(other.q, q_prev) < _wrapped_gap(first.q, q_prev)):
        return other
    return first


def solve_dual(
    world,
    T_world_object: npt.ArrayLike,
    q_near: tuple[npt.ArrayLike, npt.ArrayLike],
    *,
    max_step: float = DEFAULT_MAX_JOINT_STEP,
    check_clearance: bool = True,
    t: float = 0.0,
) -> DualSolution:
    """Solve both arms for one object pose, continuing the IK branches of ``q_near``.

    Args:
        world: a :class:`~dualpuma.world.World` (its cell gives bases and grasps).
        T_world_object: object pose (4, 4) [m].
        q_near: (q_left, q_right) of the previous step [rad]; their branches are kept.
        max_step: largest allowed change of any joint from ``q_near`` [rad]; a larger change is
            reported as a ``jump`` (or ``singular`` near q5 = 0), never hidden.
        check_clearance: also require clearance >= the cell's safety margin.
        t: time [s] for moving obstacles.

    Raises:
        PoseError, JointError: malformed input. ParameterError: max_step <= 0.
    """
    if not (max_step > 0 and np.isfinite(max_step)):
        raise ParameterError(f"max_step: expected a finite value > 0 [rad], got {max_step}")
    qn = [validate_joints(q, name=f"q_near[{i}]") for i, q in enumerate(q_near)]
    T_bh = hands_from_object(world.cell, T_world_object)
    qs: list[FloatArray | None] = []
    status: list[str] = []
    jumps: list[float] = []
    reason = ""
    for k, s in enumerate(SIDES):
        r = _pick(world.arms[s], T_bh[k], qn[k], None)
        if not r.ok:
            qs.append(None)
            status.append(r.status)
            jumps.append(float("nan"))
            reason = reason or f"{s} arm: {r.status}: {r.reason}"
            continue
        jump = float(np.max(np.abs(r.q - qn[k])))
        qs.append(r.q)
        jumps.append(jump)
        if jump > max_step:
            sing = min(abs(r.q[4]), abs(qn[k][4])) < _SINGULAR_Q5 and world.arms[s].analytic
            st = "singular" if sing else "jump"
            j = int(np.argmax(np.abs(r.q - qn[k]))) + 1
            status.append(st)
            reason = reason or (
                f"{s} arm: joint {j} would move {np.rad2deg(jump):.1f} deg in one step (max "
                f"{np.rad2deg(max_step):.1f} deg){' next to the wrist singularity' if sing else ''}"
            )
        else:
            status.append("ok")
    clearance, pair = float("nan"), ("", "")
    if all(st == "ok" for st in status) and check_clearance:
        c = world.clearance(qs[0], qs[1], T_world_object, t)
        clearance, pair = c.distance, c.pair
        if c.distance < world.cell.safety_margin:
            kinds = {world.geoms[g].side for g in _geom_ids(world, pair)} - {""}
            status = ["collision" if (s in kinds or not kinds) else "ok" for s in SIDES]
            reason = f"clearance {c.distance:.4f} m below the margin {world.cell.safety_margin:.3f} m ({pair[0]} – {pair[1]})"
    ok = all(st == "ok" for st in status)
    return DualSolution(ok, qs[0], qs[1], (status[0], status[1]), reason, (jumps[0], jumps[1]), clearance, pair)


def _geom_ids(world, pair: tuple[str, str]) -> list[int]:
    names = [g.name for g in world.geoms]
    return [names.index(n) for n in pair]


@dataclass(frozen=True, slots=True)
class PathSolution:
    """Both arms along a path of object poses.

    Attributes:
        q_left, q_right: (N, 6) joints [rad]; rows after the first failure are NaN.
        ok: (N,) per-step success (IK, limits, continuity).
        n_ok: number of leading steps that succeeded.
        status: per arm status of the first failing step (``ok`` if none failed).
        reason: explanation of the first failure ("" when all ok).
    """

    q_left: FloatArray
    q_right: FloatArray
    ok: npt.NDArray[np.bool_]
    n_ok: int
    status: tuple[str, str]
    reason: str


def solve_path(
    world,
    T_world_object: npt.ArrayLike,
    q_start: tuple[npt.ArrayLike, npt.ArrayLike],
    *,
    max_step: float = DEFAULT_MAX_JOINT_STEP,
    _trusted: bool = False,
) -> PathSolution:
    """Solve a whole path of object poses (N, 4, 4) in one call, keeping the start's branches.

    The PUMA path is vectorised: all 8 branches for all N poses at once, the start's branch
    selected, equivalent angles unwrapped along the path, then limits and jumps checked. Other arms
    run the numeric IK step by step. ``_trusted`` (internal: the planner's own validated poses and
    joints) skips input validation. Clearance is not checked here (see
    :func:`dualpuma.clearance.clearance_batch`).
    """
    if _trusted:
        T = T_world_object
        T_bh = tuple(world.T_base_inv[s] @ T @ world.T_object_hand[s] for s in SIDES)
    else:
        T = validate_pose(T_world_object, name="T_world_object").reshape(-1, 4, 4)
        T_bh = hands_from_object(world.cell, T)
    n = T.shape[0]
    pre = {}
    a_l, a_r = world.arms["left"], world.arms["right"]
    # (an empty path takes the general route below, which returns an empty solution)
    same = n > 0 and _trusted and a_l.analytic and a_r.analytic and np.array_equal(a_l.limits, a_r.limits)
    if same:  # the planner's case: one branch per arm, away from the wrist singularity
        fast = solve_path_branch(T_bh, q_start, a_l.limits, max_step)
        if fast is not None:
            return _path_solution(*fast)
    if same:
        # one vectorised IK call for both arms (halves the fixed per-call cost on short paths)
        qn = np.concatenate([np.broadcast_to(q_start[0], (n, 6)), np.broadcast_to(q_start[1], (n, 6))])
        sols2, valid2 = puma._ik_all_batch(np.concatenate([T_bh[0], T_bh[1]]), qn, a_l.limits)
        pre = {0: (sols2[:n], valid2[:n]), 1: (sols2[n:], valid2[n:])}
    qs = []
    oks = []
    status = ["ok", "ok"]
    reasons = []
    for k, s in enumerate(SIDES):
        arm = world.arms[s]
        q0 = q_start[k] if _trusted else validate_joints(q_start[k], name=f"q_start[{k}]")
        if arm.analytic:
            b = int(puma.branch_of(q0))
            if k in pre:
                sols, valid = pre[k]
            elif _trusted:
                sols, valid = puma._ik_all_trusted(T_bh[k], q0, arm.limits)
            else:
                sols, valid = puma.ik_all(T_bh[k], q_near=q0, limits=arm.limits)
            q, flipped = _wrist_tracks(sols[:, b], sols[:, b ^ 1], q0)
            chosen = np.where(flipped, b ^ 1, b)
            ok = valid[np.arange(n), chosen]
            reach = ~np.isnan(q).any(axis=1)
            # unwrap equivalent angles along the path from q0: cumulative 2 pi corrections
            qq = np.where(reach[:, None], q, 0.0)
            delta = np.diff(np.vstack([q0, qq]), axis=0)
            corr = -2 * np.pi * np.round(delta / (2 * np.pi))
            q_unw = qq + np.cumsum(corr, axis=0)
            inside = np.all((q_unw >= arm.limits[:, 0] - 1e-12) & (q_unw <= arm.limits[:, 1] + 1e-12), axis=1)
            ok &= reach & inside
            step = np.max(np.abs(np.diff(np.vstack([q0, q_unw]), axis=0)), axis=1)
            jumped = step > max_step
            ok &= ~jumped
            q = q_unw
            first = int(np.argmin(ok)) if not ok.all() else n
            if first < n:
                if not reach[first]:
                    st, why = "unreachable", "target outside the arm's reach"
                elif not inside[first]:
                    st, why = "joint_limits", "continuing the branch would leave the joint limits"
                else:
                    sing = abs(q[first, 4]) < _SINGULAR_Q5
                    st = "singular" if sing else "jump"
                    why = f"a joint would move {np.rad2deg(step[first]):.1f} deg in one step"
                status[k] = st
                reasons.append((first, f"{s} arm at step {first}: {st}: {why}"))
        else:
            q = np.full((n, 6), np.nan)
            ok = np.zeros(n, dtype=bool)
            prev = q0
            for i in range(n):
                r = arm.ik(T_bh[k][i], q_near=prev)
                if not r.ok or np.max(np.abs(r.q - prev)) > max_step:
                    status[k] = r.status if not r.ok else "jump"
                    reasons.append((i, f"{s} arm at step {i}: {status[k]}: {r.reason or 'joint jump'}"))
                    break
                q[i], ok[i], prev = r.q, True, r.q
        qs.append(q)
        oks.append(ok)
    both = oks[0] & oks[1]
    n_ok = int(np.argmin(both)) if not both.all() else n
    for q in qs:
        q[n_ok:] = np.nan
        q.setflags(write=False)
    both[n_ok:] = False
    reason = min(reasons)[1] if reasons else ""
    return PathSolution(qs[0], qs[1], both, n_ok, (status[0], status[1]), reason)


def _path_solution(Q: FloatArray, ok, first, status: list[str], why: list[str]) -> PathSolution:
    """A PathSolution from :func:`~dualpuma.branch_path.solve_path_branch`'s results."""
    n = Q.shape[0]
    n_ok = int(first.min())
    Q = Q.copy()
    Q[n_ok:] = np.nan
    Q.setflags(write=False)
    both = ok[0] & ok[1]
    both[n_ok:] = False
    fails = [(int(first[k]), f"{s} arm at step {int(first[k])}: {status[k]}: {why[k]}") for k, s in enumerate(SIDES) if first[k] < n]
    return PathSolution(Q[:, :6], Q[:, 6:], both, n_ok, (status[0], status[1]), min(fails)[1] if fails else "")
