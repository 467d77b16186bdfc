"""Self-collision and floor pairs (dualpuma.model.pairs): the derived allowed-pairs list is
re-derived and checked against an independent reference (Pinocchio FK of one arm, capsules built
here from the URDF's numbers, the exact segment distance of tests/geometry_reference.py); the
World refuses a wrist inside its own pedestal; a tilted base keeps its column against the floor."""

from __future__ import annotations

import dataclasses
import math

import coal
import numpy as np
import pinocchio as pin
import pytest
from geometry_reference import capsule_capsule, capsule_halfspace

from dualpuma import Cell, World, plan
from dualpuma.kinematics import KNOWN_ROBOTS, Arm
from dualpuma.kinematics import puma as puma_ik
from dualpuma.model import Grasp
from dualpuma.model.pairs import (
    GEOMETRY_TOL,
    SELF_PAIR_TABLE,
    SELF_PAIR_THRESHOLD,
    classify_self_pairs,
    fingerprint,
    self_pairs,
    stored_for,
    verdicts,
)

# the PUMA 560's collision capsules, copied from kinematics/data/puma560.urdf (link, z-offsets in
# the link frame are applied through Pinocchio's frame placements below): name -> (radius, length)
_RADII = {"pedestal": (0.12, 0.2404), "column": (0.11, 0.24), "shoulder": (0.1, 0.18909),
          "upper_arm": (0.075, 0.4318), "elbow": (0.07, 0.12), "forearm": (0.05, 0.36307),
          "wrist": (0.045, 0.06), "gripper": (0.035, 0.11)}


def _segments(arm: Arm, q: np.ndarray, T_world_base=None) -> dict:
    """World segments (p0, p1, r) of every capsule: Pinocchio FK of the arm's own model."""
    data = arm.model.createData()
    pin.forwardKinematics(arm.model, data, q)
    out = {}
    for c in arm.capsules:
        Tj = np.eye(4) if c.joint == 0 else data.oMi[c.joint].homogeneous
        M = (np.eye(4) if T_world_base is None else T_world_base) @ Tj @ c.placement
        r, L = _RADII[c.name]
        assert c.radius == pytest.approx(r) and c.length == pytest.approx(L, abs=1e-5)
        half = 0.5 * L * M[:3, 2]
        out[c.name] = (M[:3, 3] - half, M[:3, 3] + half, r)
    return out


@pytest.fixture(scope="module")
def puma():
    return Arm.puma560()


def test_table_is_the_derivation(puma):
    """The stored verdicts are what classify_self_pairs derives (kinds exactly; bounds to coal's
    tolerance across processes)."""
    derived = classify_self_pairs(puma)
    table = SELF_PAIR_TABLE["puma560"]
    assert [(v.a, v.b, v.kind) for v in derived] == [(v.a, v.b, v.kind) for v in table]
    for d, t in zip(derived, table):
        assert d.bound == pytest.approx(t.bound, abs=2e-6)
        if t.kind == "never":
            assert t.bound >= SELF_PAIR_THRESHOLD
    assert len(table) == 28  # 8 capsules
    checked = {(v.a, v.b) for v in table if v.kind == "checked"}
    assert checked == {("pedestal", "forearm"), ("pedestal", "wrist"), ("pedestal", "gripper"),
                       ("column", "forearm"), ("column", "wrist"), ("column", "gripper"),
                       ("shoulder", "gripper")}
    assert self_pairs(puma) == tuple(sorted(checked, key=[(v.a, v.b) for v in table].index))


@pytest.mark.parametrize("robot", [r for r in KNOWN_ROBOTS if r != "puma560"])
def test_table_is_the_derivation_other_robots(robot):
    """Every known robot's stored verdicts are the derivation for its geometry, and are used."""
    arm = Arm.load(robot)
    derived = classify_self_pairs(arm)
    assert [(v.a, v.b, v.kind) for v in derived] == [(v.a, v.b, v.kind) for v in SELF_PAIR_TABLE[robot]]
    assert stored_for(arm)
    assert verdicts(arm) is SELF_PAIR_TABLE[robot]


def test_stored_verdicts_serve_a_geometry_within_the_tolerance_only(puma):
    """Capsules fitted to meshes shift between versions of the mesh tools by more than rounding
    (UR3's did, under the exact digest the table used before): the table serves a geometry within
    GEOMETRY_TOL of the one it was derived for, and not one further off."""
    import copy

    assert stored_for(puma)
    near, far = copy.copy(puma), copy.copy(puma)
    c0 = puma.capsules[0]
    near.capsules = (dataclasses.replace(c0, radius=c0.radius + 0.5 * GEOMETRY_TOL),) + tuple(puma.capsules[1:])
    far.capsules = (dataclasses.replace(c0, radius=c0.radius + 1e-4),) + tuple(puma.capsules[1:])
    assert fingerprint(near) != fingerprint(puma)  # the old exact digest would have refused it
    assert stored_for(near) and not stored_for(far)


def test_an_arm_of_another_geometry_is_classified_not_looked_up(tmp_path):
    """A URDF named like a known robot but with other geometry (a longer forearm) does not get the
    stored verdicts: its own are derived (and kept for the next World). (Its arm is not even named
    like the robot: a URDF arm never is.)"""
    import re

    from dualpuma.kinematics import example_robot_data_dir

    src = (example_robot_data_dir() / "ur_description/urdf/ur5_robot.urdf").read_text()
    longer = re.sub(r'(<joint name="wrist_1_joint".*?<origin rpy="[^"]*" xyz=")([^"]*)"',
                    lambda m: m.group(1) + "0.0 0.0 0.5" + '"', src, count=1, flags=re.DOTALL)
    assert longer != src
    d = tmp_path / "ur5"
    d.mkdir()
    (d / "ur5.urdf").write_text(longer)
    arm = Arm.from_urdf(d / "ur5.urdf", "tool0")
    assert arm.robot == "ur5 from ur5.urdf" and not stored_for(arm)
    v = verdicts(arm)
    assert v is not SELF_PAIR_TABLE["ur5"] and v == classify_self_pairs(arm) and verdicts(arm) is v


def test_verdicts_hold_on_fresh_samples(puma):
    """On 20,000 configurations drawn with another seed (FK here, coal on capsules built here): no
    pair proven 'never' comes closer than its bound, every 'adjacent' pair stays within the
    threshold, 'rigid' pairs keep their distance, and 'checked' pairs do come within it."""
    rng = np.random.default_rng(2024)
    lim = puma.limits
    table = {(v.a, v.b): v for v in SELF_PAIR_TABLE["puma560"]}
    lowest = {k: np.inf for k in table}
    highest = {k: -np.inf for k in table}
    shapes = {n: coal.Capsule(r, L) for n, (r, L) in _RADII.items()}
    req = coal.DistanceRequest()
    for q in rng.uniform(lim[:, 0], lim[:, 1], (20_000, 6)):
        tf = {}
        for n, (p0, p1, _) in _segments(puma, q).items():
            z = (p1 - p0) / np.linalg.norm(p1 - p0)
            x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
            x /= np.linalg.norm(x)
            tf[n] = coal.Transform3s(np.column_stack([x, np.cross(z, x), z]), 0.5 * (p0 + p1))
        for (a, b) in table:
            d = coal.distance(shapes[a], tf[a], shapes[b], tf[b], req, coal.DistanceResult())
            lowest[a, b] = min(lowest[a, b], d)
            highest[a, b] = max(highest[a, b], d)
    for k, v in table.items():
        if v.kind == "never":
            assert lowest[k] >= v.bound - 1e-9, (k, lowest[k], v.bound)
        elif v.kind == "adjacent":
            assert highest[k] < SELF_PAIR_THRESHOLD, (k, highest[k])
        elif v.kind == "rigid":
            assert highest[k] - lowest[k] < 1e-9
        else:  # reachable: some sample comes within the threshold too, or the witness is close
            assert min(lowest[k], v.bound) < SELF_PAIR_THRESHOLD and highest[k] >= SELF_PAIR_THRESHOLD


def _wrist_in_pedestal(puma, depth: float) -> np.ndarray:
    """Left-arm joints whose wrist is ``depth`` [m] inside its own pedestal (independent reference),
    with every other capsule pair of the arm clear of each other except adjacent ones."""
    rng = np.random.default_rng(7)
    lim = puma.limits
    for _ in range(200_000):
        q = rng.uniform(lim[:, 0], lim[:, 1])
        s = _segments(puma, q)
        if capsule_capsule(s["pedestal"], s["wrist"]) < -depth:
            break
    else:  # pragma: no cover
        raise AssertionError("no configuration with the wrist in the pedestal")
    q_in = q
    q_out = np.array([0.0, -math.pi / 4, -math.pi / 2, 0.0, 0.0, 0.0])  # arm raised
    assert capsule_capsule(_segments(puma, q_out)["pedestal"], _segments(puma, q_out)["wrist"]) > 0.1
    for _ in range(80):  # bisect the joint-space line for the depth
        mid = 0.5 * (q_in + q_out)
        s = _segments(puma, mid)
        if capsule_capsule(s["pedestal"], s["wrist"]) < -depth:
            q_in = mid
        else:
            q_out = mid
    return q_in


def test_wrist_inside_its_own_pedestal_is_refused(puma):
    cell = Cell.default()
    world = World(cell)
    q = _wrist_in_pedestal(puma, 0.0105)
    s = _segments(puma, q, cell.left.T_world_base)
    ref = capsule_capsule(s["pedestal"], s["wrist"])
    assert ref == pytest.approx(-0.0105, abs=1e-9)
    c = world.clearance(q, cell.right.q_home, per_pair=True)
    assert c.distance <= ref + 1e-6
    k = world.pair_names.index(("left/pedestal", "left/wrist"))
    assert c.pair_distances[k] == pytest.approx(ref, abs=1e-6)
    assert not world.permitted(q, cell.right.q_home)
    # and the planner refuses such a start
    p = plan(cell, world.object_from_left(q), world.object_from_left(q), q_start=(q, cell.right.q_home), world=world)
    assert p.status == "invalid_start"


def _tilted(cell: Cell, angle: float) -> Cell:
    """The left base tilted by ``angle`` about its x axis through the home hand's position, so that
    the home hand stays where it held the bar (its grasp derived there, as a cell file derives it:
    a cell's home joints must hold the bar)."""
    T = np.array(cell.left.T_world_base)
    p = (T @ puma_ik.fk(cell.left.q_home))[:3, 3]
    R = T[:3, :3] @ pin.exp3(np.array([angle, 0.0, 0.0])) @ T[:3, :3].T  # the same turn in the world
    T[:3, :3] = R @ T[:3, :3]
    T[:3, 3] = p + R @ (T[:3, 3] - p)
    grasp = Grasp(np.linalg.inv(cell.T_world_object_start) @ T @ puma_ik.fk(cell.left.q_home))
    return dataclasses.replace(cell, left=dataclasses.replace(cell.left, T_world_base=T), grasp_left=grasp)


def test_floor_pairs_kept_for_a_tilted_base():
    cell = Cell.default()
    upright = set(World(cell).pair_names)
    assert ("left/column", "floor") not in upright and ("left/pedestal", "floor") not in upright
    tilted = World(_tilted(cell, math.radians(30.0)))
    names = set(tilted.pair_names)
    assert ("left/column", "floor") in names and ("left/shoulder", "floor") in names
    assert ("left/pedestal", "floor") not in names  # fixed to the world: its distance never changes
    assert ("right/column", "floor") not in names  # the right base is still upright
    # a tilted column that dips into the floor is seen (independent capsule-halfspace distance)
    cell2 = _tilted(dataclasses.replace(cell, floor_z=0.5), math.radians(60.0))
    w2 = World(cell2)
    q = np.array(cell.left.q_home)
    best = np.inf
    for q1 in np.linspace(-2.7, 2.7, 55):
        q[0] = q1
        s = _segments(Arm.puma560(), q, cell2.left.T_world_base)
        ref = capsule_halfspace(s["column"], 0.5)
        c = w2.clearance(q, cell.right.q_home, per_pair=True)
        k = w2.pair_names.index(("left/column", "floor"))
        assert c.pair_distances[k] == pytest.approx(ref, abs=1e-9)
        best = min(best, ref)
    assert best < cell2.safety_margin
