"""Kinematics of the arms: the PUMA 560's and the UR family's closed forms, any 6-DOF URDF arm in
Pinocchio (numeric IK), IK providers, capsules from URDFs, and the dual-arm coordination of the
held bar (eq. 5.6) with branch continuity.

May import: :mod:`dualpuma.lie`, :mod:`dualpuma.checks`, :mod:`dualpuma.errors`.
"""

from . import puma, ur
from .arm import KNOWN_ROBOTS, Arm, Capsule, RobotSpec
from .capsules import fit_capsule
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
from .providers import URIK, NumericIK, PumaIK
from .puma import BRANCH_NAMES, fk, ik, ik_all
from .urdf import example_robot_data_dir

__all__ = [
    "BRANCH_NAMES",
    "DEFAULT_MAX_JOINT_STEP",
    "KNOWN_ROBOTS",
    "SIDES",
    "SINGULAR_Q5",
    "URIK",
    "Arm",
    "Capsule",
    "DualSolution",
    "IKResult",
    "IKStatus",
    "NumericIK",
    "PathSolution",
    "PumaIK",
    "RobotSpec",
    "continue_branch",
    "continue_paths",
    "example_robot_data_dir",
    "fit_capsule",
    "fk",
    "hands_from_object",
    "ik",
    "ik_all",
    "puma",
    "solve_dual",
    "solve_path",
    "ur",
]
