"""Timed trajectories (issue 13, item 6): both arms under the PUMA's joint limits with one time law,
on the closed chain within 0.5 mm between samples (checked here with Pinocchio FK of the combined
model, World.hand_poses), exported in the plan's JSON and NPZ."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from dualpuma import World
from dualpuma.errors import ParameterError
from dualpuma.planning import (
    PUMA_QD_MAX,
    PUMA_QDD_MAX,
    Plan,
    Trajectory,
    time_plan,
    with_trajectory,
)
from dualpuma.scenarios import routine, run_routine


def _closure(world, qL, qR) -> float:
    """Right hand's distance from its grasp on the bar held by the left hand (FK: Pinocchio),
    plus 0.1 m times the rotation error [m]."""
    cell = world.cell
    HL, HR = world.hand_poses(qL, qR)
    want = HL @ np.linalg.inv(cell.grasp_left.T_object_hand) @ cell.grasp_right.T_object_hand
    dR = want[:3, :3].T @ HR[:3, :3]
    return float(np.linalg.norm(HR[:3, 3] - want[:3, 3]) + 0.1 * math.acos(min(1.0, (np.trace(dR) - 1) / 2)))


@pytest.fixture(scope="module")
def timed():
    r = routine(4)  # two legs (a corner between them), rpy rotation
    world = World(r.cell)
    p = run_routine(4, world=world)
    assert p.reached
    return world, p, time_plan(p, world)


def test_limits_are_the_documented_nominal_values():
    np.testing.assert_allclose(np.degrees(PUMA_QD_MAX), [100, 95, 100, 150, 130, 110])
    np.testing.assert_allclose(np.degrees(PUMA_QDD_MAX), [45, 40, 75, 70, 90, 80])


def test_trajectory_runs_the_plan_at_rest_ends_within_limits(timed):
    _world, p, tr = timed
    assert tr.certified and tr.reason == ""
    assert tr.t[0] == p.t[0] and np.all(np.diff(tr.t) > 0) and np.all(np.diff(tr.t) <= 0.01 + 1e-12)
    assert tr.duration == pytest.approx(tr.t[-1] - tr.t[0])
    np.testing.assert_allclose(tr.q_left[0], p.q_left[0], atol=1e-12)
    np.testing.assert_allclose(tr.q_right[-1], p.q_right[-1], atol=1e-9)
    for a in (tr.qd_left, tr.qd_right):
        assert np.abs(a[0]).max() < 1e-9 and np.abs(a[-1]).max() < 1e-6  # rest to rest
    assert tr.row_times.shape == (p.n_steps + 1,) and np.all(np.diff(tr.row_times) > 0)
    assert tr.row_times[-1] == pytest.approx(tr.t[-1])
    qd = np.hstack([tr.qd_left, tr.qd_right])
    qdd = np.hstack([tr.qdd_left, tr.qdd_right])
    v, a = np.tile(PUMA_QD_MAX, 2), np.tile(PUMA_QDD_MAX, 2)
    assert np.all(np.abs(qd) <= v * (1 + 1e-9)) and np.all(np.abs(qdd) <= a * (1 + 1e-9))
    # the velocities are those of the positions (trapezoid rule between samples)
    q = np.hstack([tr.q_left, tr.q_right])
    h = np.diff(tr.t)[:, None]
    # (trapezoid error <= h^2 / 8 times the jump of qdd at toppra's gridpoints: < 1e-4 rad)
    np.testing.assert_allclose(np.diff(q, axis=0), 0.5 * h * (qd[1:] + qd[:-1]), atol=1e-4)


def test_closed_chain_within_tolerance_between_samples(timed):
    """One time law for both arms: the hands hold the bar within 0.5 mm at every sample and on the
    joint-linear motion between samples, while the plan's own steps played joint-linearly do not."""
    world, p, tr = timed
    worst = 0.0
    for k in range(tr.n_samples - 1):
        for s in (0.0, 0.25, 0.5, 0.75):
            qL = tr.q_left[k] + s * (tr.q_left[k + 1] - tr.q_left[k])
            qR = tr.q_right[k] + s * (tr.q_right[k + 1] - tr.q_right[k])
            worst = max(worst, _closure(world, qL, qR))
    assert worst <= 0.5e-3 and tr.closure_error <= tr.closure_tol == 0.5e-3
    steps = max(_closure(world, p.q_left[i] + 0.5 * (p.q_left[i + 1] - p.q_left[i]),
                         p.q_right[i] + 0.5 * (p.q_right[i + 1] - p.q_right[i])) for i in range(p.n_steps))
    assert steps > 1e-3  # why a trajectory is needed: the plan's 50 mm steps drift more than 1 mm


def test_json_and_npz_round_trip_with_trajectory(timed, tmp_path):
    world, p, tr = timed
    pt = with_trajectory(p, world)
    assert isinstance(pt.trajectory, Trajectory) and pt.trajectory.equals(tr)
    back = Plan.from_json(pt.to_json())
    assert back.equals(pt) and back.trajectory.equals(tr)
    assert not back.equals(p)  # the trajectory counts
    d = json.loads(pt.to_json())
    assert len(d["trajectory"]["t"]) == tr.n_samples and d["trajectory"]["certified"] is True
    path = tmp_path / "timed.npz"
    pt.save_npz(path)
    assert Plan.load_npz(path).equals(pt)
    assert Plan.from_json(p.to_json()).trajectory is None  # a plan without one stays without
    with pytest.raises(ParameterError):
        dataclasses.replace(p, trajectory="no")
    d["trajectory"].pop("q_left")
    with pytest.raises(ParameterError):
        Plan.from_dict(d)


def test_limits_and_arguments(timed):
    world, p, tr = timed
    slow = time_plan(p, world, v_max=PUMA_QD_MAX / 2, a_max=PUMA_QDD_MAX / 4)
    assert slow.duration > 1.5 * tr.duration and slow.velocity_ratio <= 1 + 1e-9
    for kw in ({"v_max": [1.0] * 5}, {"a_max": np.zeros(6)}, {"closure_tol": 0.0}, {"dt": -1.0},
               {"v_max": [1.0, 2.4e-151, 1.0, 1.0, 1.0, 1.0]}):  # the deep fuzz's find: numpy's size error
        with pytest.raises(ParameterError):
            time_plan(p, world, **kw)
    # slow limits that would need millions of samples: refused before sampling, saying why
    with pytest.raises(ParameterError, match="more than 200000 samples"):
        time_plan(p, world, v_max=np.full(6, 2e-3), a_max=np.full(6, 2e-3), dt=1e-4)
    with pytest.raises(ParameterError):
        time_plan(Plan.failed("frozen", "x"), world)
    one = time_plan(dataclasses.replace(p, T_world_object=p.T_world_object[:1], q_left=p.q_left[:1],
                                        q_right=p.q_right[:1], clearance=p.clearance[:1], pair=p.pair[:1],
                                        t=p.t[:1]), world)
    assert one.n_samples == 1 and one.duration == 0.0


def test_a_repeated_row_is_passed_at_one_time(timed):
    """A plan whose row repeats the previous one (same pose and joints: a fallback's two trees met
    at the goal with a node each there) is timed like the plan without the repeat, the repeated row
    at the same time; before, toppra's ValueError ("Bad input gridpoints") escaped time_plan."""
    world, p, tr = timed
    k = 5
    idx = np.r_[np.arange(k + 1), k, np.arange(k + 1, p.T_world_object.shape[0])]  # row k twice
    dup = dataclasses.replace(p, T_world_object=p.T_world_object[idx], q_left=p.q_left[idx], q_right=p.q_right[idx],
                              clearance=p.clearance[idx], pair=tuple(p.pair[i] for i in idx),
                              t=p.t[0] + np.arange(idx.size) * (p.t[1] - p.t[0]))
    td = time_plan(dup, world)
    np.testing.assert_array_equal(td.t, tr.t)
    np.testing.assert_array_equal(td.q_left, tr.q_left)
    np.testing.assert_array_equal(td.row_times, tr.row_times[idx])
    assert td.certified
    end = dataclasses.replace(p, T_world_object=p.T_world_object[:1].repeat(3, axis=0), q_left=p.q_left[:1].repeat(3, axis=0),
                              q_right=p.q_right[:1].repeat(3, axis=0), clearance=p.clearance[:1].repeat(3),
                              pair=p.pair[:1] * 3, t=p.t[0] + np.arange(3) * 0.1)
    still = time_plan(end, world)
    assert still.n_samples == 1 and still.duration == 0.0 and still.row_times.tolist() == [p.t[0]] * 3
