"""Scenario cells beyond the seed's routines: the snaking slot field that Striving cannot pass and
the SE(3) fallback solves (:mod:`dualpuma.fallback`)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import numpy.typing as npt

from .cell import Cell, Obstacle
from .paths import calc_rot

__all__ = ["SLOT_YAW", "slot_field_cell"]

FloatArray = npt.NDArray[np.float64]

# ----------------------------------------------------------------------------- the snaking scenario
SLOT_YAW = math.radians(
    45.0
)  #: yaw of the slot in the upper plate of :func:`slot_field_cell` (lower: minus) [rad]


def slot_field_cell() -> tuple[Cell, FloatArray, FloatArray]:
    """A slot field that the bar passes only by yawing one way, then the other ("snaking").

    ``Cell.default()`` with two horizontal plates 0.26 m apart under the middle of the bar, between
    the hands: each a strip 0.12 m wide (x), 1.5 m long (y) and 0.04 m thick, cut by a slot 0.14 m
    wide yawed by +45 deg (upper plate) and -45 deg (lower plate) about the vertical. The bar (0.75 m
    along x, 0.05 m square) is lowered 0.49 m through both. It fits a slot with the 2 cm margin only
    when its yaw is within roughly 10..50 deg of the slot's sense; held unrotated its clearance to the
    slot's edges is about 14 mm, below the 20 mm margin, so the straight, fixed-orientation path is
    blocked. Each slot's edge is a thin yawed lip (0.015 m); the strip's straight pieces overlap its
    far edge at one side of the strip, leaving small triangular pockets that no bar can pass.
    Start and goal: the bar level and unrotated, centred between the shoulders (0.93 m and 0.44 m up),
    both arms away from their wrist singularity.

    Returns:
        ``(cell, T_start, T_goal)``: object poses (4, 4) [m]; the cell's home joints hold the bar at
        ``cell.T_world_object_start`` (not ``T_start``: solve the start on the home branches).
    """
    base = Cell.default()
    A = base.T_world_object_start.copy()
    A[:3, 3] += (-0.40, -0.35, 0.70)
    B = A.copy()
    B[2, 3] -= 0.49
    hw, gap, thick, half_len, lip = 0.06, 0.14, 0.04, 0.75, 0.015
    c0 = (A @ base.bar.T_object_bar)[:3, 3]
    obstacles = []
    for k, (dz, yaw) in enumerate(((-0.11, SLOT_YAW), (-0.37, -SLOT_YAW))):
        c = c0 + (0.0, 0.0, dz)  # slot centre on the bar centre's straight way down
        R = calc_rot([0.0, 0.0, yaw])
        ca, ta = math.cos(yaw), abs(math.tan(yaw))
        yf = (gap / 2 + lip) / ca + hw * ta - 0.005  # straight pieces overlap the lips' far edges
        for sgn, name in ((1, "back"), (-1, "front")):
            T = np.eye(4)
            T[:3, :3] = R
            T[:3, 3] = c + (0.0, sgn * (gap / 2 + lip / 2) / ca, 0.0)  # lip centred over the strip
            obstacles.append(
                Obstacle(
                    f"plate{k + 1}_{name}_lip",
                    "box",
                    np.array([2 * hw / ca + lip * ta, lip, thick]),
                    T,
                )
            )
            T = np.eye(4)
            T[:3, 3] = c + (0.0, sgn * 0.5 * (yf + half_len), 0.0)
            obstacles.append(
                Obstacle(f"plate{k + 1}_{name}", "box", np.array([2 * hw, half_len - yf, thick]), T)
            )
    return dataclasses.replace(base, obstacles=tuple(obstacles), name="slot-field"), A, B
