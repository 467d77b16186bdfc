"""Joint velocity and acceleration limits for timing a plan (:func:`~.timing.time_plan`): given
ones, or each arm's defaults, and what is missing where an arm has none.

The PUMA 560 has no authoritative published per-joint velocity and acceleration table.
:data:`PUMA_QD_MAX` and :data:`PUMA_QDD_MAX` are the benchmark values of Lin, Chang & Luh (1983,
IEEE Trans. Automatic Control 28(12)), as quoted by Liu, Lai & Wu (2013, Robotics and
Computer-Integrated Manufacturing 29(2)), used throughout the time-optimal trajectory literature for
the PUMA: v = 100, 95, 100, 150, 130, 110 deg/s; a = 45, 40, 75, 70, 90, 80 deg/s^2. They are below
Unimation's 1977 design figures (waist 135 deg/s, wrist 360 deg/s, 1 g at the part). Other arms take
their URDF's velocity limits (``<limit velocity>``); a URDF gives no acceleration limits, so those
must be passed. Pass the real controller's limits when they are known.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..checks import as_array
from ..errors import ParameterError
from ..kinematics.dual import SIDES

__all__ = ["JOINT_LIMIT_RANGE", "LIMITS_SOURCE", "PUMA_QDD_MAX", "PUMA_QD_MAX", "missing_rate_limits", "rate_limits"]

FloatArray = npt.NDArray[np.float64]

#: nominal PUMA 560 joint velocity limits [rad/s] (Lin, Chang & Luh 1983; see the module docstring)
PUMA_QD_MAX = np.radians([100.0, 95.0, 100.0, 150.0, 130.0, 110.0])
#: nominal PUMA 560 joint acceleration limits [rad/s^2] (same source)
PUMA_QDD_MAX = np.radians([45.0, 40.0, 75.0, 70.0, 90.0, 80.0])
LIMITS_SOURCE = ("nominal PUMA 560 limits: Lin, Chang & Luh 1983 (IEEE TAC 28(12)) as quoted by Liu, Lai & Wu 2013 "
                 "(RCIM 29(2)); v = 100, 95, 100, 150, 130, 110 deg/s, a = 45, 40, 75, 70, 90, 80 deg/s^2")
JOINT_LIMIT_RANGE = (1e-3, 1e4)  #: the values a given v_max [rad/s] or a_max [rad/s^2] may take


def rate_limits(world, value, name: str) -> tuple[FloatArray, str]:
    """The (12,) limits (left arm then right arm) and where they come from: ``value`` if given (6
    values for both arms or 12), else per arm its default: the PUMA 560's nominal table, a
    velocity limit from the arm's URDF (``<limit velocity>``); no default acceleration but the PUMA's.

    Args:
        world: the cell's :class:`~dualpuma.model.world.World`.
        value: given limits or None.
        name: ``"v_max"`` [rad/s] or ``"a_max"`` [rad/s^2].

    Raises:
        ParameterError: given limits malformed, or none given where an arm has no default (the
            message says which arm and how to pass them).
    """
    if value is not None:
        arr = as_array(value, f"time_plan: {name}").ravel()
        if arr.shape == (6,):
            arr = np.tile(arr, 2)
        lo, hi = JOINT_LIMIT_RANGE
        if arr.shape != (12,) or not np.all(np.isfinite(arr)) or np.any(arr < lo) or np.any(arr > hi):
            raise ParameterError(f"time_plan: {name}: expected 6 or 12 finite values in [{lo:g}, {hi:g}] "
                                 f"({'rad/s' if name == 'v_max' else 'rad/s^2'})")
        return arr, "given"
    parts, sources = [], []
    for s in SIDES:
        arm = world.arms[s]
        if arm.robot == "puma560":
            parts.append(PUMA_QD_MAX if name == "v_max" else PUMA_QDD_MAX)
            sources.append(f"{s}: {LIMITS_SOURCE}")
            continue
        urdf_v = np.asarray(arm.model.velocityLimit, float)
        if name == "v_max" and urdf_v.shape == (6,) and np.all(np.isfinite(urdf_v)) and np.all(urdf_v > 0):
            parts.append(urdf_v)
            sources.append(f"{s}: {arm.robot} URDF velocity limits")
            continue
        what = "acceleration limits (a URDF has none)" if name == "a_max" else "velocity limits in its URDF"
        unit, flag = ("rad/s", "--v-max [deg/s]") if name == "v_max" else ("rad/s^2", "--a-max [deg/s^2]")
        raise ParameterError(f"time_plan: {name} is needed: the {s} arm ({arm.robot}) has no {what}; pass "
                             f"{name} [{unit}] (dualpuma plan: {flag}), 6 values for both arms or 12 (left, right)")
    return np.concatenate(parts), "; ".join(sources)


def missing_rate_limits(world) -> str:
    """Why a plan in this cell cannot be timed with the arms' default limits ("" if it can): the
    viewer, which has no box for them, says so instead of offering a timing that cannot be made."""
    for name in ("v_max", "a_max"):
        try:
            rate_limits(world, None, name)
        except ParameterError as exc:
            return str(exc).removeprefix("time_plan: ")
    return ""
