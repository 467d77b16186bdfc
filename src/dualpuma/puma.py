"""Deprecated: ``dualpuma.puma`` moved to :mod:`dualpuma.kinematics.puma` (the PUMA 560's kinematics).

This module re-exports the old names for one release and will then be removed; import from
:mod:`dualpuma.kinematics.puma` (or the top-level ``dualpuma``) instead.
"""

import warnings

from .checks import validate_joints, validate_pose
from .kinematics.ik import IKResult, IKStatus
from .kinematics.puma import (
    A2,
    A3,
    BRANCH_NAMES,
    D2,
    D4,
    D_FLANGE,
    JOINT_LIMITS,
    SHOULDER_HEIGHT,
    branch_of,
    config_to_branch,
    fk,
    ik,
    ik_all,
)

__all__ = ['A2', 'A3', 'BRANCH_NAMES', 'D2', 'D4', 'D_FLANGE', 'JOINT_LIMITS', 'SHOULDER_HEIGHT', 'IKResult', 'IKStatus', 'branch_of', 'config_to_branch', 'fk', 'ik', 'ik_all', 'validate_joints', 'validate_pose']

warnings.warn(
    "dualpuma.puma is deprecated; import from dualpuma.kinematics.puma instead",
    DeprecationWarning,
    stacklevel=2,
)
