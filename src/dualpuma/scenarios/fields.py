"""Scenario cells and problems beyond the seed's routines.

* :func:`slot_field_cell` — the snaking slot field that Striving cannot pass and the SE(3) fallback
  solves (:mod:`dualpuma.planning.rrt`).
* :func:`rising_ball_cell` — a ball rising through the bar's path after the plan's own clock has
  passed it: the fastest timing of the plan meets it, waiting at the start does not
  (:func:`dualpuma.planning.time_plan`).
* :func:`random_problem` / :func:`random_problems` — random planning problems in random obstacle
  fields (for tests, benchmarks and batch demos): the default cell's start pose perturbed into a
  goal (translation up to a few decimetres, a yaw up to 15 deg), boxes, spheres and capsules
  scattered in front of the arms, only fields whose start is clear. Deterministic for a seed.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import numpy.typing as npt

from ..checks import instance, integer, real
from ..errors import ParameterError
from ..lie import rot_to_rpy, rpy_to_rot
from ..model.cell import Cell, Obstacle
from ..model.world import World
from ..planning.batch import Problem

__all__ = ["SLOT_YAW", "random_problem", "random_problems", "rising_ball_cell", "slot_field_cell"]

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
        R = rpy_to_rot([0.0, 0.0, yaw])
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


# ----------------------------------------------------------------------------- a moving obstacle
def rising_ball_cell(t_start: float = 0.5, t_end: float = 1.0) -> tuple[Cell, FloatArray, FloatArray]:
    """``Cell.default()`` with a ball (radius 20 mm) 75 mm beside the bar's centre line (in -y) and
    100 mm below it, rising at 1 m/s from ``t_start`` to ``t_end`` [s]; the goal takes the bar
    150 mm along -y and 50 mm up, through the ball's column. At the planner's clock (0.1 s a step)
    the bar has passed by 0.4 s, before the ball moves; the arms' fastest timing takes about 1.3 s
    and meets it (with the defaults), a wait at the start does not. With ``t_end`` = 0.6 s the
    ball stops in the bar's path and no timing passes.

    Returns:
        ``(cell, T_start, T_goal)``: object poses (4, 4) [m]; the start is the cell's.

    Raises:
        ParameterError: times not finite numbers with 0 <= t_start <= t_end.
    """
    base = Cell.default()
    A = base.T_world_object_start.copy()
    B = A.copy()
    B[:3, 3] += (0.0, -0.15, 0.05)
    T = np.eye(4)
    T[:3, 3] = (A @ base.bar.T_object_bar)[:3, 3] + (0.0, -0.075, -0.1)
    t0, t1 = real(t_start, "t_start", lo=0.0, unit="s"), real(t_end, "t_end", lo=0.0, unit="s")
    if t1 < t0:
        raise ParameterError(f"rising_ball_cell: need t_start <= t_end, got {t0}, {t1}")
    ball = Obstacle("ball", "sphere", [0.02], T, velocity=(0.0, 0.0, 1.0), t_start=t0, t_end=t1)
    return dataclasses.replace(base, obstacles=(ball,), name="rising-ball"), A, B


# ----------------------------------------------------------------------------- random problems
_LO = np.array([1.2, -0.75, 0.0])
_HI = np.array([2.4, -0.3, 0.7])


def _obstacle(rng: np.random.Generator, i: int) -> Obstacle:
    T = np.eye(4)
    T[:3, 3] = rng.uniform(_LO, _HI)
    kind = ("box", "sphere", "capsule")[int(rng.integers(3))]
    if kind == "box":
        T[:3, :3] = rpy_to_rot([0.0, 0.0, rng.uniform(-math.pi, math.pi)])
        return Obstacle(f"o{i}", "box", rng.uniform(0.05, 0.3, 3), T)
    if kind == "sphere":
        return Obstacle(f"o{i}", "sphere", [rng.uniform(0.03, 0.12)], T)
    T[:3, :3] = rpy_to_rot(rng.uniform(-math.pi, math.pi, 3))
    return Obstacle(f"o{i}", "capsule", [rng.uniform(0.02, 0.08), rng.uniform(0.05, 0.4)], T)


def random_problem(rng: np.random.Generator | int, max_obstacles: int = 3, base: Cell | None = None) -> Problem:
    """One random problem whose start is permitted (the goal may be blocked: that is part of it).

    Args:
        rng: a numpy Generator (advanced) or a seed (int >= 0).
        max_obstacles: at most this many random obstacles (0..100).
        base: the cell whose arms, bar, obstacles and start pose are used (default ``Cell.default()``);
            the random obstacles are added to its own.

    Raises:
        ParameterError: any argument of another type or out of range.
    """
    max_obstacles = integer(max_obstacles, "max_obstacles", lo=0, hi=100)
    if not isinstance(rng, np.random.Generator):
        rng = np.random.default_rng(integer(rng, "rng", lo=0, hi=2**63 - 1))
    base = Cell.default() if base is None else instance(base, Cell, "base")
    A = base.T_world_object_start
    B = A.copy()
    B[:3, 3] += rng.uniform([-0.3, -0.1, -0.05], [0.05, 0.1, 0.25])
    B[:3, :3] = rpy_to_rot(rot_to_rpy(A[:3, :3]) + [0.0, 0.0, math.radians(rng.uniform(-15.0, 15.0))])
    for _ in range(100):
        obs = tuple(_obstacle(rng, i) for i in range(int(rng.integers(0, max_obstacles + 1))))
        cell = dataclasses.replace(base, obstacles=tuple(base.obstacles) + obs, name="random")
        if not obs or World(cell).clearance(base.left.q_home, base.right.q_home, A).distance >= base.safety_margin:
            return Problem(cell, A, B)
    return Problem(dataclasses.replace(base, name="random"), A, B)  # pragma: no cover


def random_problems(n: int, seed: int = 0, max_obstacles: int = 3) -> list[Problem]:
    """``n`` random problems (0..100,000) from one seed (an int >= 0).

    Raises:
        ParameterError: ``n``, ``seed`` or ``max_obstacles`` not an integer in range.
    """
    n = integer(n, "n", lo=0, hi=100_000)
    seed = integer(seed, "seed", lo=0, hi=2**63 - 1)
    max_obstacles = integer(max_obstacles, "max_obstacles", lo=0, hi=100)
    ss = np.random.SeedSequence(seed).spawn(n)
    return [random_problem(np.random.default_rng(s), max_obstacles) for s in ss]
