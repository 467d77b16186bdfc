"""The teach pendant's motions, as pure functions of a World and a :class:`TeachPose`.

A teach pose is always one the two arms can hold the bar in: both hands on their grasps. Every
motion keeps it so:

* :func:`move_object` — the object (bar) frame to a new pose: both arms follow along the straight
  SE(3) path in steps of at most 10 mm / 2 deg, each arm on its own IK branch (eq. 5.6,
  ``solve_path``); refused as a whole if any step cannot be held.
* :func:`move_joint` — one joint of one arm to a new value (clamped into its limits): the object
  follows that hand and the *partner arm follows* by IK to keep its grasp, in steps of at most
  2 deg (finer where its wrist swings fast); where the partner cannot follow, the joint stops at
  the last value it can and says so (refused if it cannot move at all).
* :func:`jog_target` — the object pose after a Cartesian jog of the object or of one hand (the
  other hand follows): translations along world axes, rotations about the jogged frame's own axes.

Nothing here refuses a collision: the pendant shows it (red closest pair, a warning) and lets the
programmer move out of it. Results are :class:`Move` (a new pose or a refusal, and a message).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..checks import frozen_array
from ..kinematics import SIDES, continue_branch, solve_path
from ..lie import angle, n_steps, rpy_to_rot, slerp
from ..units import display_text

__all__ = ["JOINT_STEP", "ROT_STEP", "STOP_TOL", "TRANS_STEP", "Move", "TeachPose", "grasp_error", "home_pose", "jog_target",
           "move_joint", "move_object"]

FloatArray = npt.NDArray[np.float64]

TRANS_STEP = 0.01  #: largest translation between two solved poses of a teach move [m]
ROT_STEP = math.radians(2.0)  #: largest rotation between two solved poses [rad]
JOINT_STEP = math.radians(2.0)  #: largest joint change between two solved poses of a joint move [rad]
_MAX_JUMP = math.radians(20.0)  # a partner joint changing more than this in one step is a branch jump
#: a joint move the partner cannot follow stops within this of the last value it can [rad] (0.01 deg)
STOP_TOL = math.radians(0.01)


@dataclass(frozen=True, slots=True)
class TeachPose:
    """Both arms and the object they hold (read-only arrays).

    Attributes:
        q_left, q_right: (6,) joints [rad].
        T_object: (4, 4) object frame in the world [m].
    """

    q_left: FloatArray
    q_right: FloatArray
    T_object: FloatArray

    @classmethod
    def of(cls, q_left: npt.ArrayLike, q_right: npt.ArrayLike, T_object: npt.ArrayLike) -> TeachPose:
        return cls(frozen_array(q_left, (6,), "q_left"), frozen_array(q_right, (6,), "q_right"),
                   frozen_array(T_object, (4, 4), "T_object"))

    def q(self, side: str) -> FloatArray:
        return self.q_left if side == "left" else self.q_right


@dataclass(frozen=True, slots=True)
class Move:
    """The outcome of a teach motion: ``pose`` (None when refused) and a message for the user."""

    pose: TeachPose | None
    message: str
    #: why a move that was made stopped short of what was asked ("" if it did not): told as a warning
    short: str = ""

    @property
    def ok(self) -> bool:
        return self.pose is not None


def hand_in_world(world, side: str, q: npt.ArrayLike) -> FloatArray:
    """World pose (4, 4) of ``side``'s hand at joints ``q``."""
    return world.T_world_base[side] @ world.arms[side].fk(q)


def object_from_hand(world, side: str, q: npt.ArrayLike) -> FloatArray:
    """The object pose implied by ``side``'s hand holding its grasp (eq. 5.3)."""
    return hand_in_world(world, side, q) @ np.linalg.inv(world.T_object_hand[side])


def grasp_error(world, pose: TeachPose) -> dict[str, tuple[float, float]]:
    """Per hand: (distance [m], angle [rad]) between the hand and its grasp on the object."""
    out = {}
    for s in SIDES:
        H = hand_in_world(world, s, pose.q(s))
        G = pose.T_object @ world.T_object_hand[s]
        out[s] = (float(np.linalg.norm(H[:3, 3] - G[:3, 3])), angle(H[:3, :3], G[:3, :3]))
    return out


def home_pose(world) -> TeachPose:
    """The cell's home joints and start object pose."""
    c = world.cell
    return TeachPose.of(c.left.q_home, c.right.q_home, c.T_world_object_start)


def _mm_deg(T: FloatArray) -> str:
    p = T[:3, 3] * 1000.0
    return f"({p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f}) mm"


def move_object(world, pose: TeachPose, T_target: npt.ArrayLike) -> Move:
    """Both arms carry the object to ``T_target`` (see the module docstring)."""
    A, B = pose.T_object, np.asarray(T_target, dtype=np.float64)
    n = n_steps(float(np.linalg.norm(B[:3, 3] - A[:3, 3])), angle(A[:3, :3], B[:3, :3]), TRANS_STEP, ROT_STEP)
    if n > 2000:
        return Move(None, f"object move to {_mm_deg(B)} refused: more than 20 m or many turns away")
    path = slerp(A, B, np.arange(1, n + 1) / n)
    sol = solve_path(world, path, (pose.q_left, pose.q_right))
    if sol.n_ok < n:
        where = path[sol.n_ok]
        return Move(None, f"object move to {_mm_deg(B)} refused: {display_text(sol.reason)} (first unreachable pose at "
                          f"{_mm_deg(where)}); this move was not made")
    return Move(TeachPose.of(sol.q_left[-1], sol.q_right[-1], B), f"object moved to {_mm_deg(B)}")


def move_joint(world, pose: TeachPose, side: str, j: int, value: float) -> Move:
    """Joint ``j`` (0..5) of ``side`` to ``value`` [rad] (within its limits), the partner following
    on its IK branch (:func:`_follow`: steps of at most :data:`JOINT_STEP`, finer where its wrist
    swings fast). Where the partner cannot follow (its reach or limits, or its branch flips) the
    joint stops at the last value it can (to :data:`STOP_TOL`), as it stops at its own limit, and
    says so (a held arrow key or a value typed past that point moved nothing); a move that cannot
    start is refused."""
    partner = "right" if side == "left" else "left"
    lead = pose.q(side).copy()
    start = float(lead[j])
    n = max(1, math.ceil(abs(value - start) / JOINT_STEP - 1e-9))
    q_p, T = pose.q(partner), pose.T_object
    label = f"{side} q{j + 1} = {math.degrees(value):.1f} deg"
    for k in range(1, n + 1):
        x = start + (value - start) * k / n
        T_x, q_x, why = _follow(world, side, partner, lead, j, x, q_p)
        if T_x is None:
            hi = x  # the first value not followed; lead[j] is the last one followed
            while abs(hi - lead[j]) > STOP_TOL:
                mid = 0.5 * (float(lead[j]) + hi)
                T_m, q_m, _ = _follow(world, side, partner, lead, j, mid, q_p)
                if T_m is None:
                    hi = mid
                else:
                    lead[j], T, q_p = mid, T_m, q_m
            lo = float(lead[j])
            if abs(lo - start) <= STOP_TOL:
                return Move(None, f"{label} refused: the {partner} arm cannot follow to keep its grasp "
                                  f"({why}, at {math.degrees(x):.1f} deg); this move was not made")
            q = {side: lead, partner: q_p}
            return Move(TeachPose.of(q["left"], q["right"], T),
                        f"{side} q{j + 1} = {math.degrees(lo):.1f} deg; the {partner} arm followed",
                        f"{side} q{j + 1} stopped at {math.degrees(lo):.1f} deg of the {math.degrees(value):.1f} asked: "
                        f"the {partner} arm cannot follow beyond ({why})")
        lead[j], T, q_p = x, T_x, q_x
    q = {side: lead, partner: q_p}
    return Move(TeachPose.of(q["left"], q["right"], T), f"{label}; the {partner} arm followed")


def _follow(world, side: str, partner: str, lead: FloatArray, j: int, x: float, q_p: FloatArray):
    """``side``'s joints ``lead`` with joint ``j`` moved on to ``x`` [rad]: the object pose and the
    partner's joints continuing ``q_p`` on its branch, ``(T, q, "")``, or ``(None, None, why)``. A
    partner joint changing by more than :data:`_MAX_JUMP` is a flip of its branch only if it does so
    over a step of :data:`STOP_TOL`: a wrist swinging fast near its singularity is followed in
    halved steps (near q5 = 0 a 2 deg step of the other arm's q1 turned q4 by 30 deg)."""
    a = float(lead[j])
    q = lead.copy()
    q[j] = x
    T = object_from_hand(world, side, q)
    res = continue_branch(world.arms[partner], world.T_base_inv[partner] @ T @ world.T_object_hand[partner], q_p)
    if not res.ok:
        return None, None, display_text(res.reason)
    if float(np.max(np.abs(res.q - q_p))) <= _MAX_JUMP:
        return T, res.q, ""
    if abs(x - a) <= STOP_TOL:
        return None, None, "its IK branch would flip"
    mid = 0.5 * (a + x)
    T_m, q_m, why = _follow(world, side, partner, lead, j, mid, q_p)
    if T_m is None:
        return None, None, why
    q[j] = mid
    return _follow(world, side, partner, q, j, x, q_m)


def jog_target(world, pose: TeachPose, frame: str, axis: str, amount: float) -> FloatArray:
    """The object pose after jogging ``frame`` (``"object"``, ``"left"``, ``"right"``) along or
    about ``axis`` (``x y z`` [m] along world axes, ``rx ry rz`` [rad] about the frame's own axes)."""
    F = pose.T_object if frame == "object" else hand_in_world(world, frame, pose.q(frame))
    F2 = F.copy()
    if axis in ("x", "y", "z"):
        F2[:3, 3] += amount * np.eye(3)["xyz".index(axis)]
    else:
        rpy = np.zeros(3)
        rpy[("rx", "ry", "rz").index(axis)] = amount
        F2[:3, :3] = F[:3, :3] @ rpy_to_rot(rpy)
    T = F2 @ np.linalg.inv(F) @ pose.T_object
    T[3] = (0.0, 0.0, 0.0, 1.0)
    U, _, Vt = np.linalg.svd(T[:3, :3])  # re-orthonormalise (products of inverses drift ~1e-16)
    T[:3, :3] = U @ Vt
    return T
