"""Long work of the viewer, run in its planning worker (never in the loop, never under a lock):
routines, planning to a goal, planning through taught waypoints. Each job returns a
:class:`JobResult` — the plan's :class:`~dualpuma.viewer.playback.Playback` (its clearance checked
against the World it will be shown in) and, for a routine with its own cell, that cell and World.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from ..errors import DualpumaError
from ..model import Cell, World
from ..planning import StrivingParams, plan, with_trajectory
from ..scenarios import routine_cell, run_legs, run_routine
from .playback import Playback

__all__ = ["JobResult", "goal_job", "routine_job", "same_cell", "waypoints_job"]


@dataclass(frozen=True, slots=True)
class JobResult:
    """What a job hands to the loop: ``playback`` (None for a plan without steps), the ``plan``,
    and for a routine shown in its own cell: ``cell`` and ``world`` (else None)."""

    title: str
    plan: object
    playback: Playback | None
    cell: Cell | None = None
    world: World | None = None
    note: str = ""  #: why a plan asked to be timed is played step by step (or its timing is not certified)


def _timed(p, world: World, timed: bool):
    """``(plan, note)``: a reached plan with its timed trajectory when asked (played at real speed
    under the joint limits); the plan as it is, and why, when it cannot be timed."""
    if not timed or not p.reached:
        return p, ""
    try:
        pt = with_trajectory(p, world)
    except DualpumaError as exc:
        return p, f"played step by step, not timed: {exc}"
    tr = pt.trajectory
    if tr.n_samples < 2:  # nothing moves: a trajectory of one sample, which playback cannot time
        return p, "played step by step: the plan does not move the arms (already at the goal), nothing to time"
    note = "" if tr.certified else f"timed motion not certified: {tr.reason}"
    return pt, note


def same_cell(a: Cell, b: Cell) -> bool:
    """True if two cells describe the same geometry (the cells' own names aside; value equality,
    :mod:`dualpuma.values`)."""
    return a is b or dataclasses.replace(a, name="x") == dataclasses.replace(b, name="x")


def routine_job(n: int, world: World | None, timed: bool = False) -> JobResult:
    """Run routine ``n``; shown in ``world`` if given (the current cell is the routine's), else in
    a new World of :func:`routine_cell`; timed if asked (and reached)."""
    p = run_routine(n)
    cell = None
    if world is None:
        cell = routine_cell(n)
        world = World(cell)
    title = f"routine {n}"
    p, note = _timed(p, world, timed)
    return JobResult(title, p, Playback.from_plan(p, title, world), cell, world if cell is not None else None, note)


def goal_job(world: World, T_start, q_start, goal, fallback: bool, timed: bool, step_time: float) -> JobResult:
    """Plan from the current pose to ``goal`` in the current cell (timed if asked; moving obstacles
    checked at ``step_time`` [s] a step)."""
    params = StrivingParams(fallback=bool(fallback), step_time=step_time)
    p = plan(world.cell, T_start, goal, params, q_start=q_start, world=world)
    p, note = _timed(p, world, timed)
    return JobResult("plan to goal", p, Playback.from_plan(p, "plan to goal", world), note=note)


def waypoints_job(world: World, T_start, q_start, waypoints, timed: bool, step_time: float) -> JobResult:
    """Plan through taught waypoints, leg by leg, each from where and when the previous one ended
    (moving obstacles at their real times; stops at the first leg that does not reach)."""
    out = run_legs(world.cell, T_start, [(W, None) for W in waypoints], StrivingParams(step_time=step_time),
                   world=world, q_start=q_start)
    out, note = _timed(out, world, timed)
    title = f"{len(waypoints)} waypoints"
    return JobResult(title, out, Playback.from_plan(out, title, world), note=note)
