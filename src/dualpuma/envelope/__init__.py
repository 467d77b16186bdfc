"""The coordinated work envelope (the seed's §2.6): where both arms can hold the bar together.

* :mod:`.ideal` — the idealised model (spherical reach R, bases D apart, bar of length L): exact
  membership, volume and meridian boundary.
* :mod:`.real` — a real cell (the arms' closed-form IK, joint limits, floor, optionally clearance):
  exact membership with proving joints, sampled volume and the x–z section.
* :mod:`.contour` — marching squares with segments chained into polylines.

May import: :mod:`dualpuma.kinematics`, :mod:`dualpuma.model`, :mod:`dualpuma.collision`.
"""

from .contour import contour_polylines, marching_squares
from .ideal import (
    IdealEnvelope,
    closed_form_volume,
    contains_ideal,
    ideal_envelope,
    membership_slacks,
)
from .real import (
    MAX_GRID_POINTS,
    RealEnvelope,
    RealMembership,
    contains_real,
    real_envelope,
    solve_real,
)

__all__ = [
    "MAX_GRID_POINTS",
    "IdealEnvelope",
    "RealEnvelope",
    "RealMembership",
    "closed_form_volume",
    "contains_ideal",
    "contains_real",
    "contour_polylines",
    "ideal_envelope",
    "marching_squares",
    "membership_slacks",
    "real_envelope",
    "solve_real",
]
