"""Contact maps of the UR arms' always-close link pairs, checked against coal on the URDF meshes
(tests/mesh_reference.py: independent of dualpuma's loaders)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from mesh_reference import MeshReference

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


def test_the_joint_limited_and_the_urdf_loaded_ur5_share_the_ur5s_maps():
    maps = contact_maps(Arm.load("ur5"))
    assert contact_maps(Arm.load("ur5_joint_limited")) is maps  # (a map covers whole turns: limits do not matter)
    ur5 = Arm.load("ur5")
    assert contact_maps(Arm.from_urdf(ur5.urdf_path, ur5.hand_frame)) is maps
    # (an edited UR5 has none: tests/test_cli_plan.py, where `dualpuma plan` warns about it)


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


def _cells_passed(x0: float, x1: float, pad: int = 0) -> np.ndarray:
    """The grid cells a joint passes between x0 and x1 [rad], by dense sampling (each sample's cell
    from its angle alone), grown by ``pad`` cells each side."""
    h = 2 * math.pi / GRID
    xs = np.append(np.linspace(x0, x1, int(abs(x1 - x0) / (0.05 * h)) + 2), [x0, x1])
    c = np.unique(np.floor(((xs + math.pi) % (2 * math.pi)) / h).astype(int) % GRID)
    return np.unique((c[:, None] + np.arange(-pad, pad + 1)).ravel() % GRID)


@pytest.mark.parametrize("pad", [0, 2])
def test_box_blocked_counts_exactly_the_blocked_cells_the_joints_pass(pad):
    m = next(x for x in contact_maps(Arm.load("ur5")) if x.a == "forearm_link")
    rng = np.random.default_rng(5 + pad)
    n = 1500
    # motions near the blocked cells (and across the seam, in every turn, either way)
    cells = np.argwhere(m.cells)[rng.integers(0, int(m.cells.sum()), n)]
    Qa = rng.uniform(-2 * math.pi, 2 * math.pi, (n, 6))
    for c, j in enumerate(m.joints):
        Qa[:, j] = -math.pi + (cells[:, c] + rng.uniform(-20, 20, n)) * 2 * math.pi / GRID + 2 * math.pi * rng.integers(-1, 2, n)
    Qb = Qa + rng.normal(0.0, 0.05, (n, 6)) * rng.choice([0.1, 1.0, 4.0], (n, 1))
    got = m.box_blocked(Qa, Qb, pad)
    want = np.array([m.cells[np.ix_(*(_cells_passed(Qa[i, j], Qb[i, j], pad) for j in m.joints))].any()
                     for i in range(n)])
    assert np.any(want) and np.any(~want)
    assert np.array_equal(got, want)


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
    assert first <= touching[0] - 1 and why.startswith("left/forearm_link – left/wrist_2_link")
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
    assert "left/base_link – left/upper_arm_link" in p.reason and "self-contact" in p.reason


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


@pytest.mark.parametrize("robot", ["ur3", "ur5", "ur10"])
def test_every_maps_clear_cells_are_one_region(robot):
    """docs/robots.md: the maps assume two meshes never lie one wholly inside the other (coal's mesh
    distance is between surfaces); with the clear cells one connected region (on the torus), no
    clear configuration is cut off from the others by contact."""
    for m in contact_maps(Arm.load(robot)):
        clear = ~m.cells
        reach = np.zeros_like(clear)
        reach[tuple(np.argwhere(clear)[0])] = True
        while True:  # grow through clear neighbours (4-connected, periodic) until nothing changes
            grown = reach.copy()
            for axis in (0, 1):
                for shift in (1, -1):
                    grown |= np.roll(reach, shift, axis=axis)
            grown &= clear
            if np.array_equal(grown, reach):
                break
            reach = grown
        assert np.array_equal(reach, clear), f"{robot} {m.a} - {m.b}: the clear cells are not one region"
