"""Contact maps of the UR arms' always-close link pairs, checked against coal on the URDF meshes.

The reference here is independent of dualpuma's loaders: the URDF read by Pinocchio itself, its
collision meshes placed by Pinocchio's FK for the whole six-joint vector, and coal's mesh distance.
"""

from __future__ import annotations

import math

import coal
import numpy as np
import pinocchio as pin
import pytest

from dualpuma.collision import first_contact_chord, self_contact, unmapped_sides
from dualpuma.kinematics import Arm
from dualpuma.model import World, example_cell
from dualpuma.model.contact import CONTACT_CLEARANCE, GRID, close_pairs, contact_maps
from dualpuma.planning.certify import certify_chords
from dualpuma.planning.reach import motion_bounds

#: the pairs the stored maps hold cells for (the others are proven clear everywhere)
MAPPED = {"ur3": {("base_link", "upper_arm_link")},
          "ur5": {("base_link", "upper_arm_link"), ("forearm_link", "wrist_2_link")},
          "ur10": {("forearm_link", "wrist_2_link")}}


class MeshReference:
    """coal's distance between two links' collision meshes at whole joint vectors of the URDF."""

    def __init__(self, arm: Arm) -> None:
        self.model = pin.buildModelFromUrdf(str(arm.urdf_path))
        self.geom = pin.buildGeomFromUrdf(self.model, str(arm.urdf_path), pin.COLLISION, package_dirs=list(arm.package_dirs))
        self.data, self.gd = self.model.createData(), pin.GeometryData(self.geom)
        self.names = [g.name.removesuffix("_0") for g in self.geom.geometryObjects]

    def distance(self, q: np.ndarray, a: str, b: str) -> float:
        pin.updateGeometryPlacements(self.model, self.data, self.geom, self.gd, q)
        ia, ib = self.names.index(a), self.names.index(b)
        tf = [coal.Transform3s(self.gd.oMg[i].rotation, self.gd.oMg[i].translation) for i in (ia, ib)]
        return float(coal.distance(self.geom.geometryObjects[ia].geometry, tf[0], self.geom.geometryObjects[ib].geometry,
                                   tf[1], coal.DistanceRequest(), coal.DistanceResult()))


@pytest.mark.parametrize("robot", ["ur3", "ur5", "ur10"])
def test_stored_maps_serve_the_known_ur_arms_and_block_every_sampled_contact(robot):
    arm = Arm.load(robot)
    maps = contact_maps(arm)
    assert maps is not None and {(m.a, m.b) for m in maps} == MAPPED[robot]
    ref = MeshReference(arm)
    assert ref.model.nq == 6
    rng = np.random.default_rng(7)
    lim = np.asarray(arm.limits)
    for m in maps:
        Q = rng.uniform(lim[:, 0], lim[:, 1], (1500, 6))
        # half the samples near the blocked cells' edges, where a wrong bound would show first
        cells = np.argwhere(m.cells)
        pick = cells[rng.integers(0, len(cells), 1500)]
        near = np.tile(rng.uniform(lim[:, 0], lim[:, 1], (1, 6)), (1500, 1))
        near[:, m.joints[0]] = -math.pi + (pick[:, 0] + rng.uniform(-3, 4, 1500)) * 2 * math.pi / GRID
        near[:, m.joints[1]] = -math.pi + (pick[:, 1] + rng.uniform(-3, 4, 1500)) * 2 * math.pi / GRID
        Q = np.vstack([Q, near])
        d = np.array([ref.distance(q, m.a, m.b) for q in Q])
        blocked = m.blocked(Q)
        assert not np.any((d < CONTACT_CLEARANCE) & ~blocked), "a configuration the meshes put in contact is not blocked"
        assert np.any(d < CONTACT_CLEARANCE), "the sample never came near contact: the test proves nothing"
        # conservative, but not wildly: few configurations 3 mm clear of the clearance are blocked
        assert np.mean(blocked[d > CONTACT_CLEARANCE + 0.003]) < 0.1


def test_pairs_without_a_map_never_come_within_the_clearance():
    rng = np.random.default_rng(3)
    for robot in ("ur3", "ur5", "ur10"):
        arm = Arm.load(robot)
        ref = MeshReference(arm)
        for a, b, _ in close_pairs(arm):
            if (a, b) in MAPPED[robot]:
                continue
            lim = np.asarray(arm.limits)
            d = [ref.distance(q, a, b) for q in rng.uniform(lim[:, 0], lim[:, 1], (400, 6))]
            assert min(d) >= CONTACT_CLEARANCE


def test_the_puma_has_no_close_pair_two_joints_apart_and_a_renamed_geometry_has_no_map():
    assert contact_maps(Arm.load("puma560")) == ()
    assert unmapped_sides(World(example_cell("default"))) == ()
    assert unmapped_sides(World(example_cell("ur5_pair"))) == ()


def test_box_blocked_is_true_wherever_a_blocked_cell_is_in_the_box():
    m = next(x for x in contact_maps(Arm.load("ur5")) if x.a == "forearm_link")
    rng = np.random.default_rng(5)
    n = 3000
    Qa = rng.uniform(-2 * math.pi, 2 * math.pi, (n, 6))
    Qb = Qa + rng.normal(0.0, 0.15, (n, 6)) * rng.choice([0.1, 1.0, 5.0], (n, 1))
    got = m.box_blocked(Qa, Qb)
    h = 2 * math.pi / GRID
    want = np.empty(n, dtype=bool)
    for i in range(n):  # brute force: every cell the two joints pass between their ends
        spans = []
        for j in m.joints:
            lo, hi = sorted((Qa[i, j], Qb[i, j]))
            k0 = math.floor(((lo + math.pi) % (2 * math.pi)) / h)
            k1 = k0 + math.floor(((lo + math.pi) % (2 * math.pi) + hi - lo) / h) - k0
            spans.append(np.arange(k0, min(k1, k0 + GRID - 1) + 1) % GRID)
        want[i] = m.cells[np.ix_(spans[0], spans[1])].any()
    assert not np.any(want & ~got)
    assert np.any(want)
    assert np.mean(got & ~want) < 0.2  # the cover's conservatism


def test_a_joint_chord_through_the_wrist_contact_is_refused_at_the_chord_that_enters_it():
    world = World(example_cell("ur5_pair"))
    arm = world.arms["left"]
    ref = MeshReference(arm)
    q0 = np.asarray(world.cell.left.q_home, float)
    # sweep the left wrist_1 joint (wrist_2 at q5 = 0) until the meshes touch: the chord into that
    # point must be refused
    steps = np.radians(np.arange(0.0, 360.0, 4.0))
    QL = np.tile(q0, (steps.size, 1))
    QL[:, 3] = q0[3] + steps
    QL[:, 4] = 0.0
    d_ref = np.array([ref.distance(q, "forearm_link", "wrist_2_link") for q in QL])
    touching = np.flatnonzero(d_ref < CONTACT_CLEARANCE)
    assert touching.size, "the sweep never reaches the contact"
    Q = np.hstack([QL, np.tile(np.asarray(world.cell.right.q_home, float), (steps.size, 1))])
    first, why = first_contact_chord(world, Q)
    assert first <= touching[0] - 1 and "forearm_link – wrist_2_link" in why and why.startswith("left arm")
    # clear chords before it: the independent reference finds the meshes apart along them
    fine = np.linspace(0.0, 1.0, 9)
    for i in range(first):
        seg = QL[i] + fine[:, None] * (QL[i + 1] - QL[i])
        assert min(ref.distance(q, "forearm_link", "wrist_2_link") for q in seg) >= CONTACT_CLEARANCE
    # the certificate the planners and the timing use refuses it too (clearances given as clear)
    reach, v = motion_bounds(world)
    cert = certify_chords(world, Q, np.full(len(Q), 1.0), np.zeros(len(Q)), 0.0, reach, v)
    assert cert.n_ok == first and "self-contact" in cert.reason and math.isnan(cert.distance)
    # and the configuration query names it
    assert self_contact(world, QL[touching[0]], Q[touching[0], 6:])[0] == ("left", "forearm_link", "wrist_2_link")
    assert self_contact(world, QL[0], Q[0, 6:])[0] is None


def test_a_start_whose_meshes_touch_is_refused_by_the_planner():
    import dataclasses

    from dualpuma.kinematics.dual import hands_from_object
    from dualpuma.planning import plan

    cell = dataclasses.replace(example_cell("ur5_pair"), obstacles=())  # (the stands would refuse it first)
    world = World(cell)
    A = cell.T_world_object_start
    # the left arm's shoulder-back, elbow-down branch at the start pose folds its upper arm down by its base
    q = world.arms["left"].ik(hands_from_object(cell, A)[0], config=0).q
    assert MeshReference(world.arms["left"]).distance(q, "base_link", "upper_arm_link") < CONTACT_CLEARANCE
    q_right = np.asarray(cell.right.q_home, float)
    assert world.clearance(q, q_right, A).distance >= cell.safety_margin  # the capsules alone pass it
    B = A.copy()
    B[:3, 3] += [0.02, 0.0, 0.02]
    p = plan(cell, A, B, q_start=(q, q_right), world=world)
    assert p.status == "invalid_start"
    assert "left arm base_link – upper_arm_link" in p.reason and "self-contact" in p.reason


def test_the_real_envelope_with_clearance_proves_its_points_with_joints_out_of_contact():
    """Before contact maps, 145 of 548 inside points of this sample were proven by joints whose
    meshes touched (base-upper arm, forearm-wrist_2); the same points are inside now, by other branches."""
    import dataclasses

    from dualpuma.envelope import solve_real

    cell = dataclasses.replace(example_cell("ur5_pair"), obstacles=())
    world = World(cell)
    rng = np.random.default_rng(1)
    P = cell.T_world_object_start[:3, 3] + rng.uniform([-0.8, -0.8, -0.6], [0.8, 0.8, 0.6], (1000, 3))
    m = solve_real(cell, P, world=world)
    assert m.inside.sum() > 100
    refs = {s: MeshReference(world.arms[s]) for s in ("left", "right")}
    for i in np.flatnonzero(m.inside).tolist():
        for s, q in (("left", m.q_left[i]), ("right", m.q_right[i])):
            for a, b in (("forearm_link", "wrist_2_link"), ("base_link", "upper_arm_link")):
                assert refs[s].distance(q, a, b) >= CONTACT_CLEARANCE, (i, s, a, b)
