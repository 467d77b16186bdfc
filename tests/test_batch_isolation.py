"""plan_many: one bad problem fails alone — a worker process that dies, a problem that cannot be
pickled, a chunk an executor loses — the default pool does not fork this process, chunking is
linear in the number of problems, and bad arguments are ParameterErrors."""

from __future__ import annotations

import dataclasses
import operator
import os
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
    cluster whose worker died would) and every chunk holding a problem tagged ``"poison"``."""

    def __init__(self):
        self.submitted = []

    def submit(self, fn, /, *args, **kwargs):
        items = args[0]
        self.submitted.append(len(items))
        f: Future = Future()
        if len(items) > 1 or any(getattr(raw, "tag", None) == "poison" for _, raw in items):
            f.set_exception(RuntimeError("worker lost"))
        else:
            f.set_result(fn(*args, **kwargs))
        return f


def test_a_lost_chunk_is_retried_problem_by_problem(problems, serial):
    items = list(problems[:6])
    items[2] = dataclasses.replace(items[2], tag="poison")
    ex = LosesChunks()
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
