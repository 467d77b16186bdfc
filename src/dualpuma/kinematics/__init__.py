"""Kinematics of the arms: the PUMA 560's closed form, any URDF arm in Pinocchio, and the dual-arm
coordination of the held bar (eq. 5.6) with branch continuity.

May import: :mod:`dualpuma.lie`, :mod:`dualpuma.checks`, :mod:`dualpuma.errors`.
"""

from . import puma
from .arm import KNOWN_ROBOTS, Arm, Capsule, example_robot_data_dir
from .continuity import SINGULAR_Q5, continue_branch, continue_paths
from .dual import (
    DEFAULT_MAX_JOINT_STEP,
    SIDES,
    DualSolution,
    PathSolution,
    hands_from_object,
    solve_dual,
    solve_path,
)
from .ik import IKResult, IKStatus
from .puma import BRANCH_NAMES, fk, ik, ik_all

__all__ = [
    "BRANCH_NAMES",
    "DEFAULT_MAX_JOINT_STEP",
    "KNOWN_ROBOTS",
    "SIDES",
    "SINGULAR_Q5",
    "Arm",
    "Capsule",
    "DualSolution",
    "IKResult",
    "IKStatus",
    "PathSolution",
    "continue_branch",
    "continue_paths",
    "example_robot_data_dir",
    "fk",
    "hands_from_object",
    "ik",
    "ik_all",
    "puma",
    "solve_dual",
    "solve_path",
]
