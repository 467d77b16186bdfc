"""plan_many: order, equality with serial planning, failure isolation, any Executor, Dask."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from dualpuma import Problem, StrivingParams, plan, plan_many
from dualpuma.errors import ParameterError
from dualpuma.scenarios import random_problems


@pytest.fixture(scope="module")
def problems():
    return random_problems(24, seed=7)


@pytest.fixture(scope="module")
def serial(problems):
    return [plan(p.cell, p.start, p.goal) for p in problems]


def _same(a, b):
    assert len(a) == len(b)
    for x, y in zip(a, b):
        assert _equal(x, y), (x.status, x.reason, y.status, y.reason)


def _equal(x, y) -> bool:
    """Every field equal, bit for bit, although the pool's processes start from forkserver (not a
    fork of this one) and ask coal other queries first: dualpuma fixes the factor coal's box support
    keeps from its first call (coal-library/coal#894; before, clearances differed by ~1e-17 m)."""
    return x.equals(y)


def test_process_pool_matches_serial_in_order(problems, serial):
    statuses = {p.status for p in serial}
    assert "reached" in statuses and len(statuses) >= 2  # the sample exercises several outcomes
    _same(plan_many(problems, progress=False), serial)


def test_bad_problems_fail_alone(problems, serial):
    bad_pose = Problem(problems[0].cell, problems[0].start, np.full((4, 4), np.nan))
    items = [problems[0], bad_pose, "not a problem", problems[1], (problems[2].cell, problems[2].start)]
    out = plan_many(items, executor=ThreadPoolExecutor(2), progress=False)
    assert len(out) == 5
    assert out[0].equals(serial[0]) and out[3].equals(serial[1])
    assert out[1].status == "invalid_input" and "goal" in out[1].reason
    assert out[2].status == "invalid_input" and "Problem" in out[2].reason
    assert out[4].status == "invalid_input"


def test_params_apply_and_validate(problems):
    p = StrivingParams(step=0.1)
    out = plan_many(problems[:4], p, executor=ThreadPoolExecutor(1), progress=False)
    ref = [plan(q.cell, q.start, q.goal, p) for q in problems[:4]]
    _same(out, ref)
    with pytest.raises(ParameterError):
        plan_many(problems[:2], params={"step": 0.1})
    with pytest.raises(ParameterError):
        plan_many(problems[:2], chunksize=0)
    assert plan_many([], progress=False) == []


def test_dask_local_cluster(problems, serial):
    import distributed  # part of the test extra: a missing install fails here, never skips
    with (distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cluster,
          distributed.Client(cluster) as client):
        out = plan_many(problems[:8], executor=client.get_executor(), progress=False, chunksize=3)
    _same(out, serial[:8])


class _Stream:
    """A stand-in for sys.stderr that reports whether it is a terminal and records what it gets."""

    def __init__(self, tty: bool) -> None:
        self.tty, self.text = tty, ""

    def isatty(self) -> bool:
        return self.tty

    def write(self, s: str) -> int:
        self.text += s
        return len(s)

    def flush(self) -> None:
        pass


@pytest.mark.parametrize("tty", [True, False])
def test_progress_bar_only_on_a_terminal(problems, serial, monkeypatch, tty):
    stream = _Stream(tty)
    monkeypatch.setattr("sys.stderr", stream)
    out = plan_many(problems[:6], executor=ThreadPoolExecutor(1), chunksize=2)
    _same(out, serial[:6])
    if tty:  # one update per finished chunk, the last one complete, then a newline
        assert [line.split(" problems")[0] for line in stream.text.split("\r")[1:]] == \
            ["plan_many: 2/6", "plan_many: 4/6", "plan_many: 6/6"]
        assert stream.text.endswith("\n")
    else:
        assert stream.text == ""


def test_a_problem_starts_at_its_t_start(problems):
    """A leg that continues another starts at the other's end time (moving obstacles checked at
    their real times); Problem had no t_start, so a batched leg was checked from t = 0."""
    from dualpuma.scenarios import rising_ball_cell

    cell, A, B = rising_ball_cell()
    alone = plan(cell, A, B, t_start=0.4)
    assert alone.t[0] == 0.4
    for ex in (None, ThreadPoolExecutor(1)):
        out = plan_many([Problem(cell, A, B, t_start=0.4), Problem(cell, A, B)], executor=ex, progress=False)
        assert out[0].equals(alone)
        assert out[1].t[0] == 0.0 and out[1].equals(plan(cell, A, B))
