"""Timed trajectories (issue 13, item 6): both arms under the PUMA's joint limits with one time law,
on the closed chain within 0.5 mm between samples (checked here with Pinocchio FK of the combined
model, World.hand_poses), exported in the plan's JSON and NPZ."""

from __future__ import annotations

import dataclasses
import json
import math
import re

import numpy as np
import pytest
from motion_reference import MotionReference

from dualpuma import World, plan
from dualpuma.errors import ParameterError
from dualpuma.planning import (
    PUMA_QD_MAX,
    PUMA_QDD_MAX,
    Plan,
    Trajectory,
    time_plan,
    with_trajectory,
)
from dualpuma.scenarios import rising_ball_cell, routine, run_routine


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
    # a margin in millimetres by mistake: said so, as the planners' and the cell's margins say it (it
    # was taken as 20 m: "not certified, below 20.000 m")
    with pytest.raises(ParameterError, match="the margin is in metres"):
        time_plan(p, world, margin=20)
    # slow limits that would need millions of samples: refused before sampling, saying why
    with pytest.raises(ParameterError, match="more than 200000 samples"):
        time_plan(p, world, v_max=np.full(6, 2e-3), a_max=np.full(6, 2e-3), dt=1e-4)
    with pytest.raises(ParameterError):
        time_plan(Plan.failed("frozen", "x"), world)
    # a plan that failed before it moved is not a motion: it was given a certified one-sample
    # trajectory of its start
    stay = dataclasses.replace(p, status="invalid_goal", reason="outside its reach",
                               **{f: getattr(p, f)[:1] for f in ("T_world_object", "q_left", "q_right", "clearance", "t")},
                               pair=p.pair[:1])
    with pytest.raises(ParameterError, match="status invalid_goal is no motion to execute"):
        time_plan(stay, world)
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


# ----------------------------------------------------------------------------- moving obstacles
def _rising_ball(t_start: float, t_end: float):
    """:func:`~dualpuma.scenarios.rising_ball_cell` and its plan (the planner's clock passes the
    ball's column before the ball moves)."""
    cell, A, B = rising_ball_cell(t_start, t_end)
    world = World(cell)
    p = plan(cell, A, B, world=world)
    assert p.reached, p.reason
    return cell, world, p


def _reference_min(cell, tr) -> float:
    """The smallest clearance of a trajectory at its samples and halfway between consecutive
    samples (joint-linear, time-linear), by the independent reference (tests/motion_reference.py)."""
    ref = MotionReference(cell)
    Q, t = np.hstack([tr.q_left, tr.q_right]), tr.t
    Qm, tm = np.vstack([Q, 0.5 * (Q[1:] + Q[:-1])]), np.concatenate([t, 0.5 * (t[1:] + t[:-1])])
    return min(ref.clearance(q[:6], q[6:], float(s), cell.safety_margin)[0] for q, s in zip(Qm, tm))


def test_a_ball_crossing_the_fastest_timing_is_waited_for():
    """The fastest timing (1.3 s) takes the bar through the ball's column while the ball rises
    (t = 0.5..1.0 s); the plan's own clock passed before it moved. time_plan waits at the first row
    instead, and the waiting and the motion keep the margin at their real times by the independent
    reference; without a wait or slowdown allowed it says the fastest timing is not certified, and
    the reference finds that timing inside the margin."""
    cell, world, p = _rising_ball(0.5, 1.0)
    margin = cell.safety_margin
    fastest = time_plan(p, world, max_wait=0.0, max_slowdown=1.0)
    assert not fastest.certified and fastest.start_delay == 0.0 and fastest.time_scale == 1.0
    assert _reference_min(cell, fastest) < margin - 0.01
    # the reason names the first refusal and the least clearance at the samples (the reference's)
    ref = MotionReference(cell)
    least = min(ref.clearance(a, b, float(s), margin)[0] for a, b, s in zip(fastest.q_left, fastest.q_right, fastest.t))
    shown = float(re.search(r"\(the least clearance of the checked pairs at the samples: (-?\d+\.\d+) m\)", fastest.reason).group(1))
    assert shown == pytest.approx(least, abs=1e-4) and shown < 0.0
    tr = time_plan(p, world)
    assert tr.certified, tr.reason
    assert tr.start_delay > 0.0 and tr.time_scale == 1.0 and "waits" in tr.retimed
    assert _reference_min(cell, tr) >= margin - 1e-6
    wait = tr.t < tr.t[0] + tr.start_delay
    assert np.count_nonzero(wait) >= 2 and np.all(np.diff(tr.t) <= 0.01 + 1e-12)
    np.testing.assert_array_equal(tr.q_left[wait], np.repeat(p.q_left[:1], np.count_nonzero(wait), axis=0))
    assert not np.any(tr.qd_left[wait]) and not np.any(tr.qdd_right[wait])
    # the motion after the wait is the fastest one shifted in time
    np.testing.assert_allclose(tr.row_times[1:], fastest.row_times[1:] + tr.start_delay, atol=1e-9)
    np.testing.assert_allclose(tr.duration, fastest.duration + tr.start_delay, atol=1e-9)
    assert tr.velocity_ratio <= 1.0 + 1e-9 and tr.acceleration_ratio <= 1.0 + 1e-9
    # after the wait: the same samples as the fastest timing's, shifted
    np.testing.assert_allclose(tr.t[~wait], fastest.t + tr.start_delay, atol=1e-9)
    np.testing.assert_array_equal(tr.q_right[~wait], fastest.q_right)


def test_a_slower_timing_when_waiting_is_not_allowed():
    """With no wait allowed, the earliest slowdown that lets the ball pass is used (the ball rises
    at t = 0.5..1.0 s): the joints follow the fastest path at a uniformly slower pace."""
    cell, world, p = _rising_ball(0.5, 1.0)
    fastest = time_plan(p, world, max_wait=0.0, max_slowdown=1.0)
    tr = time_plan(p, world, max_wait=0.0)
    assert tr.certified, tr.reason
    assert tr.start_delay == 0.0 and tr.time_scale > 1.0 and "slower" in tr.retimed
    np.testing.assert_allclose(tr.duration, tr.time_scale * fastest.duration, rtol=1e-9)
    np.testing.assert_allclose(tr.velocity_ratio, fastest.velocity_ratio / tr.time_scale, rtol=1e-2)  # other sample times
    assert _reference_min(cell, tr) >= cell.safety_margin - 1e-6


def test_no_timing_passes_a_ball_that_parks_on_the_path():
    """A ball that rises into the bar's path and stays there (t_end = 0.6 s): no wait and no
    slowdown helps; the fastest timing is returned, not certified, saying so."""
    cell, world, p = _rising_ball(0.45, 0.6)
    tr = time_plan(p, world)
    assert not tr.certified and "no wait at the first row up to 10 s" in tr.reason
    late = max((tr.row_times[i] - tr.row_times[0]) / (p.t[i] - p.t[0]) for i in range(1, p.t.shape[0]))
    assert late > 2.0 and f"up to {late:.1f}x sooner than the arms can reach them" in tr.reason  # 0.1 s a step
    assert tr.start_delay == 0.0 and tr.time_scale == 1.0 and tr.retimed == ""
    assert _reference_min(cell, tr) < cell.safety_margin


def test_timing_without_moving_obstacles_is_the_fastest(timed):
    _, _, tr = timed
    assert tr.start_delay == 0.0 and tr.time_scale == 1.0 and tr.retimed == ""


def test_wait_and_slowdown_arguments_and_old_files(timed, tmp_path):
    world, p, tr = timed
    for kw in ({"max_wait": -1.0}, {"max_wait": math.nan}, {"max_slowdown": 0.5}, {"max_slowdown": math.inf}):
        with pytest.raises(ParameterError):
            time_plan(p, world, **kw)
    d = tr.to_dict()
    assert d["start_delay"] == 0.0 and d["time_scale"] == 1.0
    for bad in ({"start_delay": -0.1}, {"time_scale": 0.9}, {"start_delay": None}):
        with pytest.raises(ParameterError):
            Trajectory.from_dict({**d, **bad})
    old = {k: v for k, v in d.items() if k not in ("start_delay", "time_scale")}  # written before they existed
    assert Trajectory.from_dict(old).equals(tr)
    moved = dataclasses.replace(tr, start_delay=1.5, time_scale=2.0)
    assert Trajectory.from_dict(moved.to_dict()).equals(moved) and not moved.equals(tr)
    pt = dataclasses.replace(p, trajectory=moved)
    path = tmp_path / "moved.npz"
    pt.save_npz(path)
    assert Plan.load_npz(path).trajectory.equals(moved)


def test_candidates_beyond_the_sample_bound_are_skipped(monkeypatch):
    """A wait or slowdown that would need more than MAX_SAMPLES samples is not tried (it used to
    raise from inside the search although the fastest timing fitted): with the bound between the
    fastest timing's 129 samples and the waiting one's 169, the fastest is returned, not certified."""
    from dualpuma.planning import timing

    _, world, p = _rising_ball(0.5, 1.0)
    assert time_plan(p, world).n_samples > 150
    monkeypatch.setattr(timing, "MAX_SAMPLES", 150)
    tr = time_plan(p, world)
    assert not tr.certified and tr.start_delay == 0.0 and tr.n_samples <= 150


def test_rising_ball_cell_arguments():
    with pytest.raises(ParameterError):
        rising_ball_cell(1.0, 0.5)
    with pytest.raises(ParameterError):
        rising_ball_cell(math.nan, 1.0)


# ----------------------------------------------------------------------------- a controller's clock
def test_samples_on_a_controller_clock(timed):
    """period=0.004 (a 250 Hz joint controller): every sample exactly 4 ms after the previous one
    from the plan's start, the last one the first at or after the end of the motion, at rest there;
    the same motion as the per-piece timing (its row times; its joints at the clock's instants, by
    interpolating a 1 ms per-piece sampling); within the limits, the closed chain (Pinocchio FK) and
    the margin (the independent reference) at the samples and between them."""
    world, p, tr = timed
    P = 0.004
    clk = time_plan(p, world, period=P)
    assert clk.period == P and tr.period == 0.0 and clk.certified, clk.reason
    assert clk.t[0] == p.t[0] and np.abs(np.diff(clk.t) - P).max() <= 1e-12
    np.testing.assert_allclose(clk.row_times, tr.row_times, rtol=0, atol=1e-9)  # the same time law
    assert tr.row_times[-1] <= clk.t[-1] < tr.row_times[-1] + P + 1e-12
    assert abs(np.diff(tr.t) - 0.01).max() > 1e-6  # the default samples are not on a clock
    np.testing.assert_allclose(clk.q_right[-1], p.q_right[-1], atol=1e-9)
    for a in (clk.qd_left, clk.qd_right, clk.qdd_left):
        assert not np.any(a[-1])  # at rest after the end
    fine = time_plan(p, world, dt=0.001)
    Qf, Qc = np.hstack([fine.q_left, fine.q_right]), np.hstack([clk.q_left, clk.q_right])
    on = np.column_stack([np.interp(clk.t, fine.t, Qf[:, j]) for j in range(12)])
    assert np.abs(on - Qc).max() < 1e-5  # linear interpolation of 1 ms samples: error ~ qdd h^2 / 8
    qd, qdd = np.hstack([clk.qd_left, clk.qd_right]), np.hstack([clk.qdd_left, clk.qdd_right])
    assert np.all(np.abs(qd) <= np.tile(PUMA_QD_MAX, 2) * (1 + 1e-9))
    assert np.all(np.abs(qdd) <= np.tile(PUMA_QDD_MAX, 2) * (1 + 1e-9))
    worst = max(_closure(world, clk.q_left[k] + s * (clk.q_left[k + 1] - clk.q_left[k]),
                         clk.q_right[k] + s * (clk.q_right[k + 1] - clk.q_right[k]))
                for k in range(0, clk.n_samples - 1, 3) for s in (0.0, 0.5))
    assert worst <= clk.closure_tol and clk.closure_error <= clk.closure_tol
    assert _reference_min(world.cell, clk) >= world.cell.safety_margin - 1e-6


def test_a_period_too_long_for_the_closed_chain_is_refused_naming_one_that_is_not(timed):
    """A controller's cycle is not halved: 0.1 s with a 0.2 mm closed-chain tolerance is refused,
    saying which period keeps it; that period is then accepted and keeps it (Pinocchio FK)."""
    world, p, _ = timed
    with pytest.raises(ParameterError, match=r"at a period of 0.1 s .* a period of ([0-9.]+) s keeps it") as e:
        time_plan(p, world, period=0.1, closure_tol=2e-4)
    import re

    shorter = float(re.search(r"a period of ([0-9.]+) s keeps it", str(e.value)).group(1))
    ok = time_plan(p, world, period=shorter, closure_tol=2e-4)
    assert ok.period == shorter and np.abs(np.diff(ok.t) - shorter).max() <= 1e-12
    worst = max(_closure(world, 0.5 * (ok.q_left[k] + ok.q_left[k + 1]), 0.5 * (ok.q_right[k] + ok.q_right[k + 1]))
                for k in range(ok.n_samples - 1))
    assert worst <= 2e-4 and ok.closure_error <= 2e-4
    for kw in ({"period": 0.0}, {"period": -0.004}, {"period": math.nan}, {"period": 2.0},
               {"period": 0.004, "dt": 0.01}):
        with pytest.raises(ParameterError):
            time_plan(p, world, **kw)


def test_a_shorter_period_beyond_the_sample_bound_is_not_offered(timed, monkeypatch):
    """When halving the period would need more than MAX_SAMPLES samples, the refusal says so
    instead of naming a period that would be refused in turn (routine 4 takes 3.8 s: 39 samples
    at 0.1 s, 78 at 0.05 s)."""
    from dualpuma.planning import timing

    world, p, _ = timed
    monkeypatch.setattr(timing, "MAX_SAMPLES", 60)
    with pytest.raises(ParameterError, match="no shorter period fits the sample bound"):
        time_plan(p, world, period=0.1, closure_tol=2e-4)


def test_a_wait_on_a_controller_clock_is_whole_periods():
    """The rising ball, timed on a 30 ms clock: the timing waits a whole number of periods, at rest
    on the clock's instants, and then runs the fastest clocked motion shifted by that many periods;
    the reference keeps the margin at the real times."""
    P = 0.03
    cell, world, p = _rising_ball(0.5, 1.0)
    fastest = time_plan(p, world, period=P, max_wait=0.0, max_slowdown=1.0)
    assert not fastest.certified
    tr = time_plan(p, world, period=P)
    assert tr.certified and tr.period == P and tr.time_scale == 1.0, tr.reason
    m = round(tr.start_delay / P)
    assert m >= 1 and abs(tr.start_delay - m * P) <= 1e-12 and np.abs(np.diff(tr.t) - P).max() <= 1e-12
    np.testing.assert_array_equal(tr.q_left[:m], np.repeat(p.q_left[:1], m, axis=0))
    assert not np.any(tr.qd_right[:m])
    np.testing.assert_allclose(np.hstack([tr.q_left[m:], tr.q_right[m:]]),
                               np.hstack([fastest.q_left, fastest.q_right]), rtol=0, atol=1e-9)
    assert tr.closure_error <= tr.closure_tol
    assert _reference_min(cell, tr) >= cell.safety_margin - 1e-6


def test_the_period_in_files(timed, tmp_path):
    """The period is written (JSON, NPZ) and read back; files written before it existed read as 0;
    a file that claims a period its sample times do not keep is refused."""
    world, p, tr = timed
    clk = time_plan(p, world, period=0.02)
    assert Trajectory.from_dict(json.loads(json.dumps(clk.to_dict()))).equals(clk)
    pt = dataclasses.replace(p, trajectory=clk)
    pt.save_npz(tmp_path / "clk.npz")
    assert Plan.load_npz(tmp_path / "clk.npz").trajectory.equals(clk)
    old = {k: v for k, v in tr.to_dict().items() if k != "period"}
    assert Trajectory.from_dict(old).period == 0.0
    for bad in ({**tr.to_dict(), "period": 0.01},  # per-piece samples are not 10 ms apart
                {**clk.to_dict(), "period": 0.021}, {**clk.to_dict(), "period": -0.02},
                {**clk.to_dict(), "period": None}):
        with pytest.raises(ParameterError):
            Trajectory.from_dict(bad)


def test_a_plan_keeps_the_margin_along_the_bars_path_between_its_rows():
    """A problem on which the planner used to return a reached plan whose bar path dipped between
    its checked poses (its 77 mm step was checked every 25 % at 30.5 / 22.1 / 20.4 / 23.2 mm; the
    path between the 50 % and 75 % poses reached 19.55 mm, and its timed trajectory was not
    certified). The planner now certifies that path: the plan it returns keeps the margin along it
    (a Pinocchio-only tracking of both hands, 20 poses a step, and the independent reference), and
    its timed trajectory is certified and keeps the margin by the reference."""
    from motion_reference import MotionReference

    from dualpuma import StrivingParams
    from dualpuma.planning import SEED_ALTERNATES
    from dualpuma.scenarios import random_problem

    prob = random_problem(2231170221, max_obstacles=4)
    world, margin = World(prob.cell), prob.cell.safety_margin
    p = plan(prob.cell, prob.start, prob.goal, StrivingParams(step=0.1, substeps=2, orientation="puma",
                                                              alternates=SEED_ALTERNATES, max_recoveries=20),
             world=world)
    assert p.reached
    assert MotionReference(prob.cell).plan_path_min(p, margin, end_tol=1e-7)[0] >= margin - 1e-9
    tr = time_plan(p, world)
    assert tr.certified, tr.reason
    assert _reference_min(prob.cell, tr) >= margin - 1e-9


def _urdf_hand_error(cell, side: str, q, T_world_object) -> float:
    """How far the hand (the PUMA's wrist frame, by Pinocchio FK of the URDF) is from its grasp of
    the bar at T_world_object [m]: position error plus 0.1 m times the rotation angle."""
    from pathlib import Path

    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(Path(__file__).resolve().parent.parent / "urdf" / "puma560.urdf"))
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.asarray(q, float))
    H = getattr(cell, side).T_world_base @ data.oMf[model.getFrameId("wrist")].homogeneous
    want = T_world_object @ getattr(cell, f"grasp_{side}").T_object_hand
    c = (np.trace(H[:3, :3].T @ want[:3, :3]) - 1.0) / 2.0
    return float(np.linalg.norm(H[:3, 3] - want[:3, 3]) + 0.1 * math.acos(min(1.0, max(-1.0, c))))


def test_rows_that_do_not_hold_the_bar_in_this_cell_are_refused_before_timing():
    """time_plan timed an invalid_start plan whose joints (zeros) do not hold the bar, certified,
    with a closed-chain error of 1.1 m; a plan's rows edited by 0.001 rad were refused for a period
    (wrong advice); a plan of another cell got a wrist-singularity message. Rows are checked first:
    the message names the row, the hand and how far it is off (Pinocchio's FK of the URDF)."""
    from dualpuma import Cell
    from dualpuma.model import example_cell

    cell = Cell.default()
    w = World(cell)
    S = cell.T_world_object_start
    p0 = plan(cell, S, S, q_start=(np.zeros(6), np.zeros(6)), world=w)
    assert p0.status == "invalid_start"
    with pytest.raises(ParameterError, match="status invalid_start is no motion"):
        time_plan(p0, w)
    with pytest.raises(ParameterError, match=r"time_plan: row 0 does not hold the bar in this World's cell: the left "
                                             r"hand is (\d+\.\d+) m off its grasp") as e:
        time_plan(dataclasses.replace(p0, status="frozen"), w)  # its rows, as a plan that moved
    shown = float(re.search(r"is (\d+\.\d+) m off", str(e.value)).group(1))
    assert shown == pytest.approx(_urdf_hand_error(cell, "left", np.zeros(6), S), abs=1e-7) and shown > 0.5
    G = S.copy()
    G[0, 3] -= 0.1
    p = plan(cell, S, G, world=w)
    assert time_plan(p, w).certified  # the plan as made holds the bar: timed
    qR = p.q_right.copy()
    qR[2, 1] += 0.001
    edited = dataclasses.replace(p, q_right=qR)
    with pytest.raises(ParameterError, match=r"row 2 does not hold the bar in this World's cell: the right hand is "):
        time_plan(edited, w)
    assert _urdf_hand_error(cell, "right", qR[2], p.T_world_object[2]) > 1e-4
    with pytest.raises(ParameterError, match=r"row 0 does not hold the bar in this World's cell"):
        time_plan(p, World(example_cell("mixed_puma_ur5")), a_max=np.ones(6))
