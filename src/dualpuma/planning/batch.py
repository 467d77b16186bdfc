"""Plan many problems at once: ``plan_many(problems, params, executor=None, progress=True)``.

By default a process pool sized to the machine runs the problems in chunks (each worker builds one
:class:`~dualpuma.model.world.World` per distinct cell of its chunk and reuses it). Its processes
are started by ``forkserver`` (``spawn`` where there is none), never by a plain ``fork`` of this
process: forking a process that runs threads (the viewer, a Dask client) is unsafe. Any
``concurrent.futures.Executor`` works instead — e.g. Dask distributed::

    from dask.distributed import Client, LocalCluster
    with LocalCluster(n_workers=2, threads_per_worker=1) as cluster, Client(cluster) as client:
        plans = plan_many(problems, executor=client.get_executor())

Results come back in input order. A bad problem never kills the batch, it yields its own failed
:class:`~dualpuma.planning.plan.Plan` with a reason:

* malformed input (a pose, a cell, an unknown robot, not a problem at all): ``invalid_input``;
* a problem that cannot be pickled for the worker processes: ``invalid_input``, found in this
  process before anything is sent;
* a crash (an exception in the planner, even one that is not an ``Exception`` such as
  ``SystemExit``; a worker process that dies): ``error``. A chunk that fails
  is retried problem by problem: with the default pool, markers in a temporary directory tell
  which problems had started and not finished when a worker died, and only those are re-run, each
  alone in a fresh one-worker pool, so that only the problem that kills its worker fails (the
  others are planned again normally). With another executor each problem of a failed chunk is
  submitted on its own, one at a time, and fails alone with its reason (an executor that cannot
  recover from a dead worker, such as a user's ``ProcessPoolExecutor``, fails the problems it
  still had).

Every executor receives the problems pickled (bytes), so that nothing of a problem is unpickled in
this process (Dask's tokenising would, and a problem that kills its process killed the caller).
``KeyboardInterrupt`` (Ctrl-C) ends the batch: the workers stop after the problem each is planning,
not after their chunk. If this process is killed (SIGTERM, SIGKILL: a scheduler's time limit),
the default pool's workers notice within a second, remove their temporary directory and exit.

As with any ``spawn``/``forkserver`` pool, the worker processes import the ``__main__`` script: a
script that calls ``plan_many`` with the default pool must do its work under
``if __name__ == "__main__":`` (otherwise the workers die starting up, and every problem fails with
a reason saying so).
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import multiprocessing
import os
import pickle
import shutil
import signal
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterable
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool

from ..checks import flag, integer
from ..errors import DualpumaError, ParameterError
from ..model.cell import Cell
from ..model.world import World
from ..values import value_class
from .params import StrivingParams
from .plan import Plan
from .striving import plan

__all__ = ["MAX_PROBLEMS", "Problem", "plan_many"]

MAX_PROBLEMS = 10_000_000  #: most problems one call takes
_NO_START = ("the worker processes died before planning anything (a script that calls plan_many must do so "
             "under `if __name__ == '__main__':`, as the workers import it)")


@value_class
@dataclasses.dataclass(frozen=True, slots=True)
class Problem:
    """One planning problem (see :func:`dualpuma.planning.plan` for the fields); equal to another
    when every field is (arrays element for element: :mod:`dualpuma.values`)."""

    cell: object
    start: object
    goal: object
    q_start: object = None
    params: StrivingParams | None = None
    start_rpy: object = None
    goal_rpy: object = None
    rng: int | None = None
    tag: object = dataclasses.field(default=None)
    t_start: float = 0.0  #: [s] the plan's start time (a leg continuing another: its end time)


def _as_problem(p) -> Problem:
    if isinstance(p, Problem):
        return p
    try:
        if isinstance(p, dict):
            return Problem(**p)
        if isinstance(p, (tuple, list)) and 3 <= len(p) <= 4:
            return Problem(*p)
    except TypeError as e:  # unknown or missing fields
        raise ParameterError(f"expected a Problem: {e}") from None
    raise ParameterError(f"expected a Problem, a dict or a (cell, start, goal[, q_start]) tuple, got {type(p).__name__}")


def _solve_one(prob: Problem, params: StrivingParams | None, worlds: dict) -> Plan:
    try:
        p = prob.params if prob.params is not None else params
        key = id(prob.cell)
        if key not in worlds:
            worlds[key] = World(prob.cell)
        return plan(prob.cell, prob.start, prob.goal, p, prob.rng, q_start=prob.q_start, start_rpy=prob.start_rpy,
                    goal_rpy=prob.goal_rpy, world=worlds[key], t_start=prob.t_start)
    except DualpumaError as e:
        return Plan.failed("invalid_input", str(e))
    except KeyboardInterrupt:
        raise
    except BaseException as e:  # noqa: BLE001 - one bad problem must not kill the batch (SystemExit too)
        return Plan.failed("error", f"{type(e).__name__}: {e}"[:2000])


def _mark(marks: str | None, name: str) -> None:
    if marks is not None:
        open(os.path.join(marks, name), "w").close()


_STOP = "stop"  #: the marker that tells the workers to stop before their next problem


def _watch(parent: int, marks: str | None) -> None:
    """Worker initializer of the default pool: a thread that ends this worker (and removes the
    markers' directory) once the process that called plan_many is gone."""

    def gone() -> bool:
        try:
            os.kill(parent, 0)
        except ProcessLookupError:
            return True
        except OSError:
            return False
        try:  # killed but not yet reaped by its own parent
            with open(f"/proc/{parent}/stat", "rb") as f:
                return f.read().rsplit(b")", 1)[1].split()[0] in (b"Z", b"X")
        except (OSError, IndexError):
            return False

    def loop() -> None:
        while not gone():
            time.sleep(0.5)
        if marks is not None:
            shutil.rmtree(marks, ignore_errors=True)
        os.kill(os.getpid(), signal.SIGKILL)  # at once: no cleanup of a pool whose caller is gone

    threading.Thread(target=loop, name="dualpuma-parent-watch", daemon=True).start()


def _run_pickled(payload: list[tuple[int, int, bytes]], cells: dict[int, bytes], params: StrivingParams | None,
                 marks: str | None) -> list[tuple[int, Plan]]:
    """Worker entry point (module level so that it pickles). Each problem (without its cell) and
    each distinct cell arrive pickled on their own; a problem is unpickled and planned between its
    ``started`` and ``done`` markers, and problems that shared a cell object share it (and its
    World) again. With the stop marker present the chunk ends before its next problem."""
    worlds: dict = {}
    unpickled: dict[int, object] = {}
    out = []
    for i, key, blob in payload:
        if marks is not None and os.path.exists(os.path.join(marks, _STOP)):
            break
        _mark(marks, f"{i}.started")
        try:
            if key not in unpickled:
                unpickled[key] = pickle.loads(cells[key])
            prob = dataclasses.replace(pickle.loads(blob), cell=unpickled[key])
        except KeyboardInterrupt:
            raise
        except BaseException as e:  # noqa: BLE001 - e.g. a class defined in the caller's __main__, SystemExit
            out.append((i, Plan.failed("invalid_input", f"problem cannot be unpickled in a worker process: "
                                                        f"{type(e).__name__}: {e}"[:2000])))
        else:
            out.append((i, _solve_one(prob, params, worlds)))
        _mark(marks, f"{i}.done")
    return out


def _context() -> multiprocessing.context.BaseContext:
    """``forkserver`` (its server imports dualpuma once; workers fork from it) or ``spawn``."""
    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload([__name__])
        return ctx
    return multiprocessing.get_context("spawn")


class _Progress:
    """The progress line on stderr (only when it is a terminal)."""

    def __init__(self, n: int, show: bool) -> None:
        self.n, self.show, self.done, self.t0 = n, show, 0, time.perf_counter()

    def add(self, k: int) -> None:
        self.done += k
        if self.show:
            rate = self.done / max(time.perf_counter() - self.t0, 1e-9)
            sys.stderr.write(f"\rplan_many: {self.done}/{self.n} problems ({rate:.0f}/s)")
            sys.stderr.flush()

    def close(self) -> None:
        if self.show:
            sys.stderr.write("\n")


def _failed_worker(e: BaseException) -> Plan:
    return Plan.failed("error", f"worker failed: {type(e).__name__}: {e}"[:2000])


def _listed(problems: object) -> list:
    if isinstance(problems, (str, bytes, dict)) or not isinstance(problems, Iterable):
        raise ParameterError(f"problems: expected an iterable of problems, got {type(problems).__name__}")
    if isinstance(problems, (tuple, list)) and problems and isinstance(problems[0], Cell):
        raise ParameterError("problems: this is one problem (cell, start, goal), not a list of them: "
                             "plan_many([(cell, start, goal)]), or plan(cell, start, goal)")
    items = []
    try:
        for p in problems:
            items.append(p)
            if len(items) > MAX_PROBLEMS:
                raise ParameterError(f"problems: more than the {MAX_PROBLEMS} accepted")
    except TypeError as e:  # e.g. a 0-d array
        raise ParameterError(f"problems: expected an iterable of problems ({e})") from None
    return items


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
        executor: any ``concurrent.futures.Executor`` instance (e.g. Dask's
            ``client.get_executor()``; the problems reach it pickled); default: a process pool
            (forkserver) with one worker per CPU, shut down afterwards.
        progress: show a progress line on stderr when it is a terminal.
        chunksize: problems per task (default: about 4 tasks per worker).

    Returns:
        One :class:`~dualpuma.planning.plan.Plan` per problem (failed ones with their reason, see
        the module docstring).

    Raises:
        ParameterError: ``problems`` not an iterable; malformed ``params``, ``executor``,
            ``progress`` or ``chunksize``.
    """
    items = _listed(problems)
    if params is not None and not isinstance(params, StrivingParams):
        raise ParameterError(f"params: expected StrivingParams or None, got {type(params).__name__}")
    if executor is not None and (isinstance(executor, type) or not callable(getattr(executor, "submit", None))):
        what = f"the class {executor.__name__}: pass an instance, e.g. {executor.__name__}(2)" \
            if isinstance(executor, type) else type(executor).__name__
        raise ParameterError(f"executor: expected a concurrent.futures.Executor or None, got {what}")
    show = flag(progress, "progress") and sys.stderr.isatty()
    n = len(items)
    workers = os.cpu_count() or 1
    if chunksize is None:
        chunksize = max(1, math.ceil(n / (4 * workers)))
    chunksize = integer(chunksize, "chunksize", lo=1, hi=MAX_PROBLEMS)
    if n == 0:
        return []
    results: list[Plan | None] = [None] * n
    bar = _Progress(n, show)
    try:
        data = _Pickled(items, results, bar.add)
        if executor is None:
            _own_pool(data, params, chunksize, workers, results, bar.add)
        else:
            _foreign(executor, data, params, chunksize, results, bar.add)
    finally:
        bar.close()
    return [r if r is not None else Plan.failed("error", "no result") for r in results]


def _foreign(ex: Executor, data: _Pickled, params, chunksize: int, results: list, add: Callable[[int], None]) -> None:
    """Chunks on the user's executor; each problem of a failed chunk is then submitted alone, one
    at a time."""
    todo = sorted(data.problems)
    retry: list[int] = []
    futures = {}
    for s in range(0, len(todo), chunksize):
        ch = todo[s : s + chunksize]
        try:
            futures[ex.submit(_run_pickled, *data.chunk(ch), params, None)] = ch
        except KeyboardInterrupt:
            raise
        except BaseException as e:  # noqa: BLE001 - a shut-down executor
            if not futures:  # nothing submitted yet: the executor itself is unusable
                raise ParameterError(f"executor: cannot submit work: {type(e).__name__}: {e}"[:2000]) from None
            retry += ch
    for fut in as_completed(futures):
        ch = futures[fut]
        try:
            for i, pl in fut.result():
                results[i] = pl
            add(len(ch))
        except KeyboardInterrupt:
            raise
        except BaseException:  # noqa: BLE001 - a dead worker or a failed chunk: retried problem by problem
            retry += ch
    # one at a time, as the default pool re-runs its suspects: a problem that kills its worker
    # takes down the tasks queued there too (Dask counts the death against each of them, and an
    # innocent problem failed with KilledWorker when they were submitted together)
    for i in retry:
        try:
            results[i] = ex.submit(_run_pickled, *data.chunk([i]), params, None).result()[0][1]
        except KeyboardInterrupt:
            raise
        except BaseException as e:  # noqa: BLE001 - this problem alone fails
            results[i] = _failed_worker(e)
        add(1)


class _Pickled:
    """The problems pickled for the default pool: each problem without its cell, and each distinct
    cell once. A problem that is malformed or cannot be pickled fails here, alone."""

    def __init__(self, items: list, results: list, add: Callable[[int], None]) -> None:
        self.problems: dict[int, tuple[int, bytes]] = {}
        self.cells: dict[int, bytes] = {}
        bad_cells: dict[int, str] = {}
        for i, raw in enumerate(items):
            try:
                prob = _as_problem(raw)
                if not isinstance(prob.cell, Cell):  # as plan() says it (a World does not even pickle)
                    raise ParameterError(f"cell: expected a dualpuma Cell, got {type(prob.cell).__name__}")
            except DualpumaError as e:
                results[i] = Plan.failed("invalid_input", str(e))
                add(1)
                continue
            key = id(prob.cell)
            why = bad_cells.get(key)
            try:
                if why is None and key not in self.cells:
                    self.cells[key] = pickle.dumps(prob.cell, protocol=pickle.HIGHEST_PROTOCOL)
                if why is None:
                    self.problems[i] = (key, pickle.dumps(dataclasses.replace(prob, cell=None),
                                                          protocol=pickle.HIGHEST_PROTOCOL))
            except KeyboardInterrupt:
                raise
            except BaseException as e:  # noqa: BLE001 - pickling runs the user's __reduce__
                why = f"{type(e).__name__}: {e}"[:2000]
                if key not in self.cells:
                    bad_cells[key] = why
            if why is not None:
                results[i] = Plan.failed("invalid_input", f"problem cannot be sent to a worker process: {why}")
                add(1)

    def chunk(self, indices: list[int]) -> tuple[list[tuple[int, int, bytes]], dict[int, bytes]]:
        payload = [(i, *self.problems[i]) for i in indices]
        return payload, {k: self.cells[k] for k in {key for _, key, _ in payload}}


def _own_pool(data: _Pickled, params, chunksize: int, workers: int, results: list, add: Callable[[int], None]) -> None:
    """The default process pool, with crash isolation (module docstring)."""
    todo = sorted(data.problems)
    alone: list[int] = []
    ctx = _context()
    with tempfile.TemporaryDirectory(prefix="dualpuma-plan-many-") as marks:
        while todo:
            chunks = [todo[s : s + chunksize] for s in range(0, len(todo), chunksize)]
            todo, settled = [], 0
            ex = ProcessPoolExecutor(max_workers=min(workers, len(chunks)), mp_context=ctx, initializer=_watch,
                                     initargs=(os.getpid(), marks))
            try:
                futures = {ex.submit(_run_pickled, *data.chunk(ch), params, marks): ch for ch in chunks}
                for fut in as_completed(futures):
                    ch = futures[fut]
                    try:
                        for i, pl in fut.result():
                            results[i] = pl
                        add(len(ch))
                        settled += len(ch)
                    except BrokenProcessPool:  # a worker died: suspects are the problems it had started
                        suspects = [i for i in ch if _state(marks, i) == "started"]
                        alone += suspects
                        settled += len(suspects)
                        todo += [i for i in ch if i not in suspects]
                    except KeyboardInterrupt:
                        raise
                    except BaseException:  # noqa: BLE001 - e.g. a result that does not unpickle
                        alone += ch
                        settled += len(ch)
            except KeyboardInterrupt:  # the workers stop before their next problem
                _mark(marks, _STOP)
                raise
            finally:
                ex.shutdown(wait=True, cancel_futures=True)
            for i in todo:  # re-run in the next round: forget their markers
                for suffix in (".started", ".done"):
                    with contextlib.suppress(FileNotFoundError):
                        os.unlink(os.path.join(marks, f"{i}{suffix}"))
            if not settled:  # the workers died before any problem started: not a problem's fault
                for i in todo:
                    results[i] = Plan.failed("error", _NO_START)
                add(len(todo))
                todo = []
            todo.sort()
    _alone(sorted(alone), data, params, ctx, results, add)


def _state(marks: str, i: int) -> str:
    if os.path.exists(os.path.join(marks, f"{i}.done")):
        return "done"
    return "started" if os.path.exists(os.path.join(marks, f"{i}.started")) else "new"


def _alone(indices: list[int], data: _Pickled, params, ctx, results: list, add: Callable[[int], None]) -> None:
    """Each problem alone in a one-worker pool (a new pool after a worker died): only a problem
    that kills its worker fails."""
    ex = None
    try:
        for i in indices:
            if ex is None:
                ex = ProcessPoolExecutor(max_workers=1, mp_context=ctx, initializer=_watch, initargs=(os.getpid(), None))
            try:
                results[i] = ex.submit(_run_pickled, *data.chunk([i]), params, None).result()[0][1]
            except BrokenProcessPool as e:
                results[i] = Plan.failed("error", f"the worker process died planning this problem ({type(e).__name__})")
                ex.shutdown(wait=True)
                ex = None
            except KeyboardInterrupt:
                raise
            except BaseException as e:  # noqa: BLE001
                results[i] = _failed_worker(e)
            add(1)
    finally:
        if ex is not None:
            ex.shutdown(wait=True)
