"""plan_many: one bad problem fails alone — a worker process that dies, a problem that cannot be
pickled, a chunk an executor loses — the default pool does not fork this process, chunking is
linear in the number of problems, and bad arguments are ParameterErrors."""

from __future__ import annotations

import dataclasses
import operator
import os
import signal
import subprocess
import sys
import textwrap
import time
from concurrent.futures import Executor, Future, ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

import dualpuma
from dualpuma import plan, plan_many
from dualpuma.errors import ParameterError
from dualpuma.planning import batch
from dualpuma.scenarios import random_problems


class Crash:
    """Unpickling this kills the process that does it (the worker; never this test process)."""

    def __reduce__(self):
        return (os._exit, (3,))


class FailsToUnpickle:
    """Pickles, but unpickling raises (ZeroDivisionError) in the worker."""

    def __reduce__(self):
        return (operator.truediv, (1, 0))


class Unpicklable:
    def __reduce__(self):
        raise TypeError("this tag cannot be pickled")


@pytest.fixture(scope="module")
def problems():
    return random_problems(12, seed=11)


@pytest.fixture(scope="module")
def serial(problems):
    return [plan(p.cell, p.start, p.goal) for p in problems]


def _same(a, b):
    """Every field equal, clearance to 1e-9 m (see tests/test_batch.py's _equal)."""
    ok = a.clearance.shape == b.clearance.shape and np.allclose(a.clearance, b.clearance, rtol=0, atol=1e-9)
    assert ok and dataclasses.replace(a, clearance=b.clearance).equals(b), (a.status, a.reason, b.status, b.reason)


def test_a_worker_that_dies_fails_only_its_problem(problems, serial):
    items = list(problems)
    items[4] = dataclasses.replace(items[4], tag=Crash())
    out = plan_many(items, progress=False, chunksize=4)  # the default process pool
    assert out[4].status == "error" and "died" in out[4].reason
    for i in range(len(items)):
        if i != 4:
            _same(out[i], serial[i])


def test_two_crashes_and_an_unpicklable_problem_fail_alone(problems, serial):
    items = list(problems)
    items[1] = dataclasses.replace(items[1], tag=Crash())
    items[7] = dataclasses.replace(items[7], tag=Unpicklable())
    items[10] = dataclasses.replace(items[10], tag=Crash())
    out = plan_many(items, progress=False, chunksize=6)
    assert [o.status for o in (out[1], out[7], out[10])] == ["error", "invalid_input", "error"]
    assert "cannot be pickled" in out[7].reason
    for i in set(range(len(items))) - {1, 7, 10}:
        _same(out[i], serial[i])


def test_a_problem_that_does_not_unpickle_in_the_worker_fails_alone(problems, serial):
    items = list(problems[:5])
    items[2] = dataclasses.replace(items[2], tag=FailsToUnpickle())
    out = plan_many(items, progress=False, chunksize=5)
    assert out[2].status == "invalid_input" and "ZeroDivisionError" in out[2].reason
    for i in (0, 1, 3, 4):
        _same(out[i], serial[i])


def test_the_default_pool_does_not_fork(monkeypatch, problems, serial):
    seen = []

    class Spy(batch.ProcessPoolExecutor):
        def __init__(self, *args, **kwargs):
            seen.append(kwargs.get("mp_context"))
            super().__init__(*args, **kwargs)

    monkeypatch.setattr(batch, "ProcessPoolExecutor", Spy)
    out = plan_many(problems[:3], progress=False)
    assert seen and all(c is not None and c.get_start_method() in ("forkserver", "spawn") for c in seen)
    for a, b in zip(out, serial[:3]):
        _same(a, b)


class LosesChunks(Executor):
    """Runs work at once in this thread, but loses every chunk of more than one problem (as a
    cluster whose worker died would) and every chunk holding a problem of index in ``poison``
    (the problems arrive pickled: (index, cell key, bytes))."""

    def __init__(self, poison=()):
        self.submitted, self.poison = [], set(poison)

    def submit(self, fn, /, *args, **kwargs):
        items = args[0]
        self.submitted.append(len(items))
        f: Future = Future()
        if len(items) > 1 or any(i in self.poison for i, *_ in items):
            f.set_exception(RuntimeError("worker lost"))
        else:
            f.set_result(fn(*args, **kwargs))
        return f


def test_a_lost_chunk_is_retried_problem_by_problem(problems, serial):
    items = list(problems[:6])
    ex = LosesChunks(poison={2})
    out = plan_many(items, executor=ex, progress=False, chunksize=3)
    assert ex.submitted == [3, 3, 1, 1, 1, 1, 1, 1]
    assert out[2].status == "error" and "worker lost" in out[2].reason
    for i in (0, 1, 3, 4, 5):
        _same(out[i], serial[i])


class Inline(Executor):
    def submit(self, fn, /, *args, **kwargs):
        f: Future = Future()
        f.set_result(fn(*args, **kwargs))
        return f


def test_chunking_is_linear_in_the_number_of_problems():
    """20,000 one-problem chunks (bad problems: each fails at once): rebuilding the whole
    enumerated list per chunk took minutes; this takes about a second."""
    t0 = time.perf_counter()
    out = plan_many(["not a problem"] * 20_000, executor=Inline(), progress=False, chunksize=1)
    assert time.perf_counter() - t0 < 15.0
    assert len(out) == 20_000 and {o.status for o in out} == {"invalid_input"}


@pytest.mark.parametrize(
    "kwargs",
    [{"problems": None}, {"problems": 5}, {"problems": "abc"}, {"problems": np.array(1.0)}, {"problems": {"a": 1}},
     {"executor": "abc"}, {"executor": 5}, {"progress": "yes"}, {"progress": np.zeros(3)}, {"chunksize": True},
     {"chunksize": 0}, {"chunksize": 2.5}, {"params": {"step": 0.1}}],
)
def test_bad_arguments_are_parameter_errors(kwargs):
    args = {"problems": [], "executor": ThreadPoolExecutor(1), "progress": False} | kwargs
    with pytest.raises(ParameterError):
        plan_many(**args)


def test_a_script_without_a_main_guard_gets_a_reason(tmp_path):
    """The workers import the calling script (forkserver): without the guard they die starting up;
    every problem then says why, and nothing hangs."""
    script = tmp_path / "unguarded.py"
    script.write_text(textwrap.dedent("""
        from dualpuma import plan_many
        from dualpuma.scenarios import random_problems
        out = plan_many(random_problems(3), progress=False)
        print(sorted({o.status for o in out}), out[0].reason)
    """))
    src = str(Path(dualpuma.__file__).parents[1])  # the dualpuma under test, whatever the cwd
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([src, os.environ.get("PYTHONPATH", "")])}
    r = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120, cwd=tmp_path,
                       check=False, env=env)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "['error']" in r.stdout and "__main__" in r.stdout


class Exits:
    """Unpickling this raises SystemExit (not an Exception) in the process that does it."""

    def __reduce__(self):
        return (sys.exit, (7,))


def test_a_problem_raising_system_exit_in_its_worker_fails_alone(problems, serial):
    """SystemExit escaped the worker's `except Exception`, came back through the future and ended
    the calling script with exit code 7: every other plan was lost."""
    items = list(problems[:6])
    items[3] = dataclasses.replace(items[3], tag=Exits())
    out = plan_many(items, progress=False, chunksize=3)
    assert out[3].status == "invalid_input" and "SystemExit" in out[3].reason
    for i in (0, 1, 2, 4, 5):
        _same(out[i], serial[i])


def test_dask_never_unpickles_a_problem_in_the_calling_process(problems, serial):
    """Dask's tokenising round-tripped the arguments through pickle in the caller: a problem that
    kills the process unpickling it killed the caller (exit 3, no plans). The problems now travel as
    bytes; with worker processes, only that problem fails."""
    import distributed

    items = list(problems[:5])
    items[4] = dataclasses.replace(items[4], tag=Crash())
    with (distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cluster,
          distributed.Client(cluster) as client):
        out = plan_many(items, executor=client.get_executor(), progress=False, chunksize=5)
    assert out[4].status == "error"
    for i in range(4):
        _same(out[i], serial[i])


def test_the_workers_exit_when_the_caller_is_killed(tmp_path):
    """A scheduler's SIGKILL of the calling script left its workers running and then idle for good,
    with a temporary directory of marker files; they now exit within about a second and remove it."""
    script = tmp_path / "caller.py"
    script.write_text(
        "import os, sys\n"
        "from dualpuma import plan_many\n"
        "from dualpuma.scenarios import random_problems\n"
        "if __name__ == '__main__':\n"
        "    plan_many(random_problems(400, seed=5), progress=False, chunksize=200)\n")
    env = {**os.environ, "TMPDIR": str(tmp_path)}
    proc = subprocess.Popen([sys.executable, str(script)], env=env, cwd=tmp_path)
    marks = []
    deadline = time.time() + 60
    while time.time() < deadline and not marks:  # the batch is under way once a marker exists
        marks = [d for d in tmp_path.glob("dualpuma-plan-many-*") if any(d.iterdir())]
        time.sleep(0.1)
    assert marks, "the batch never started"
    workers = _children_of_forkserver(proc.pid)
    proc.kill()
    proc.wait()
    t0 = time.time()
    while time.time() - t0 < 15 and (any(_alive(p) for p in workers) or marks[0].exists()):
        time.sleep(0.1)
    assert workers and not any(_alive(p) for p in workers), workers
    assert not marks[0].exists()


def _children(pid: int) -> list[int]:
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            out.append(int(stat.parent.name))
    return out


def _children_of_forkserver(pid: int) -> list[int]:
    """The pool's workers: children of the caller's forkserver (a child of the caller)."""
    return [w for c in _children(pid) for w in _children(c)]


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")


def test_ctrl_c_stops_the_workers_after_their_current_problem(tmp_path):
    """Ctrl-C (SIGINT to the caller, as Jupyter's interrupt sends it) waited for the running chunks
    to finish (12.7 s in a user's batch of 1,600); the workers now stop before their next problem.
    Here each worker holds one chunk of 400 problems (several seconds of planning)."""
    script = tmp_path / "caller.py"
    script.write_text(
        "import signal\n"
        "from dualpuma import plan_many\n"
        "from dualpuma.scenarios import random_problems\n"
        "if __name__ == '__main__':\n"
        "    signal.signal(signal.SIGINT, signal.default_int_handler)\n"
        "    plan_many(random_problems(800, seed=5), progress=False, chunksize=400)\n")
    proc = subprocess.Popen([sys.executable, str(script)], env={**os.environ, "TMPDIR": str(tmp_path)}, cwd=tmp_path,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while time.time() < deadline and not any(any(d.glob("*.done")) for d in tmp_path.glob("dualpuma-plan-many-*")):
        time.sleep(0.05)
    def planned() -> int:  # problems the workers have finished (a marker each)
        return sum(1 for d in tmp_path.glob("dualpuma-plan-many-*") for _ in d.glob("*.done"))

    before = planned()
    assert before, "the batch never started"
    proc.send_signal(signal.SIGINT)
    most = before
    while proc.poll() is None:  # until the caller has ended, and its markers' directory is gone
        most = max(most, planned())
        time.sleep(0.02)
    err = proc.stderr.read()
    assert proc.returncode != 0 and "KeyboardInterrupt" in err
    assert planned() == 0  # the markers' directory is gone
    # after the interrupt each worker finished at most the problem it was planning (before: its
    # whole chunk of 400, all 800 planned)
    assert most <= before + 6, (before, most)


def test_bad_executors_are_refused_before_any_work(problems):
    """The class instead of an instance, or an executor already shut down, gave every problem a
    cryptic 'worker failed: AttributeError ...' plan."""
    with pytest.raises(ParameterError, match=r"executor: .*got the class ThreadPoolExecutor: pass an instance"):
        plan_many(problems[:2], executor=ThreadPoolExecutor, progress=False)
    ex = ThreadPoolExecutor(1)
    ex.shutdown()
    with pytest.raises(ParameterError, match=r"executor: cannot submit work: RuntimeError"):
        plan_many(problems[:2], executor=ex, progress=False)


def test_a_world_for_a_cell_and_one_problem_for_a_list_are_named(problems):
    p = problems[0]
    out = plan_many([batch.Problem(dualpuma.World(p.cell), p.start, p.goal), p], progress=False)
    assert out[0].status == "invalid_input" and out[0].reason == "cell: expected a dualpuma Cell, got World"
    assert out[1].status == plan(p.cell, p.start, p.goal).status
    with pytest.raises(ParameterError, match=r"this is one problem \(cell, start, goal\), not a list of them"):
        plan_many((p.cell, p.start, p.goal), progress=False)
