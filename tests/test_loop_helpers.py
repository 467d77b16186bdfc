"""The Striving loop's fast paths give what the plain forms give: visited keys, row tables, the
turn of a run, the planner's unchecked Plan, the World's history-free coal data."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pinocchio as pin
import pytest

from dualpuma import Cell, StrivingParams, World, plan
from dualpuma.lie import angle, rpy_to_rot
from dualpuma.model.cache import history_free_data
from dualpuma.planning.plan import Plan
from dualpuma.planning.runs import RunContext, line_rotation, n_line_steps, pose_key, pose_keys


def _plain_key(T):
    return tuple(np.round(T[:3, 3] * 1e3).astype(np.int64).tolist()
                 + np.round(T[:3, :3] * 1e3).astype(np.int64).ravel().tolist())


def test_pose_keys_are_the_plain_keys():
    rng = np.random.default_rng(4)
    Ts = []
    for scale in (1e-4, 1e-3, 0.5, 1.0, 30.0):
        for _ in range(200):
            T = np.eye(4)
            T[:3, :3] = rpy_to_rot(rng.uniform(-np.pi, np.pi, 3))
            T[:3, 3] = rng.normal(size=3) * scale
            Ts.append(T)
    Ts.append(np.eye(4) * 0.0005)  # halves round to even either way
    want = [_plain_key(T) for T in Ts]
    assert [pose_key(T) for T in Ts] == want
    assert pose_keys(Ts) == want
    assert pose_keys([]) == []


@pytest.mark.parametrize("orientation", ["slerp", "rpy", "puma"])
def test_line_rotation_is_what_n_line_steps_computes(orientation):
    cell = Cell.default()
    ctx = RunContext(World(cell), StrivingParams(orientation=orientation))
    A = cell.T_world_object_start
    rng = np.random.default_rng(1)
    for _ in range(20):
        r_a, r_b = rng.uniform(-0.3, 0.3, 3), rng.uniform(-0.3, 0.3, 3)
        A2, B = A.copy(), A.copy()
        A2[:3, :3], B[:3, :3] = rpy_to_rot(r_a), rpy_to_rot(r_b)
        B[:3, 3] += rng.uniform(-0.2, 0.2, 3)
        rot = line_rotation(ctx, A2, B, r_a, r_b)
        want = float(np.max(np.abs(r_b - r_a))) if orientation == "rpy" else angle(A2[:3, :3], B[:3, :3])
        assert rot == want
        for step in (0.01, 0.05):
            assert n_line_steps(ctx, A2, B, r_a, r_b, step, rot) == n_line_steps(ctx, A2, B, r_a, r_b, step)


def test_step_and_between_rows():
    ctx = RunContext(World(Cell.default()), StrivingParams(substeps=4))
    for m in (0, 1, 3, 7):
        rows = ctx.step_rows(m)
        assert rows.tolist() == (np.arange(1, m + 1) * 4 - 1).tolist()
        fine, k = ctx.between_rows(m)
        want = [i for i in range(4 * m) if i % 4 != 3]
        assert fine.tolist() == want and k.tolist() == [i // 4 for i in want]
        assert not rows.flags.writeable and not fine.flags.writeable
        assert ctx.step_rows(m) is rows


def test_trusted_plan_equals_the_checked_one():
    cell = Cell.default()
    B = cell.T_world_object_start.copy()
    B[:3, 3] += (-0.25, -0.05, 0.1)  # (see benchmarks/bench_planner.py)
    p = plan(cell, cell.T_world_object_start, B)
    assert p.n_steps > 5
    fields = [f.name for f in dataclasses.fields(Plan)]
    q = Plan(*[getattr(p, f) for f in fields])
    for f in fields:
        a, b = getattr(p, f), getattr(q, f)
        if isinstance(a, np.ndarray):
            assert a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b)
            assert not a.flags.writeable and a.flags.c_contiguous
        else:
            assert type(a) is type(b) and a == b
    assert all(type(x) is tuple and all(type(s) is str for s in x) for x in p.pair)


def test_history_free_data_switches_every_request_and_nothing_else():
    w = World(Cell.default())
    gd, ok = history_free_data(w.geom_model)
    assert ok
    ref = pin.GeometryData(w.geom_model)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        for reqs in (ref.distanceRequests, ref.collisionRequests):
            for r in reqs:
                r.enable_cached_gjk_guess = False
        for a, b in ((gd.distanceRequests, ref.distanceRequests), (gd.collisionRequests, ref.collisionRequests)):
            assert len(a) == len(b) == len(w.pair_ids)
            assert all(not r.enable_cached_gjk_guess for r in a)
            assert [r.saveToString() for r in a] == [r.saveToString() for r in b]


def test_puma_provider_single_pose_is_the_checked_ik_all():
    from dualpuma.kinematics import Arm, puma

    arm = Arm.puma560()
    rng = np.random.default_rng(9)
    for _ in range(200):
        q = rng.uniform(arm.limits[:, 0], arm.limits[:, 1])
        T = puma.fk(q)
        T[:3, 3] += rng.normal(size=3) * 0.3  # some out of reach
        q_near = rng.uniform(-3, 3, 6)
        s1, v1 = arm.solver.ik_all(T, q_near, arm.limits)
        s2, v2 = puma.ik_all(T, q_near=q_near, limits=arm.limits)
        assert np.array_equal(s1, s2, equal_nan=True) and np.array_equal(v1, v2)
