"""Resolved position control of the held bar (the seed's eq. 5.6, procedure NexTran).

The object frame drives both hands through the rigid grasps::

    T_base_hand(rob, t) = inv(T_world_base(rob)) @ T_world_object(t) @ T_object_hand(rob)

(the printed eq. 5.6 omits ``inv(T_world_base)``; the seed's NexTran multiplies by ``Tinvrb`` first,
which is what is implemented). ``T_object_hand = inv(T_world_object(0)) @ T_world_base @
T_base_hand(0)`` is eq. 5.5.

:func:`solve_dual` solves both arms for one object pose with branch continuity; :func:`solve_path`
does a whole path in one call (vectorised IK for the PUMA, see :mod:`.continuity`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..checks import flag, has_attributes, joint_pair, real, validate_pose
from ..errors import JointError, ParameterError
from ..values import value_class
from . import puma
from .continuity import SINGULAR_Q5, continue_branch, continue_paths
from .providers import PumaIK

__all__ = [
    "CLOSURE_LEVER",
    "DEFAULT_MAX_JOINT_STEP",
    "GRASP_TOL",
    "SIDES",
    "DualSolution",
    "PathSolution",
    "bar_poses",
    "check_rows_hold_the_bar",
    "closed_arms",
    "closure_error",
    "hands_from_object",
    "pose_error",
    "solve_dual",
    "solve_path",
]

FloatArray = npt.NDArray[np.float64]
SIDES = ("left", "right")  #: the two arms, in the order of every (left, right) pair
DEFAULT_MAX_JOINT_STEP = float(np.deg2rad(20.0))  #: the seed's RobMov step bound (20 deg) [rad]
_ONE_PATH = np.zeros(1, dtype=np.int64)
CLOSURE_LEVER = 0.1  #: rotation errors count as the displacement of a point this far from the wrist centre [m]
GRASP_TOL = 1e-6  #: a plan's row holds the bar when each hand is this close to its grasp [m] (IK: ~1e-9)
_CLOSED_ARMS = "kinematics.closed_arms"  # WorldCache key
_CELL = ("left", "right", "grasp_left", "grasp_right")  # what a Cell has (this package may not import it)
_WORLD = ("cell", "arms", "T_base_inv", "T_object_hand", "clearance", "cache")  # likewise a World


def hands_from_object(cell, T_world_object: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Both hands' targets in their arms' base frames for object pose(s) (eq. 5.6).

    Args:
        cell: the Cell (bases and grasps).
        T_world_object: (4, 4) or (..., 4, 4) [m].

    Returns:
        ``(T_base_hand_left, T_base_hand_right)``, each shaped like ``T_world_object``.

    Raises:
        PoseError: malformed pose. ParameterError: ``cell`` is not a Cell.
    """
    has_attributes(cell, _CELL, "Cell", "cell")
    T = validate_pose(T_world_object, name="T_world_object")
    out = []
    for s in SIDES:
        Tb_inv = np.linalg.inv(np.asarray(getattr(cell, s).T_world_base, float))
        out.append(Tb_inv @ T @ np.asarray(getattr(cell, f"grasp_{s}").T_object_hand, float))
    return out[0], out[1]


@value_class
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
        world: a :class:`~dualpuma.model.world.World` (its cell gives bases and grasps).
        T_world_object: object pose (4, 4) [m].
        q_near: (q_left, q_right) of the previous step [rad]; their branches are kept.
        max_step: largest allowed change of any joint from ``q_near`` [rad]; a larger change is
            reported as a ``jump`` (or ``singular`` near q5 = 0), never hidden.
        check_clearance: also require clearance >= the cell's safety margin.
        t: time [s] for moving obstacles.

    Raises:
        PoseError, JointError: malformed input. ParameterError: not a World, max_step <= 0 or not
            finite, check_clearance not a bool, t not finite.
    """
    has_attributes(world, _WORLD, "World", "world")
    max_step = real(max_step, "max_step", lo=0.0, lo_open=True, unit="rad")
    check_clearance = flag(check_clearance, "check_clearance")
    t = real(t, "t", unit="s")
    qn = joint_pair(q_near, "q_near")
    T = validate_pose(T_world_object, name="T_world_object")
    if T.shape != (4, 4):
        raise JointError(f"T_world_object: solve_dual takes one pose (4, 4), got {T.shape}; use solve_path")
    T_bh = [world.T_base_inv[s] @ T @ world.T_object_hand[s] for s in SIDES]
    qs: list[FloatArray | None] = []
    status: list[str] = []
    jumps: list[float] = []
    reason = ""
    for k, s in enumerate(SIDES):
        r = continue_branch(world.arms[s], T_bh[k], qn[k])
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
            sing = min(abs(r.q[4]), abs(qn[k][4])) < SINGULAR_Q5 and world.arms[s].analytic
            st = "singular" if sing else "jump"
            j = int(np.argmax(np.abs(r.q - qn[k]))) + 1
            status.append(st)
            reason = reason or (
                f"{s} arm: joint {j} would move {jump:.4f} rad in one step (max "
                f"{max_step:.4f} rad){' next to the wrist singularity' if sing else ''}"
            )
        else:
            status.append("ok")
    clearance, pair = float("nan"), ("", "")
    if all(st == "ok" for st in status) and check_clearance:
        c = world.clearance(qs[0], qs[1], T, t)
        clearance, pair = c.distance, c.pair
        if c.distance < world.cell.safety_margin:
            kinds = {world.geometry(n).side for n in pair} - {""}
            status = ["collision" if (s in kinds or not kinds) else "ok" for s in SIDES]
            reason = (f"clearance {c.distance:.4f} m below the margin {world.cell.safety_margin:.3f} m "
                      f"({pair[0]} – {pair[1]})")
    ok = all(st == "ok" for st in status)
    return DualSolution(ok, qs[0], qs[1], (status[0], status[1]), reason, (jumps[0], jumps[1]), clearance, pair)


@value_class
@dataclass(frozen=True, slots=True)
class PathSolution:
    """Both arms along a path of object poses.

    Attributes:
        q_left, q_right: (N, 6) joints [rad] (read-only); rows after the first failure are NaN.
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
) -> PathSolution:
    """Solve a whole path of object poses (N, 4, 4) in one call, keeping the start's branches.

    Arms with a closed-form IK (PUMA, UR) are solved for all N poses at once on their start branch
    (then unwrapped, checked against the limits and the step bound:
    :func:`~dualpuma.kinematics.continuity.continue_paths`); other arms run their numeric IK pose by
    pose, seeded with the previous solution. Clearance is not
    checked here (see :func:`dualpuma.collision.clearance_batch`).

    Raises:
        PoseError, JointError: malformed input. ParameterError: not a World, max_step <= 0 or not
            finite.
    """
    has_attributes(world, _WORLD, "World", "world")
    max_step = real(max_step, "max_step", lo=0.0, lo_open=True, unit="rad")
    T = validate_pose(T_world_object, name="T_world_object").reshape(-1, 4, 4)
    q0 = joint_pair(q_start, "q_start")
    return solve_path_unchecked(world, T, q0, max_step)


def closed_arms(world) -> tuple[list[int], list, FloatArray, FloatArray, FloatArray]:
    """The arms of a World with a closed-form IK: ``(their indices into SIDES, IK providers, joint
    limits (A, 6, 2) [rad], inverse base poses (A, 1, 4, 4), grasps T_object_hand (A, 1, 4, 4))``,
    stacked for vectorised IK of both arms (:func:`solve_path_unchecked`; kept in ``world.cache``)."""

    def build():
        closed = [k for k, s in enumerate(SIDES) if world.arms[s].analytic]
        stack = [np.stack([getattr(world, a)[SIDES[k]] for k in closed]).reshape(-1, 1, 4, 4) if closed
                 else np.zeros((0, 1, 4, 4)) for a in ("T_base_inv", "T_object_hand")]
        limits = np.stack([world.arms[SIDES[k]].limits for k in closed]) if closed else np.zeros((0, 6, 2))
        for a in (limits, *stack):
            a.setflags(write=False)
        return closed, [world.arms[SIDES[k]].solver for k in closed], limits, stack[0], stack[1]

    return world.cache.shared(_CLOSED_ARMS, build)


def solve_path_unchecked(world, T: FloatArray, q0: tuple[FloatArray, FloatArray], max_step: float) -> PathSolution:
    """:func:`solve_path` for trusted input: poses (N, 4, 4), start joints (q_left, q_right) (6,)
    each, ``max_step`` > 0 [rad] (the planners' own validated data)."""
    n = T.shape[0]
    qs: list = [None, None]  # each arm's joints and ok flags (the closed-form arms' straight from their solver)
    oks: list = [None, None]
    status = ["ok", "ok"]
    fails: list[tuple[int, str]] = []
    closed, solvers, limits, base_inv, grasp = closed_arms(world)
    if closed and n:
        q, ok, first, reasons = continue_paths(
            solvers, base_inv @ T @ grasp, _ONE_PATH, np.stack([q0[k] for k in closed]), limits, max_step,
        )
        for i, k in enumerate(closed):
            qs[k], oks[k] = q[i], ok[i]
            st, why = reasons[i][0]
            if st != "ok":
                status[k] = st
                fails.append((int(first[i, 0]), f"{SIDES[k]} arm at step {int(first[i, 0])}: {st}: {why}"))
    for k in range(2):
        if qs[k] is None:
            qs[k], oks[k] = np.full((n, 6), np.nan), np.zeros(n, dtype=bool)
    for k, s in enumerate(SIDES):
        if k in closed:
            continue
        arm, prev = world.arms[s], q0[k]
        T_bh = world.T_base_inv[s] @ T @ world.T_object_hand[s]
        for i in range(n):
            r = arm.ik(T_bh[i], q_near=prev)
            if not r.ok or np.max(np.abs(r.q - prev)) > max_step:
                status[k] = r.status if not r.ok else "jump"
                fails.append((i, f"{s} arm at step {i}: {status[k]}: {r.reason or 'joint jump'}"))
                break
            qs[k][i], oks[k][i], prev = r.q, True, r.q
    both = oks[0] & oks[1]
    n_ok = int(np.argmin(both)) if not both.all() else n
    for q in qs:
        q[n_ok:] = np.nan
        q.setflags(write=False)
    both[n_ok:] = False
    return PathSolution(qs[0], qs[1], both, n_ok, (status[0], status[1]), min(fails)[1] if fails else "")


def bar_poses(world, Q: FloatArray) -> FloatArray:
    """The bar's poses ``T_world_object`` (K, 4, 4) held by the left hand at configurations Q
    (K, 12) (left joints first; the closed chain, eq. 5.3)."""
    return _hand_poses(world, "left", Q[:, :6]) @ np.linalg.inv(world.T_object_hand["left"])


# ----------------------------------------------------------------------------- closed chain
def _hand_poses(world, side: str, Q: FloatArray) -> FloatArray:
    arm = world.arms[side]
    # the PUMA's closed-form FK is vectorised; any other arm: Pinocchio FK of its own model
    T = puma.fk(Q) if isinstance(arm.solver, PumaIK) else arm.fk(Q).reshape(-1, 4, 4)
    return world.T_world_base[side] @ T


def closure_error(world, Q: FloatArray) -> FloatArray:
    """Closed-chain error of configurations Q (K, 12) (left then right joints) [m]: how far the
    right hand is from its grasp on the bar held by the left hand (position error plus
    :data:`CLOSURE_LEVER` times the rotation error), by FK of both arms."""
    HL = _hand_poses(world, "left", Q[:, :6])
    HR = _hand_poses(world, "right", Q[:, 6:])
    return pose_error(HR, HL @ (np.linalg.inv(world.T_object_hand["left"]) @ world.T_object_hand["right"]))


def pose_error(H: FloatArray, want: FloatArray) -> FloatArray:
    """How far poses H (K, 4, 4) are from ``want`` [m]: position error plus :data:`CLOSURE_LEVER`
    times the rotation angle."""
    c = (np.einsum("kij,kij->k", H[:, :3, :3], want[:, :3, :3]) - 1.0) / 2.0
    return np.linalg.norm(H[:, :3, 3] - want[:, :3, 3], axis=1) + CLOSURE_LEVER * np.arccos(np.clip(c, -1.0, 1.0))


def check_rows_hold_the_bar(world, P: FloatArray, Q: FloatArray, who: str) -> None:
    """Refuse rows whose joints Q (K, 12) do not hold the bar at poses P (K, 4, 4) in ``world``'s
    cell: a hand farther than :data:`GRASP_TOL` from its grasp (position error plus
    :data:`CLOSURE_LEVER` times the rotation error, by FK of each arm), as a plan of another cell,
    or rows edited in a file, would be.

    Raises:
        ParameterError: naming ``who``, the first such row, the hand and how far it is off [m].
    """
    for s, q in zip(SIDES, (Q[:, :6], Q[:, 6:])):
        err = pose_error(_hand_poses(world, s, q), P @ world.T_object_hand[s])
        bad = np.flatnonzero(~(err <= GRASP_TOL))
        if bad.size:
            k = int(bad[0])
            raise ParameterError(f"{who}: row {k} does not hold the bar in this World's cell: the {s} hand is "
                                 f"{err[k]:.7f} m off its grasp (a plan made for another cell, or edited rows?)")
