"""Random planning problems in random obstacle fields (for tests, benchmarks and batch demos).

``random_problem(rng)`` perturbs the default cell's start pose into a goal (translation up to a few
decimetres, a yaw up to 15 deg) and scatters boxes, spheres and capsules in front of the arms, keeping
only fields whose start configuration is clear. Deterministic for a given seed.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .batch import Problem
from .cell import Cell, Obstacle
from .errors import ParameterError
from .paths import calc_rot, rpy_from_rot
from .world import World

__all__ = ["random_problem", "random_problems"]

_LO = np.array([1.2, -0.75, 0.0])
_HI = np.array([2.4, -0.3, 0.7])


def _obstacle(rng: np.random.Generator, i: int) -> Obstacle:
    T = np.eye(4)
    T[:3, 3] = rng.uniform(_LO, _HI)
    kind = ("box", "sphere", "capsule")[int(rng.integers(3))]
    if kind == "box":
        T[:3, :3] = calc_rot([0.0, 0.0, rng.uniform(-math.pi, math.pi)])
        return Obstacle(f"o{i}", "box", rng.uniform(0.05, 0.3, 3), T)
    if kind == "sphere":
        return Obstacle(f"o{i}", "sphere", [rng.uniform(0.03, 0.12)], T)
    T[:3, :3] = calc_rot(rng.uniform(-math.pi, math.pi, 3))
    return Obstacle(f"o{i}", "capsule", [rng.uniform(0.02, 0.08), rng.uniform(0.05, 0.4)], T)


def random_problem(rng: np.random.Generator | int, max_obstacles: int = 3, base: Cell | None = None) -> Problem:
    """One random problem whose start is permitted (the goal may be blocked: that is part of it)."""
    if isinstance(max_obstacles, bool) or not isinstance(max_obstacles, int) or max_obstacles < 0:
        raise ParameterError(f"max_obstacles: expected an integer >= 0, got {max_obstacles!r}")
    rng = np.random.default_rng(rng)
    base = Cell.default() if base is None else base
    A = base.T_world_object_start
    B = A.copy()
    B[:3, 3] += rng.uniform([-0.3, -0.1, -0.05], [0.05, 0.1, 0.25])
    B[:3, :3] = calc_rot(rpy_from_rot(A[:3, :3]) + [0.0, 0.0, math.radians(rng.uniform(-15.0, 15.0))])
    for _ in range(100):
        obs = tuple(_obstacle(rng, i) for i in range(int(rng.integers(0, max_obstacles + 1))))
        cell = dataclasses.replace(base, obstacles=obs, name="random")
        if not obs or World(cell).clearance(base.left.q_home, base.right.q_home, A).distance >= base.safety_margin:
            return Problem(cell, A, B)
    return Problem(dataclasses.replace(base, obstacles=(), name="random"), A, B)  # pragma: no cover


def random_problems(n: int, seed: int = 0, max_obstacles: int = 3) -> list[Problem]:
    """``n`` random problems from one seed."""
    if isinstance(n, bool) or not isinstance(n, int) or n < 0:
        raise ParameterError(f"n: expected an integer >= 0, got {n!r}")
    ss = np.random.SeedSequence(seed).spawn(n)
    return [random_problem(np.random.default_rng(s), max_obstacles) for s in ss]
