"""Deprecated: ``dualpuma.coordination`` moved to :mod:`dualpuma.kinematics` (dual-arm coordination).

This module re-exports the old names for one release and will then be removed; import from
:mod:`dualpuma.kinematics` (or the top-level ``dualpuma``) instead.
"""

import warnings

from .kinematics import (
    DEFAULT_MAX_JOINT_STEP,
    DualSolution,
    PathSolution,
    hands_from_object,
    solve_dual,
    solve_path,
)

__all__ = ['DEFAULT_MAX_JOINT_STEP', 'DualSolution', 'PathSolution', 'hands_from_object', 'solve_dual', 'solve_path']

warnings.warn(
    "dualpuma.coordination is deprecated; import from dualpuma.kinematics instead",
    DeprecationWarning,
    stacklevel=2,
)
