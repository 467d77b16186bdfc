"""Lengths of a path of object poses, the same for every planner a benchmark compares: the
translation of the object origin [m], and the fallback's SE(3) metric (that translation plus
``rot_weight`` times the angle the bar turns, summed over the steps) [m]. The first alone does not
see a path that turns the bar more."""

from __future__ import annotations

import numpy as np

from dualpuma.lie import angles
from dualpuma.planning import FallbackParams


def lengths(poses) -> tuple[float, float]:
    """(translation length [m], SE(3) metric length [m]) of poses (N, 4, 4)."""
    P = np.asarray(poses, dtype=float)
    trans = float(np.sum(np.linalg.norm(np.diff(P[:, :3, 3], axis=0), axis=1)))
    rot = float(angles(P[:-1, :3, :3], P[1:, :3, :3]).sum())
    return trans, trans + FallbackParams().rot_weight * rot
