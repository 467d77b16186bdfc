"""Long work of the viewer, run in its planning worker (never in the loop, never under a lock):
routines, planning to a goal, planning through taught waypoints. Each job returns a
:class:`JobResult` — the plan's :class:`~dualpuma.viewer.playback.Playback` (its clearance checked
against the World it will be shown in) and, for a routine with its own cell, that cell and World.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..model import Cell, World, cell_to_toml
from ..planning import StrivingParams, chain, plan
from ..scenarios import routine, run_routine
from .playback import Playback

__all__ = ["JobResult", "goal_job", "routine_cell", "routine_job", "same_cell", "waypoints_job"]


@dataclass(frozen=True, slots=True)
class JobResult:
    """What a job hands to the loop: ``playback`` (None for a plan without steps), the ``plan``,
    and for a routine shown in its own cell: ``cell`` and ``world`` (else None)."""

    title: str
    plan: object
    playback: Playback | None
    cell: Cell | None = None
    world: World | None = None


def routine_cell(n: int) -> Cell:
    """The cell routine ``n`` is shown in.

    Routine 1 carries a 100 mm cube in the left hand instead of the bar (its plan's clearance is
    computed so, inside :func:`~dualpuma.scenarios.run_routine`); ``routine(1).cell`` names the
    default cell, so the cube is rebuilt here to show what was checked.
    """
    cell = routine(n).cell
    if n == 1:
        cell = dataclasses.replace(cell, name="routine1-cube", bar=dataclasses.replace(cell.bar, size=np.array([0.1, 0.1, 0.1])))
    return cell


def same_cell(a: Cell, b: Cell) -> bool:
    """True if two cells describe the same geometry (names aside)."""
    if a is b:
        return True
    try:
        return cell_to_toml(dataclasses.replace(a, name="x")) == cell_to_toml(dataclasses.replace(b, name="x"))
    except Exception:  # noqa: BLE001 - a cell that cannot be written is compared by identity only
        return False


def routine_job(n: int, world: World | None) -> JobResult:
    """Run routine ``n``; shown in ``world`` if given (the current cell is the routine's), else in
    a new World of :func:`routine_cell`."""
    p = run_routine(n)
    cell = None
    if world is None:
        cell = routine_cell(n)
        world = World(cell)
    title = f"routine {n}"
    return JobResult(title, p, Playback.from_plan(p, title, world), cell, world if cell is not None else None)


def goal_job(world: World, T_start, q_start, goal, fallback: bool) -> JobResult:
    """Plan from the current pose to ``goal`` in the current cell."""
    p = plan(world.cell, T_start, goal, StrivingParams(fallback=bool(fallback)), q_start=q_start, world=world)
    return JobResult("plan to goal", p, Playback.from_plan(p, "plan to goal", world))


def waypoints_job(world: World, T_start, q_start, waypoints) -> JobResult:
    """Plan through taught waypoints, leg by leg (stops at the first leg that does not reach)."""
    out, T, q = None, T_start, q_start
    for W in waypoints:
        leg = plan(world.cell, T, W, q_start=q, world=world)
        out = leg if out is None else chain(out, leg)
        if not leg.reached or leg.T_world_object.shape[0] == 0:
            break
        T, q = W, (leg.q_left[-1], leg.q_right[-1])
    title = f"{len(waypoints)} waypoints"
    return JobResult(title, out, Playback.from_plan(out, title, world))
