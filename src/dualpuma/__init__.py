"""dualpuma: two PUMA 560 arms carrying one bar — kinematics, clearance, planning, viewer.

SI units inside (metres, radians); degrees and millimetres only at the UI edge.
"""

from __future__ import annotations

from . import puma
from .arm import KNOWN_ROBOTS, Arm, Capsule
from .cell import EXAMPLE_CELLS, Cell, example_cell, load_cell, save_cell
from .world import World
from .errors import CellError, DualpumaError, JointError, ParameterError, PoseError, RobotError
from .puma import BRANCH_NAMES, IKResult, fk, ik, ik_all
from .plan_io import Plan
from .planner import StrivingParams, plan
from .batch import Problem, plan_many

__version__ = "0.1.0"

__all__ = [
    "Arm",
    "BRANCH_NAMES",
    "Capsule",
    "Cell",
    "World",
    "load_cell",
    "example_cell",
    "EXAMPLE_CELLS",
    "save_cell",
    "CellError",
    "DualpumaError",
    "IKResult",
    "JointError",
    "KNOWN_ROBOTS",
    "ParameterError",
    "PoseError",
    "RobotError",
    "fk",
    "ik",
    "ik_all",
    "puma",
    "Plan",
    "Problem",
    "StrivingParams",
    "plan",
    "plan_many",
]
