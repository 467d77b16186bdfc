"""What an IK solver returns for one pose: :class:`IKResult` with a status from :class:`IKStatus`
(the same for the PUMA's closed form and the numeric solver)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["IKResult", "IKStatus"]

FloatArray = npt.NDArray[np.float64]


class IKStatus:
    """Status codes of :func:`ik` (plain strings, stable)."""

    OK = "ok"
    UNREACHABLE = "unreachable"
    JOINT_LIMITS = "joint_limits"


@dataclass(frozen=True, slots=True)
class IKResult:
    """Result of :func:`ik` for one pose.

    Attributes:
        q: joint angles [rad], shape (6,), read-only; ``None`` unless ``status == "ok"``.
        branch: branch index 0..7 (see :data:`BRANCH_NAMES`), or -1.
        status: ``"ok"``, ``"unreachable"`` or ``"joint_limits"``.
        reason: human-readable explanation when not ok.
        wrist_singular: True when |sin q5| < 1e-10 (q4 was taken from ``q_near``).
    """

    q: FloatArray | None
    branch: int
    status: str
    reason: str = ""
    wrist_singular: bool = False

    @property
    def ok(self) -> bool:
        return self.status == IKStatus.OK
