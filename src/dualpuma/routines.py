"""Deprecated: ``dualpuma.routines`` moved to :mod:`dualpuma.scenarios` (the seed's routines).

This module re-exports the old names for one release and will then be removed; import from
:mod:`dualpuma.scenarios` (or the top-level ``dualpuma``) instead.
"""

import warnings

from .planning.plan import chain
from .scenarios import (
    ROUTINES,
    Routine,
    routine,
    run_routine,
)

__all__ = ['ROUTINES', 'Routine', 'chain', 'routine', 'run_routine']

warnings.warn(
    "dualpuma.routines is deprecated; import from dualpuma.scenarios instead",
    DeprecationWarning,
    stacklevel=2,
)
