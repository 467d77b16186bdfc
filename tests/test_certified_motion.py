"""Certified motion (issue 13, item 2): a returned plan keeps the margin along the motion between
its rows (the arms holding the bar along its path, which the timed trajectory follows), for
Striving, the fallback and its shortcuts, whatever ``substeps`` is (checked here with the
independent reference of tests/motion_reference.py at 20 poses per step, each arm tracked with
Pinocchio alone); and the certificate itself (planning/certify.py) against brute force."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from motion_reference import MotionReference
from planner_checks import ball_cell

from dualpuma import Cell, StrivingParams, World, plan
from dualpuma.collision import clearance_batch
from dualpuma.kinematics import solve_dual
from dualpuma.model import Obstacle
from dualpuma.planning import FallbackParams, rrt_connect
from dualpuma.planning.certify import certify_chords
from dualpuma.planning.reach import motion_bounds

TOL = 1e-6


def _path_min(ref: MotionReference, p, margin: float) -> float:
    """The lowest clearance along the bar's path between the rows of a plan or fallback result p
    (the certified motion; the joint chord between rows leaves the closed chain and is not it)."""
    return ref.plan_path_min(p, margin)[0]


@pytest.fixture(scope="module")
def rod():
    """A thin rod (5 mm) parallel to the bar, 60 mm above it: the bar's straight 120 mm lift in one
    step ends 30 mm clear on both sides of it, but passes through it halfway."""
    c0 = Cell.default()
    A = c0.T_world_object_start
    B = A.copy()
    B[:3, 3] += (0.0, 0.0, 0.12)
    T = np.eye(4)
    T[:3, :3] = [[0, 0, 1], [0, 1, 0], [-1, 0, 0]]
    T[:3, 3] = (A @ c0.bar.T_object_bar)[:3, 3] + (0.0, 0.0, 0.06)
    cell = dataclasses.replace(c0, obstacles=(Obstacle("rod", "capsule", [0.005, 0.2], T),))
    return cell, World(cell), A, B, MotionReference(cell)


BIG = {"step": 0.2, "substeps": 1, "max_joint_step": math.radians(45.0)}


def test_striving_one_substep_does_not_jump_through_the_rod(rod):
    cell, world, A, B, ref = rod
    assert ref.clearance(cell.left.q_home, cell.right.q_home, 0.0, 0.02)[0] >= 0.02
    p = plan(cell, A, B, StrivingParams(alternates=(), **BIG), world=world)
    assert p.n_steps == 0 or _path_min(ref, p, cell.safety_margin) >= 0.02 - TOL
    assert not p.reached and "not certified" in p.reason and "obstacle/rod" in p.reason


@pytest.mark.parametrize("substeps", [1, 3])
def test_fallback_paths_are_certified(rod, substeps):
    cell, world, A, B, ref = rod
    fp = FallbackParams(substeps=substeps, step=0.2, max_joint_step=math.radians(45.0), max_iterations=500)
    res = rrt_connect(world, A, (cell.left.q_home, cell.right.q_home), B, fp, 0)
    assert res.ok, res.reason
    assert _path_min(ref, res, cell.safety_margin) >= 0.02 - TOL
    p = plan(cell, A, B, StrivingParams(alternates=(), fallback=True, fallback_params=fp, **BIG), world=world)
    assert p.reached and p.planner == "striving+rrt"
    assert _path_min(ref, p, cell.safety_margin) >= 0.02 - TOL


def test_certificate_against_brute_force(rod):
    """certify_chords accepts a chord only if dense brute force finds no configuration below the
    margin on it, refuses one that crosses the rod with a distance below the margin, and accepts a
    far chord without any query."""
    cell, world, _, B, _ = rod
    reach, v = motion_bounds(world)
    q0 = np.concatenate([cell.left.q_home, cell.right.q_home])
    rng = np.random.default_rng(5)
    accepted = refused = refused_real = 0
    for _ in range(600):
        a = q0 + rng.normal(0, 0.05, 12)
        Q = np.vstack([a, a + rng.normal(0, 0.05, 12)])
        d, _ = clearance_batch(world, Q[:, :6], Q[:, 6:])
        if d.min() < 0.02:
            continue
        cert = certify_chords(world, Q, d, np.zeros(2), 0.02, reach, v)
        s = np.linspace(0.0, 1.0, 401)[:, None]
        dense, _ = clearance_batch(world, (Q[0] + s * (Q[1] - Q[0]))[:, :6], (Q[0] + s * (Q[1] - Q[0]))[:, 6:])
        if cert.n_ok == 1:
            accepted += 1
            assert dense.min() >= 0.02 - TOL
        else:
            refused += 1
            assert np.isnan(cert.distance) or cert.distance < 0.02
            refused_real += bool(dense.min() < 0.02)
    assert accepted >= 20 and refused_real >= 1, (accepted, refused, refused_real)
    # the one-step lift through the rod: both ends 30 mm clear, refused with the rod's pair
    sol = solve_dual(world, B, (cell.left.q_home, cell.right.q_home), check_clearance=False)
    Q = np.vstack([q0, np.concatenate([sol.q_left, sol.q_right])])
    d, _ = clearance_batch(world, Q[:, :6], Q[:, 6:])
    assert d.min() >= 0.02
    cert = certify_chords(world, Q, d, np.zeros(2), 0.02, reach, v)
    assert cert.n_ok == 0 and cert.distance < 0.0 and "obstacle/rod" in cert.reason
    far = np.vstack([q0, q0 + 1e-4])
    d, _ = clearance_batch(world, far[:, :6], far[:, 6:])
    c = certify_chords(world, far, d, np.zeros(2), 0.02, reach, v)
    assert c.n_ok == 1 and c.queries == 0


def test_moving_obstacle_speed_is_part_of_the_bound():
    """A ball that crosses where the arms stand still: both ends of the 'motion' (the same
    configuration at t = 0 and t = 1 s) are clear, the middle is not."""
    c0, bar = ball_cell((0.0, -0.5, 0.0), 0.05, (0.0, 1.0, 0.0), 1.0)
    w = World(c0)
    q = np.concatenate([c0.left.q_home, c0.right.q_home])
    Q = np.vstack([q, q])
    T2 = np.eye(4)
    T2[:3, 3] = bar + (0.0, 0.5, 0.0)
    ends = [w.clearance(q[:6], q[6:], t=t).distance for t in (0.0, 1.0)]
    assert min(ends) >= 0.02 and w.clearance(q[:6], q[6:], t=0.5).distance < 0.0
    reach, v = motion_bounds(w)
    assert v == pytest.approx(1.0)
    cert = certify_chords(w, Q, np.array(ends), np.array([0.0, 1.0]), 0.02, reach, v)
    assert cert.n_ok == 0 and "obstacle/ball" in cert.reason


def test_every_pairs_own_bound_holds():
    """For random chords, no pair's distance (every pair, kernel without pruning) changes by more
    than its own bound W_k . |dq| (pair_weights); turning q1 leaves an arm's distance to its own
    upright pedestal and to the floor unchanged (weight 0, and really unchanged)."""
    from dualpuma.collision import pair_distances_batch
    from dualpuma.planning.reach import pair_weights
    from dualpuma.scenarios import random_problem

    prob = random_problem(11, max_obstacles=4)
    w = World(prob.cell)
    W, v = pair_weights(w)
    rng = np.random.default_rng(3)
    q0 = np.concatenate([prob.cell.left.q_home, prob.cell.right.q_home])
    A = q0 + rng.normal(0, 0.3, (3000, 12))
    B = A + rng.normal(0, 0.05, (3000, 12))
    dA = pair_distances_batch(w, A[:, :6], A[:, 6:])
    dB = pair_distances_batch(w, B[:, :6], B[:, 6:])
    assert np.all(np.abs(dB - dA) <= np.abs(B - A) @ W.T + 1e-9)
    k = w.pair_names.index(("right/pedestal", "right/wrist"))
    f = w.pair_names.index(("right/forearm", "floor"))
    assert W[k, 6] == 0.0 and W[f, 6] == 0.0 and W[k, 7] > 0.0 and not v.any()
    C = A.copy()
    C[:, 6] += rng.normal(0, 0.5, 3000)
    dC = pair_distances_batch(w, C[:, :6], C[:, 6:])
    np.testing.assert_allclose(dC[:, [k, f]], dA[:, [k, f]], atol=1e-9)


def test_one_substep_still_checks_the_bar_path_the_trajectory_follows():
    """Hypothesis example (seed 586240): with substeps = 1 Striving checked nothing between steps
    on the bar's path, returned 'reached', and the timed trajectory (IK along that path) came
    0.39 mm inside the 20 mm margin. Now a pose between steps is checked; and on the same problem a
    plan is never reached with a trajectory that leaves the margin: the midpoint of each step on
    the bar's path, solved by IK here and checked by the independent reference, keeps it."""
    from dualpuma import example_cell
    from dualpuma.kinematics import solve_path
    from dualpuma.lie import slerp
    from dualpuma.planning import SEED_ALTERNATES, time_plan
    from dualpuma.scenarios import random_problem

    prob = random_problem(586240, max_obstacles=4, base=example_cell("default"))
    margin = prob.cell.safety_margin
    ref = MotionReference(prob.cell)
    for sub in (1, 2):
        params = StrivingParams(step=0.05, rot_step=math.radians(2.0), substeps=sub, max_joint_step=math.radians(20.0),
                                alternates=SEED_ALTERNATES, max_recoveries=20)
        world = World(prob.cell)
        p = plan(prob.cell, prob.start, prob.goal, params, world=world)
        for i in range(p.n_steps):
            mid = slerp(p.T_world_object[i], p.T_world_object[i + 1], np.array([0.5]))
            sol = solve_path(world, mid, (p.q_left[i], p.q_right[i]), max_step=math.radians(20.0))
            d, pair = ref.clearance(sol.q_left[0], sol.q_right[0], float(p.t[i]), margin)
            assert d >= margin - 1e-6, (sub, i, d, pair)
        if p.reached:
            tr = time_plan(p, world)
            assert tr.certified, tr.reason


# Two rows of a plan the planner returned before it certified the bar's path (random_problem(2231170221,
# max_obstacles=4), Striving 0.1 m steps, two substeps, orientation "puma"): the joint chord between them keeps
# the margin, the arms holding the bar between them do not (right upper arm against obstacle o2).
_DIP_ROW_1 = np.array([[0.9967541267054533, -0.08050596807472919, 0.0, 1.8904892796646209],
                       [-0.08050596807472919, -0.9967541267054533, 0.0, -0.20663153658016914],
                       [0.0, 0.0, -1.0, 0.29307036144330334], [0.0, 0.0, 0.0, 1.0]])
_DIP_Q_1 = np.array([1.0779459230015718, 0.021460371120488153, -0.6673310277562146, 0.0, 0.6458706566357264,
                     -0.41225721841227986, -0.15992950478058648, -0.0029665426057362554, 0.5104966780184425, 0.0,
                     -0.5075301354127062, -1.6501326461944377])
_DIP_ROW_2 = np.array([[0.9870375782087014, -0.16048931180580758, 0.0, 1.8194941100914945],
                       [-0.16048931180580758, -0.9870375782087014, 0.0, -0.2123530427465295],
                       [0.0, 0.0, -1.0, 0.32131581195036174], [0.0, 0.0, 0.0, 1.0]])
_DIP_Q_2 = np.array([1.0421430562701355, -0.13194655252774934, -0.33475257886563337, 0.0, 0.4666991313933827,
                     -0.3674668997626706, -0.4675352450644804, -0.06913284726888835, 0.5753410765608257, 0.0,
                     -0.5062082292919374, -1.877145201097286])


def test_the_bars_path_is_certified_not_the_joint_chord():
    """The motion a plan's rows stand for is the arms holding the bar along its path between them (a
    timed trajectory follows it). Between these two rows the joint chord keeps the 20 mm margin (an
    independent reference at 41 points) but that path does not: a Pinocchio-only tracking of both
    hands along it (160 poses), checked by the same reference, comes to 19.55 mm. The chord is
    certified as a chord and refused as the bar's path, at a point the reference confirms."""
    from dualpuma.scenarios import random_problem

    cell = random_problem(2231170221, max_obstacles=4).cell
    world, ref, margin = World(cell), MotionReference(cell), cell.safety_margin
    for q, T in ((_DIP_Q_1, _DIP_ROW_1), (_DIP_Q_2, _DIP_ROW_2)):  # the rows hold the bar
        H = world.hand_poses(q[:6], q[6:])
        np.testing.assert_allclose(H[0], T @ cell.grasp_left.T_object_hand, atol=1e-9)
        np.testing.assert_allclose(H[1], T @ cell.grasp_right.T_object_hand, atol=1e-9)
    Q = np.stack([_DIP_Q_1, _DIP_Q_2])
    chord = [ref.clearance(*np.split(Q[0] + s * (Q[1] - Q[0]), 2), 0.0, margin)[0] for s in np.linspace(0, 1, 41)]
    path = ref.bar_path(_DIP_ROW_1, _DIP_ROW_2, _DIP_Q_1, 160)
    np.testing.assert_allclose(path[-1], _DIP_Q_2, atol=1e-8)  # the tracking ends at the second row
    along = np.array([ref.clearance(*np.split(q, 2), 0.0, margin)[0] for q in path])
    assert min(chord) >= margin + 5e-4 and along.min() < margin - 3e-4
    d = np.array([world.clearance(q[:6], q[6:]).distance for q in Q])
    reach, v = motion_bounds(world)
    assert certify_chords(world, Q, d, np.zeros(2), margin, reach, v).n_ok == 1
    cert = certify_chords(world, Q, d, np.zeros(2), margin, reach, v, closed_chain=True)
    assert cert.n_ok == 0 and cert.reason.startswith("clearance") and cert.distance < margin
    s = float(cert.reason.split("s = ")[1].split(" ")[0])  # where it was refused: the reference agrees there
    q_s = ref.bar_path(_DIP_ROW_1, _DIP_ROW_2, _DIP_Q_1, 1000)[round(1000 * s) - 1]
    assert abs(ref.clearance(*np.split(q_s, 2), 0.0, margin)[0] - cert.distance) < 1e-6
