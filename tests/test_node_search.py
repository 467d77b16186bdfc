"""The seed's node search vs exact capsule clearance: misses and false alarms exist (seeded search)."""

import numpy as np

from dualpuma.collision import NODE_THRESHOLD, arm_arm_distance, node_positions, node_search
from dualpuma.model import Cell, World


def test_node_positions_follow_the_arm():
    c = Cell.default()
    n = node_positions(c.left.T_world_base, c.left.q_home)
    assert n.shape == (16, 3)
    np.testing.assert_allclose(n[1], c.left.T_world_base[:3, 3])  # shoulder
    hand = c.T_world_object_start @ c.grasp_left.T_object_hand
    np.testing.assert_allclose(n[5], hand[:3, 3], atol=1e-12)  # wrist centre


def test_nodes_miss_collisions_and_raise_false_alarms():
    c = Cell.default()
    w = World(c)
    rng = np.random.default_rng(0)
    QL = c.left.q_home + rng.normal(0, 0.6, (3000, 6))
    QR = c.right.q_home + rng.normal(0, 0.6, (3000, 6))
    coll, dn = node_search(c.left.T_world_base, QL, c.right.T_world_base, QR)
    miss = alarm = 0
    for i in range(len(QL)):
        d, _ = arm_arm_distance(w, QL[i], QR[i])
        miss += (not coll[i]) and d < 0  # nodes say safe, capsules penetrate
        alarm += coll[i] and d > 0.05  # nodes say collision, 5 cm of real clearance
    assert dn.min() >= 0 and NODE_THRESHOLD == 0.175
    assert alarm > 0, "expected node false alarms near joints"
    assert miss > 0, "expected collisions between nodes that the node search misses"


def test_node_elbow_matches_pinocchio_with_yawed_bases():
    """Node 4 is the elbow (end of the upper arm) for the yawed mounts of Cell.default()."""
    import pinocchio as pin

    from dualpuma.kinematics import Arm

    c = Cell.default()
    arm = Arm.puma560()
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = rng.uniform(arm.limits[:, 0], arm.limits[:, 1])
        n = node_positions(c.right.T_world_base, q)
        pin.forwardKinematics(arm.model, arm.data, q)
        T3 = c.right.T_world_base @ arm.data.oMi[3].homogeneous  # joint 3 (elbow) frame
        # the elbow joint lies d2 sideways of the node chain's 200 mm offset point, at the same height
        np.testing.assert_allclose(n[3][2], T3[2, 3], atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(n[3][:2] - T3[:2, 3]), 0.200 - 0.14909, atol=1e-12)


# Documented in docs/clearance.md (found by the seeded search above, rounded to 0.1 deg)
MISS = ([72.2, 12.7, -84.0, 47.1, 44.0, -65.2], [11.1, -0.2, 43.0, 11.7, -26.1, -136.5])
ALARM = ([19.5, -12.6, -33.3, -12.7, 15.8, -11.3], [-34.8, -20.2, -6.4, 27.5, -18.7, -78.0])


def test_documented_miss_and_false_alarm():
    c = Cell.default()
    w = World(c)
    for (qL, qR), want_nodes, check in (
        (MISS, False, lambda d, pair: d < -0.05 and pair == ("left/gripper", "right/pedestal")),
        (ALARM, True, lambda d, pair: d > 0.25),
    ):
        qL, qR = np.radians(qL), np.radians(qR)
        coll, dn = node_search(c.left.T_world_base, qL, c.right.T_world_base, qR)
        d, pair = arm_arm_distance(w, qL, qR)
        assert bool(coll) == want_nodes and check(d, pair), (coll, dn, d, pair)
        # the capsule answer is confirmed by the exact segment-segment reference
        from geometry_reference import segment_segment

        segs = w.segments(qL, qR)
        ref = min(
            segment_segment(*segs[a][:2], *segs[b][:2]) - segs[a][2] - segs[b][2]
            for a in segs for b in segs if a.startswith("left/") and b.startswith("right/") and (a, b) in w.pair_names
        )
        assert abs(ref - d) < 1e-9


def test_batches_of_both_arms_must_broadcast():
    """Found by the fuzz in CI: a batch of 2 left configurations against 0 right ones raised numpy's
    broadcast ValueError. Now a JointError naming both; batches that broadcast give one result
    per configuration, equal to the one-by-one search (independent loop)."""
    import pytest

    from dualpuma.errors import JointError

    c = Cell.default()
    with pytest.raises(JointError, match="broadcast"):
        node_search(c.left.T_world_base, np.zeros((2, 6)), c.right.T_world_base, np.zeros((0, 6)))
    rng = np.random.default_rng(4)
    qL = rng.uniform(-1, 1, (3, 6))
    hit, d = node_search(c.left.T_world_base, qL, c.right.T_world_base, c.right.q_home)
    for i in range(3):
        hi, di = node_search(c.left.T_world_base, qL[i], c.right.T_world_base, c.right.q_home)
        assert d[i] == di and hit[i] == hi
