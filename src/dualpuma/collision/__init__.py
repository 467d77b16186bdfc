"""Clearance: exact signed distances between the arms' capsules, the bar, the obstacles and the
floor — one configuration (``World.clearance``), batches (a vectorised exact kernel), margin
tests for the planners — and the seed's own methods (node search, configuration mapping, the
twisting detector) kept beside them.

May import: :mod:`dualpuma.model` (and kinematics, lie, checks, errors).
"""

from .batch import (
    BATCH_KERNEL_MIN,
    batch_kernel,
    below_margin,
    clearance_batch,
    min_clearance,
    pair_distances_batch,
)
from .contact import first_contact_chord, self_contact, unmapped_sides
from .forms import point_box, segment_box, segment_segment
from .kernel import ClearanceKernel, KernelUnsupported
from .seed import (
    NODE_THRESHOLD,
    GrownObstacle,
    arm_arm_distance,
    bar_major_dimension,
    grown_obstacles,
    node_positions,
    node_search,
    object_point_clear,
    point_distance,
    twisting,
)

__all__ = [
    "BATCH_KERNEL_MIN",
    "NODE_THRESHOLD",
    "ClearanceKernel",
    "GrownObstacle",
    "KernelUnsupported",
    "arm_arm_distance",
    "bar_major_dimension",
    "batch_kernel",
    "below_margin",
    "clearance_batch",
    "first_contact_chord",
    "grown_obstacles",
    "min_clearance",
    "node_positions",
    "node_search",
    "object_point_clear",
    "pair_distances_batch",
    "point_box",
    "point_distance",
    "segment_box",
    "segment_segment",
    "self_contact",
    "twisting",
    "unmapped_sides",
]
