"""Plan many problems at once: ``plan_many(problems, params, executor=None, progress=True)``.

By default a process pool sized to the machine runs the problems in chunks (each worker builds one
:class:`~dualpuma.model.world.World` per distinct cell of its chunk and reuses it). Any
``concurrent.futures.Executor`` works instead — e.g. Dask distributed::

    from dask.distributed import Client, LocalCluster
    with LocalCluster(n_workers=2, threads_per_worker=1) as cluster, Client(cluster) as client:
        plans = plan_many(problems, executor=client.get_executor())

Results come back in input order. A bad problem (malformed pose, unknown robot, a crash in a worker)
yields its own failed :class:`~dualpuma.planning.plan.Plan` with a reason and never kills the batch.
"""

from __future__ import annotations

import math
import os
import sys
import time
from collections.abc import Iterable, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field

from ..errors import ParameterError
from ..model.world import World
from .params import StrivingParams
from .plan import Plan
from .striving import plan

__all__ = ["Problem", "plan_many"]


@dataclass(frozen=True, slots=True)
class Problem:
    """One planning problem (see :func:`dualpuma.planning.plan` for the fields)."""

    cell: object
    start: object
    goal: object
    q_start: object = None
    params: StrivingParams | None = None
    start_rpy: object = None
    goal_rpy: object = None
    rng: int | None = None
    tag: object = field(default=None)


def _as_problem(p) -> Problem:
    if isinstance(p, Problem):
        return p
    if isinstance(p, dict):
        return Problem(**p)
    if isinstance(p, (tuple, list)) and 3 <= len(p) <= 4:
        return Problem(*p)
    raise ParameterError(f"expected a Problem, a dict or a (cell, start, goal[, q_start]) tuple, got {type(p).__name__}")


def _solve_one(prob: Problem, params: StrivingParams | None, worlds: dict) -> Plan:
    try:
        p = prob.params if prob.params is not None else params
        key = id(prob.cell)
        if key not in worlds:
            worlds[key] = World(prob.cell)
        return plan(prob.cell, prob.start, prob.goal, p, prob.rng, q_start=prob.q_start, start_rpy=prob.start_rpy,
                    goal_rpy=prob.goal_rpy, world=worlds[key])
    except Exception as e:  # noqa: BLE001 - one bad problem must not kill the batch
        return Plan.failed("error", f"{type(e).__name__}: {e}")


def _run_chunk(items: list[tuple[int, object]], params: StrivingParams | None) -> list[tuple[int, Plan]]:
    """Worker entry point (module level so that it pickles)."""
    worlds: dict = {}
    out = []
    for i, raw in items:
        try:
            prob = _as_problem(raw)
        except Exception as e:  # noqa: BLE001
            out.append((i, Plan.failed("invalid_input", str(e))))
            continue
        out.append((i, _solve_one(prob, params, worlds)))
    return out


def plan_many(
    problems: Iterable,
    params: StrivingParams | None = None,
    executor: Executor | None = None,
    progress: bool = True,
    chunksize: int | None = None,
) -> list[Plan]:
    """Plan every problem; results in input order.

    Args:
        problems: :class:`Problem` objects, dicts of its fields or ``(cell, start, goal[, q_start])``.
        params: default planner parameters (a problem's own ``params`` wins).
        executor: any ``concurrent.futures.Executor`` (e.g. Dask's ``client.get_executor()``);
            default: a process pool with one worker per CPU, shut down afterwards.
        progress: show a progress line on stderr when it is a terminal.
        chunksize: problems per task (default: about 4 tasks per worker).

    Returns:
        One :class:`~dualpuma.planning.plan.Plan` per problem.

    Raises:
        ParameterError: malformed ``params`` or ``chunksize``.
    """
    items: Sequence = list(problems)
    if params is not None and not isinstance(params, StrivingParams):
        raise ParameterError(f"params: expected StrivingParams or None, got {type(params).__name__}")
    n = len(items)
    if n == 0:
        return []
    own = executor is None
    workers = os.cpu_count() or 1
    if chunksize is None:
        chunksize = max(1, math.ceil(n / (4 * workers)))
    elif isinstance(chunksize, bool) or not isinstance(chunksize, int) or chunksize < 1:
        raise ParameterError(f"chunksize: expected an integer >= 1, got {chunksize!r}")
    chunks = [list(enumerate(items))[i : i + chunksize] for i in range(0, n, chunksize)]
    results: list[Plan | None] = [None] * n
    show = progress and sys.stderr.isatty()
    t0 = time.perf_counter()
    ex = ProcessPoolExecutor(max_workers=workers) if own else executor
    try:
        futures = {ex.submit(_run_chunk, ch, params): ch for ch in chunks}
        done = 0
        for fut in as_completed(futures):
            ch = futures[fut]
            try:
                for i, pl in fut.result():
                    results[i] = pl
            except Exception as e:  # noqa: BLE001 - a dead worker fails its chunk only
                for i, _ in ch:
                    results[i] = Plan.failed("error", f"worker failed: {type(e).__name__}: {e}")
            done += len(ch)
            if show:
                rate = done / max(time.perf_counter() - t0, 1e-9)
                sys.stderr.write(f"\rplan_many: {done}/{n} problems ({rate:.0f}/s)")
                sys.stderr.flush()
    finally:
        if own:
            ex.shutdown()
        if show:
            sys.stderr.write("\n")
    return [r if r is not None else Plan.failed("error", "no result") for r in results]
