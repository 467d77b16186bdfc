"""Independent checks of a plan (used by the planner tests): closed chain, limits, clearance, and
validity between steps at a finer resolution — computed with Pinocchio FK, the scalar coal query and
a fresh step-by-step IK, not with the planner's own batched code paths."""

from __future__ import annotations

import os

import numpy as np
import pinocchio as pin

from dualpuma.kinematics import solve_dual

#: The planner properties (tests/test_planner_property.py, tests/test_certified_property.py) run a
#: fixed, reproducible sample in CI. DUALPUMA_PROPERTY_RANDOM=1 draws new examples on every run and
#: DUALPUMA_PROPERTY_SCALE=N runs N times as many. The audit that found the defects fixed on
#: 2026-11-26 ran random samples of about this size: DUALPUMA_PROPERTY_RANDOM=1
#: DUALPUMA_PROPERTY_SCALE=19 (about 15 minutes for the certified-motion property).
PROPERTY_RANDOM = os.environ.get("DUALPUMA_PROPERTY_RANDOM") == "1"
PROPERTY_SCALE = max(1, int(os.environ.get("DUALPUMA_PROPERTY_SCALE", "1")))


def ball_cell(offset, radius: float, velocity, t_end: float):
    """The default cell with only a ball, placed at ``offset`` [m] from the bar's start position and
    moving at ``velocity`` [m/s] from t = 0 to ``t_end`` [s], the floor lowered out of the way:
    (cell, the bar's start position (3,))."""
    import dataclasses

    from dualpuma import Cell
    from dualpuma.model import Obstacle

    c0 = Cell.default()
    bar = (c0.T_world_object_start @ c0.bar.T_object_bar)[:3, 3]
    T = np.eye(4)
    T[:3, 3] = bar + np.asarray(offset, float)
    ball = Obstacle("ball", "sphere", [radius], T, velocity=velocity, t_start=0.0, t_end=t_end)
    return dataclasses.replace(c0, obstacles=(ball,), floor_z=-1.0), bar


def rising_into_a_ball(offset: float):
    """The default start and the bar rising 0.15 m straight up towards a ball (radius 30 mm) whose
    centre is ``offset`` [m] above the bar's centre line at 85 % of the way (the bar's half height
    is 25 mm): (cell, start pose A, end pose B, the start's dual IK (a DualSolution, ok))."""
    import dataclasses

    from dualpuma import Cell, World
    from dualpuma.lie import slerp
    from dualpuma.model import Obstacle

    base = Cell.default()
    A = base.T_world_object_start
    B = A.copy()
    B[:3, 3] += (0.0, 0.0, 0.15)
    ball = np.eye(4)
    ball[:3, 3] = (slerp(A, B, np.array([0.85]))[0] @ base.bar.T_object_bar)[:3, 3] + (0.0, 0.0, offset)
    cell = dataclasses.replace(base, obstacles=(Obstacle("ball", "sphere", [0.03], ball),))
    home = (np.asarray(cell.left.q_home, float), np.asarray(cell.right.q_home, float))
    start = solve_dual(World(cell), A, home)
    assert start.ok, start.reason
    return cell, A, B, start


def count_edge_ik(monkeypatch) -> list[int]:
    """Count the fallback edge checker's IK calls (``solve_path_unchecked`` as planning.edges calls
    it): the list grows by one per call."""
    from dualpuma.planning import edges

    calls: list[int] = []
    real = edges.solve_path_unchecked

    def counted(*a, **k):
        calls.append(1)
        return real(*a, **k)

    monkeypatch.setattr(edges, "solve_path_unchecked", counted)
    return calls


GJK_TOL = 1e-6  # coal's GJK/EPA answers box/capsule distances to about this, depending on warm starts


def check_plan_valid(world, plan, *, margin: float, fine: int = 5, max_joint_step: float = np.radians(20.0)) -> None:
    """Assert every step and ``fine - 1`` poses between steps are permitted (raises AssertionError)."""
    cell = world.cell
    n = plan.T_world_object.shape[0]
    assert n >= 1
    for i in range(n):
        T = plan.T_world_object[i]
        qL, qR = plan.q_left[i], plan.q_right[i]
        HL, HR = world.hand_poses(qL, qR)  # Pinocchio FK
        np.testing.assert_allclose(HL, T @ cell.grasp_left.T_object_hand, atol=1e-9, err_msg=f"left grasp at step {i}")
        np.testing.assert_allclose(HR, T @ cell.grasp_right.T_object_hand, atol=1e-9, err_msg=f"right grasp at step {i}")
        for side, q in (("left", qL), ("right", qR)):
            lim = world.arms[side].limits
            assert np.all(q >= lim[:, 0] - 1e-12) and np.all(q <= lim[:, 1] + 1e-12), f"{side} limits at step {i}"
        c = world.clearance(qL, qR, T, float(plan.t[i]))
        assert c.distance >= margin - GJK_TOL, f"step {i}: clearance {c.distance} ({c.pair})"
        assert abs(c.distance - plan.clearance[i]) < GJK_TOL, f"step {i}: reported clearance differs"
        if i == 0:
            continue
        dq = max(np.abs(qL - plan.q_left[i - 1]).max(), np.abs(qR - plan.q_right[i - 1]).max())
        assert dq <= max_joint_step + 1e-9, f"step {i}: joint step {np.degrees(dq):.2f} deg"
        # between steps: SE(3) geodesic sub-poses, each solved continuing the previous one
        A = plan.T_world_object[i - 1]
        w = pin.log3(A[:3, :3].T @ T[:3, :3])
        q = (plan.q_left[i - 1], plan.q_right[i - 1])
        for k in range(1, fine + 1):
            s = k / fine
            M = np.eye(4)
            M[:3, :3] = A[:3, :3] @ pin.exp3(s * w)
            M[:3, 3] = A[:3, 3] + s * (T[:3, 3] - A[:3, 3])
            t = float(plan.t[i - 1] + s * (plan.t[i] - plan.t[i - 1]))
            sol = solve_dual(world, M, q, max_step=max_joint_step, check_clearance=False, t=t)
            assert sol.ok, f"between steps {i - 1} and {i} (s={s}): {sol.reason}"
            d = world.clearance(sol.q_left, sol.q_right, M, t).distance
            assert d >= margin - GJK_TOL, f"between steps {i - 1} and {i} (s={s}): clearance {d}"
            q = (sol.q_left, sol.q_right)
        np.testing.assert_allclose(q[0], qL, atol=1e-6, err_msg=f"left joints discontinuous before step {i}")
        np.testing.assert_allclose(q[1], qR, atol=1e-6, err_msg=f"right joints discontinuous before step {i}")
