"""Any two 6-DOF arms carrying one bar: the shipped mixed cells (a PUMA 560 and a UR5; two UR5s)
and an arm from a URDF path. Every step of a returned plan keeps the grasp, checked with
Pinocchio models built here directly from each arm's URDF file (independent of dualpuma's Arm)."""

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from urdf_reference import FullUrdf

from dualpuma import CellError, World, example_cell, load_cell, plan
from dualpuma.kinematics import Arm, RobotSpec
from dualpuma.lie import rot_to_rpy, rpy_to_rot
from dualpuma.model import cell_to_toml

ARM6 = Path(__file__).parent / "data" / "arm6.urdf"
MOVES = [((-0.15, 0.0, 0.0), (0, 0, 0)), ((0.1, -0.1, 0.1), (0, 0, 0)), ((0.0, 0.0, 0.15), (0, 0, 20)),
         ((0.05, 0.05, 0.0), (10, 0, -15)), ((0.0, 0.0, 0.05), (0, 15, 0)), ((-0.1, 0.0, -0.05), (0, -10, 10))]


def goal(cell, d, rpy_deg):
    A = cell.T_world_object_start
    B = A.copy()
    B[:3, 3] += d
    B[:3, :3] = rpy_to_rot(rot_to_rpy(A[:3, :3]) + np.radians(rpy_deg))
    return B


def independent_fk(cell):
    """Per side: a function q -> T_world_hand from a Pinocchio model of the arm's URDF file."""
    out = {}
    for side in ("left", "right"):
        arm = Arm.load(getattr(cell, side).robot)  # only for the file path and the joint/frame names
        ref = FullUrdf(arm.urdf_path, [arm.model.names[j] for j in range(1, 7)], arm.hand_frame)
        T_wb = getattr(cell, side).T_world_base
        out[side] = lambda q, ref=ref, T_wb=T_wb: T_wb @ ref.fk(q)
    return out


def assert_grasp_kept(cell, p):
    fk = independent_fk(cell)
    for T, qL, qR in zip(p.T_world_object, p.q_left, p.q_right):
        np.testing.assert_allclose(fk["left"](qL), T @ cell.grasp_left.T_object_hand, atol=1e-9)
        np.testing.assert_allclose(fk["right"](qR), T @ cell.grasp_right.T_object_hand, atol=1e-9)


@pytest.mark.parametrize("name", ["mixed_puma_ur5", "ur5_pair"])
def test_shipped_cell_starts_well_inside_and_clear(name):
    cell = example_cell(name)
    w = World(cell)
    c = w.clearance(cell.left.q_home, cell.right.q_home)
    assert c.distance > cell.safety_margin
    for side in ("left", "right"):
        arm, q = w.arms[side], getattr(cell, side).q_home
        assert arm.analytic  # PUMA and UR5: closed forms
        assert np.all(q > arm.limits[:, 0] + 0.4) and np.all(q < arm.limits[:, 1] - 0.4)  # > 23 deg from every limit
        assert abs(math.sin(q[4])) > 0.4 and arm.manipulability(q) > 0.02  # away from the singularities
    assert w.arms["right"].robot == "ur5" and w.arms["left"].robot == ("puma560" if name.startswith("mixed") else "ur5")


@pytest.mark.parametrize("name", ["mixed_puma_ur5", "ur5_pair"])
@pytest.mark.parametrize(("d", "rpy"), MOVES)
def test_plans_reach_and_keep_the_grasp(name, d, rpy):
    cell = example_cell(name)
    p = plan(cell, cell.T_world_object_start, goal(cell, d, rpy))
    assert p.reached, p.reason
    assert np.allclose(p.T_world_object[-1], goal(cell, d, rpy), atol=1e-12)
    assert p.min_clearance >= cell.safety_margin
    assert_grasp_kept(cell, p)


@pytest.mark.parametrize("name", ["mixed_puma_ur5", "ur5_pair"])
def test_goal_beyond_reach_is_refused_naming_the_arm(name):
    """1.2 m up: the left hand's target is farther from its base than the largest base-to-hand
    distance over 20k random joint vectors of the URDF (Pinocchio), so no IK can exist."""
    cell = example_cell(name)
    B = goal(cell, (0.0, 0.0, 1.2), (0, 0, 0))
    fk = independent_fk(cell)
    arm = Arm.load(cell.left.robot)
    rng = np.random.default_rng(2)
    Q = rng.uniform(arm.limits[:, 0], arm.limits[:, 1], (20_000, 6))
    T_wb = cell.left.T_world_base
    reach = max(np.linalg.norm(fk["left"](q)[:3, 3] - T_wb[:3, 3]) for q in Q)
    target = (B @ cell.grasp_left.T_object_hand)[:3, 3]
    assert np.linalg.norm(target - T_wb[:3, 3]) > reach + 0.1
    p = plan(cell, cell.T_world_object_start, B)
    assert p.status == "invalid_goal" and "left arm" in p.reason and "reach" in p.reason


def _z1_cell():
    """The mixed cell with example-robot-data's Unitree Z1 (gripper joint locked, numeric IK)
    holding the bar's right end where the UR5's hand was."""
    import dataclasses

    from dualpuma.model import ArmMount, Grasp

    base = example_cell("mixed_puma_ur5")
    base = dataclasses.replace(base, obstacles=tuple(o for o in base.obstacles if o.name != "stand_right"))
    arm = Arm.load("z1")
    q = np.array([0.0, 1.0, -1.0, 0.0, 0.6, 0.0])
    T_wh = base.T_world_object_start @ base.grasp_right.T_object_hand  # where the UR5's hand was
    T_wb = np.eye(4)
    T_wb[:3, :3] = rpy_to_rot([0.0, 0.0, math.radians(195.0)])
    T_wb[:3, 3] = T_wh[:3, 3] - T_wb[:3, :3] @ arm.fk(q)[:3, 3]
    grasp = Grasp(np.linalg.inv(base.T_world_object_start) @ T_wb @ arm.fk(q))
    return dataclasses.replace(base, right=ArmMount("right", "z1", T_wb, q), grasp_right=grasp)


def test_cell_with_a_named_numeric_arm(tmp_path):
    """``robot = "z1"`` (example-robot-data's Unitree Z1, gripper joint locked, numeric IK) holds
    the bar's right end with a PUMA; the cell file round-trips; plans keep the grasp."""
    cell = _z1_cell()
    text = cell_to_toml(cell)
    assert 'robot = "z1"' in text
    (tmp_path / "z1.toml").write_text(text)
    loaded = load_cell(tmp_path / "z1.toml")
    assert World(loaded).clearance(loaded.left.q_home, loaded.right.q_home).distance > loaded.safety_margin
    for d, rpy in [*MOVES[:2], ((0.0, 0.0, 0.05), (0, 0, 10))]:  # the Z1 is a small arm (reach 0.85 m)
        p = plan(loaded, loaded.T_world_object_start, goal(loaded, d, rpy))
        assert p.reached, (d, rpy, p.reason)
        assert_grasp_kept(loaded, p)


def test_cell_with_a_urdf_arm(tmp_path):
    """``robot = { urdf = ..., tip = ... }`` (relative to the cell file): a generic arm with a
    numeric IK carries the bar with a PUMA; the plan keeps the grasp."""
    base = example_cell("mixed_puma_ur5")
    arm = Arm.from_urdf(ARM6, "tool")
    T_wb = np.eye(4)
    T_wb[:3, 3] = (2.3, -0.45, 0.0)
    T_wb[:3, :3] = rpy_to_rot([0.0, 0.0, math.pi])
    T_bh = np.linalg.inv(T_wb) @ base.T_world_object_start @ base.grasp_right.T_object_hand
    r = arm.ik(T_bh, q_near=np.array([0.0, 0.5, 1.3, 0.0, 1.3, 0.0]))
    assert r.ok, r.reason
    import dataclasses

    from dualpuma.model import ArmMount

    cell = dataclasses.replace(base, right=ArmMount("right", RobotSpec(ARM6, "tool"), T_wb, r.q), obstacles=())
    text = cell_to_toml(cell).replace(str(ARM6), "arm6.urdf")
    (tmp_path / "arm6.urdf").write_text(ARM6.read_text())
    (tmp_path / "cell.toml").write_text(text)
    loaded = load_cell(tmp_path / "cell.toml")
    assert loaded.right.robot == RobotSpec(tmp_path / "arm6.urdf", "tool")
    p = plan(loaded, loaded.T_world_object_start, goal(loaded, (-0.05, 0.0, 0.05), (0, 0, 5)))
    assert p.reached, p.reason
    assert_grasp_kept(loaded, p)
    bad = text.replace('tip = "tool"', 'tip = "no_such_frame"')
    (tmp_path / "bad.toml").write_text(bad)
    with pytest.raises(CellError, match="no_such_frame"):
        load_cell(tmp_path / "bad.toml")
    (tmp_path / "missing.toml").write_text(text.replace("arm6.urdf", "gone.urdf"))
    with pytest.raises(CellError, match="gone.urdf"):
        load_cell(tmp_path / "missing.toml")


def cli(*args):
    return subprocess.run([sys.executable, "-m", "dualpuma.cli", *args], capture_output=True, text=True, timeout=300,
                          check=False)


def test_cli_plan_and_envelope_on_mixed_cells():
    r = cli("plan", "--cell", "mixed_puma_ur5", "--by", "-100", "0", "50", "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["status"] == "reached"
    r = cli("envelope", "--cell", "ur5_pair", "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["model"] == "real" and d["volume_m3"] > 0.1 and d["xz_boundary_m"]


def test_hold_bar_with_a_numeric_arm():
    """The certificate's bisection solves both arms at bar poses on the path (kinematics.bar_path.
    hold_bar); a Z1 (numeric IK) holding the right end continues from its nearby joints like a
    Pinocchio-only tracking of its hand along the bar's path, and a pose out of its reach is not held."""
    from motion_reference import MotionReference

    from dualpuma.kinematics.bar_path import hold_bar

    cell = _z1_cell()
    world, ref = World(cell), MotionReference(cell)
    A = cell.T_world_object_start
    q0 = np.concatenate([cell.left.q_home, cell.right.q_home])
    targets = []
    for d in ((0.01, 0.0, 0.0), (0.0, -0.01, 0.01), (0.0, 0.0, -0.015)):
        B = A.copy()
        B[:3, 3] += d
        targets.append(B)
    Q, ok = hold_bar(world, np.array(targets), np.tile(q0, (3, 1)))
    assert ok.all()
    for k, B in enumerate(targets):
        np.testing.assert_allclose(Q[k], ref.bar_path(A, B, q0, 20)[-1], atol=1e-6)
    far = A.copy()
    far[:3, 3] += (0.0, 0.0, 1.5)
    assert not hold_bar(world, far[None], q0[None])[1][0]
