"""What an IK solver returns for one pose: :class:`IKResult` with a status from :class:`IKStatus`
(the same for the PUMA's closed form and the numeric solver)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..values import value_class
from .limits import LIMIT_TOL

__all__ = ["BRANCH_NAMES", "QUIET_FAR_OUT", "WRIST_SINGULAR", "IKResult", "IKStatus", "select_branch"]

#: the eight branches of a closed-form IK in index order ``4 s + 2 e + w``
BRANCH_NAMES: tuple[str, ...] = tuple(
    f"{s}/{e}/{w}" for s in ("left", "right") for e in ("up", "down") for w in ("noflip", "flip")
)
WRIST_SINGULAR = 1e-10  #: |sin q5| below this: the wrist is singular

FloatArray = npt.NDArray[np.float64]


#: the public IK calls run under this: a target 1e200 m out overflows in a closed form's squares
#: (and in rounding it for a message), which then says unreachable all the same, and numpy must not
#: warn about it (a warning is an exception under -W error)
QUIET_FAR_OUT = np.errstate(over="ignore", invalid="ignore")


class IKStatus:
    """Status codes of :func:`ik` (plain strings, stable)."""

    OK = "ok"
    UNREACHABLE = "unreachable"
    JOINT_LIMITS = "joint_limits"
    #: a numeric IK found no solution: the pose is within the links' reach, and may still be
    #: reachable (its restarts can miss one; "unreachable" claimed it could not be reached)
    NOT_FOUND = "not_found"


@value_class
@dataclass(frozen=True, slots=True)
class IKResult:
    """Result of :func:`ik` for one pose.

    Attributes:
        q: joint angles [rad], shape (6,), read-only; ``None`` unless ``status == "ok"``.
        branch: branch index 0..7 (see :data:`BRANCH_NAMES`), or -1 (failed, or a numeric IK).
        status: ``"ok"``, ``"unreachable"``, ``"joint_limits"`` or, from a numeric IK,
            ``"not_found"`` (no solution found, which does not prove there is none).
        reason: human-readable explanation when not ok.
        wrist_singular: True when |sin q5| < 1e-10 (one wrist joint was taken from ``q_near``).
    """

    q: FloatArray | None
    branch: int
    status: str
    reason: str = ""
    wrist_singular: bool = False

    @property
    def ok(self) -> bool:
        return self.status == IKStatus.OK


def select_branch(sols: FloatArray, valid: npt.NDArray[np.bool_], branch: int | None, q_near: FloatArray | None,
                  limits: FloatArray, point: str) -> IKResult:
    """One pose's :class:`IKResult` from all its branches ``(sols (8, 6), valid (8,))``.

    Args:
        branch: the branch asked for (0..7), or None: the valid one nearest ``q_near`` (max-abs
            joint distance), the first valid one without ``q_near``.
        point: what must be reached, for the unreachable message (``"the wrist centre"``).
    """
    b = 0 if branch is None else branch
    if branch is None and valid.any():
        b = int(np.argmax(valid))  # the first valid branch
        if q_near is not None:
            with np.errstate(invalid="ignore"):
                dist = np.where(valid, np.max(np.abs(sols - np.asarray(q_near, dtype=np.float64)), axis=-1), np.inf)
            b = int(np.argmin(dist))
    q = sols[b]
    if valid[b]:
        q = q.copy()
        q.setflags(write=False)
        return IKResult(q, b, IKStatus.OK, wrist_singular=bool(abs(math.sin(q[4])) < WRIST_SINGULAR))
    if np.isnan(q).any():
        return IKResult(None, -1, IKStatus.UNREACHABLE, f"{point} is outside the arm's reach")
    bad = [i + 1 for i in range(6) if not limits[i, 0] - LIMIT_TOL <= q[i] <= limits[i, 1] + LIMIT_TOL]
    return IKResult(None, -1, IKStatus.JOINT_LIMITS,
                    f"branch {BRANCH_NAMES[b]} needs joint(s) {bad} outside their limits")
