"""Planning the held bar from a start pose to a goal: the seed's Striving planner as a pure
function (:func:`plan`), the SE(3) RRT-Connect fallback it hands over to, the frozen
:class:`Plan` they return (JSON/NPZ), batches (:func:`plan_many`), certified motion between
checked configurations (:mod:`.certify`) and timed trajectories for execution (:func:`time_plan`).

May import: :mod:`dualpuma.collision`, :mod:`dualpuma.kinematics`, :mod:`dualpuma.model` (and
lie, checks, files, errors).
"""

from .batch import Problem, plan_many
from .interpolation import interpolate_object, orientation_joints, robmov
from .params import ORIENTATIONS, SEED_ALTERNATES, UP_AND_OVER, FallbackParams, StrivingParams
from .plan import STATUSES, Plan, chain
from .rate_limits import PUMA_QD_MAX, PUMA_QDD_MAX
from .rrt import FallbackResult, rrt_connect
from .striving import plan
from .timing import time_plan, with_trajectory
from .trajectory import Trajectory

__all__ = [
    "ORIENTATIONS",
    "PUMA_QDD_MAX",
    "PUMA_QD_MAX",
    "SEED_ALTERNATES",
    "STATUSES",
    "UP_AND_OVER",
    "FallbackParams",
    "FallbackResult",
    "Plan",
    "Problem",
    "StrivingParams",
    "Trajectory",
    "chain",
    "interpolate_object",
    "orientation_joints",
    "plan",
    "plan_many",
    "robmov",
    "rrt_connect",
    "time_plan",
    "with_trajectory",
]
