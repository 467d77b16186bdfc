"""Deprecated: ``dualpuma.cell`` moved to :mod:`dualpuma.model` (cells and cell files).

This module re-exports the old names for one release and will then be removed; import from
:mod:`dualpuma.model` (or the top-level ``dualpuma``) instead.
"""

import warnings

from .model import (
    EXAMPLE_CELLS,
    MOUNT_YAW,
    ArmMount,
    Bar,
    Cell,
    Grasp,
    Obstacle,
    cell_from_spec,
    example_cell,
    load_cell,
    save_cell,
    seed_units_to_world,
)

__all__ = ['EXAMPLE_CELLS', 'MOUNT_YAW', 'ArmMount', 'Bar', 'Cell', 'Grasp', 'Obstacle', 'cell_from_spec', 'example_cell', 'load_cell', 'save_cell', 'seed_units_to_world']

warnings.warn(
    "dualpuma.cell is deprecated; import from dualpuma.model instead",
    DeprecationWarning,
    stacklevel=2,
)
