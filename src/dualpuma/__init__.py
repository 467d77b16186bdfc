"""dualpuma: two PUMA 560 arms carrying one bar — kinematics, clearance, planning, viewer.

SI units inside (metres, radians); degrees and millimetres only at the UI edge. The curated API is
listed in ``__all__``; the subpackages are ``kinematics``, ``model``, ``collision``, ``planning``,
``envelope``, ``scenarios``, ``viewer`` and ``cli`` (docs/architecture.md).
"""

from __future__ import annotations

from .errors import (
    CellError,
    CellFileError,
    DualpumaError,
    FileError,
    JointError,
    ParameterError,
    PoseError,
    RobotError,
)
from .kinematics import puma
from .kinematics.arm import KNOWN_ROBOTS, Arm, Capsule
from .kinematics.ik import IKResult
from .kinematics.puma import BRANCH_NAMES, fk, ik, ik_all
from .model.cell import Cell
from .model.cell_file import EXAMPLE_CELLS, example_cell, load_cell, save_cell
from .model.world import World
from .planning.batch import Problem, plan_many
from .planning.params import FallbackParams, StrivingParams
from .planning.plan import Plan
from .planning.striving import plan

__version__ = "0.2.0"

__all__ = [
    "BRANCH_NAMES",
    "EXAMPLE_CELLS",
    "KNOWN_ROBOTS",
    "Arm",
    "Capsule",
    "Cell",
    "CellError",
    "CellFileError",
    "DualpumaError",
    "FallbackParams",
    "FileError",
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
