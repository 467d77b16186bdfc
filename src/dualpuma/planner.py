"""Deprecated: ``dualpuma.planner`` moved to :mod:`dualpuma.planning` (the planner).

This module re-exports the old names for one release and will then be removed; import from
:mod:`dualpuma.planning` (or the top-level ``dualpuma``) instead.
"""

import warnings

from .planning import (
    SEED_ALTERNATES,
    UP_AND_OVER,
    Plan,
    StrivingParams,
    plan,
)

__all__ = ['SEED_ALTERNATES', 'UP_AND_OVER', 'Plan', 'StrivingParams', 'plan']

warnings.warn(
    "dualpuma.planner is deprecated; import from dualpuma.planning instead",
    DeprecationWarning,
    stacklevel=2,
)
