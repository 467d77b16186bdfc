"""The work cell and the World built from it: the frozen description (arms and their bases, the
bar, the grasps, the obstacles, the floor), its TOML file form and the shipped example cells, and
the Pinocchio + coal structures built once per cell.

May import: :mod:`dualpuma.kinematics` (and lie, checks, files, errors).
"""

from .cache import WorldCache
from .cell import (
    MAX_EXTENT,
    MAX_GRASP_GAP,
    MAX_MARGIN,
    MAX_NAME,
    MAX_OBSTACLES,
    MOUNT_YAW,
    SHAPES,
    ArmMount,
    Bar,
    Cell,
    Grasp,
    Obstacle,
    seed_units_to_world,
)
from .cell_file import (
    EXAMPLE_CELLS,
    MAX_CELL_BYTES,
    cell_from_spec,
    cell_from_toml,
    cell_to_toml,
    example_cell,
    load_cell,
    save_cell,
)
from .world import Clearance, GeometryInfo, World

__all__ = [
    "EXAMPLE_CELLS",
    "MAX_CELL_BYTES",
    "MAX_EXTENT",
    "MAX_GRASP_GAP",
    "MAX_MARGIN",
    "MAX_NAME",
    "MAX_OBSTACLES",
    "MOUNT_YAW",
    "SHAPES",
    "ArmMount",
    "Bar",
    "Cell",
    "Clearance",
    "GeometryInfo",
    "Grasp",
    "Obstacle",
    "World",
    "WorldCache",
    "cell_from_spec",
    "cell_from_toml",
    "cell_to_toml",
    "example_cell",
    "load_cell",
    "save_cell",
    "seed_units_to_world",
]
