"""dualpuma: two PUMA 560 arms carrying one bar — kinematics, clearance, planning, viewer.

SI units inside (metres, radians); degrees and millimetres only at the UI edge.
"""

from __future__ import annotations

from . import puma
from .arm import KNOWN_ROBOTS, Arm, Capsule
from .batch import Problem, plan_many
from .cell import EXAMPLE_CELLS, Cell, example_cell, load_cell, save_cell
from .errors import CellError, DualpumaError, JointError, ParameterError, PoseError, RobotError
from .plan_io import Plan
from .planner import StrivingParams, plan
from .puma import BRANCH_NAMES, IKResult, fk, ik, ik_all
from .world import World

__version__ = "0.1.0"

__all__ = [
    "BRANCH_NAMES",
    "EXAMPLE_CELLS",
    "KNOWN_ROBOTS",
    "Arm",
    "Capsule",
    "Cell",
    "CellError",
    "DualpumaError",
    "IKResult",
    "JointError",
    "ParameterError",
    "Plan",
    "PoseError",
    "Problem",
    "RobotError",
    "StrivingParams",
    "World",
    "example_cell",
    "fk",
    "ik",
    "ik_all",
    "load_cell",
    "plan",
    "plan_many",
    "puma",
    "save_cell",
]
