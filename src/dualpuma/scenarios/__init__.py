"""Ready-made problems: the seed's routines 1–8 (with their documented deviations), the snaking
slot field that only the SE(3) fallback passes, a ball that rises through the bar's path (moving
obstacles and timing), and random problems in random obstacle fields.

May import: :mod:`dualpuma.planning` (and everything below it).
"""

from .fields import SLOT_YAW, random_problem, random_problems, rising_ball_cell, slot_field_cell
from .routines import (
    ROUTINE3_GOAL_UNITS,
    ROUTINE3_LISTED_GOAL_UNITS,
    ROUTINES,
    Routine,
    routine,
    routine_cell,
    run_legs,
    run_routine,
)

__all__ = [
    "ROUTINE3_GOAL_UNITS",
    "ROUTINE3_LISTED_GOAL_UNITS",
    "ROUTINES",
    "SLOT_YAW",
    "Routine",
    "random_problem",
    "random_problems",
    "rising_ball_cell",
    "routine",
    "routine_cell",
    "run_legs",
    "run_routine",
    "slot_field_cell",
]
