"""Deprecated: ``dualpuma.world`` moved to :mod:`dualpuma.model` (the World).

This module re-exports the old names for one release and will then be removed; import from
:mod:`dualpuma.model` (or the top-level ``dualpuma``) instead.
"""

import warnings

from .model import (
    Clearance,
    GeometryInfo,
    World,
)

__all__ = ['Clearance', 'GeometryInfo', 'World']

warnings.warn(
    "dualpuma.world is deprecated; import from dualpuma.model instead",
    DeprecationWarning,
    stacklevel=2,
)
