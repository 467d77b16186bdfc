"""World + clearance: coal distances vs independent references, pair filtering, batches, errors."""

import dataclasses
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from geometry_reference import (
    box_box,
    box_surface_samples,
    capsule_box,
    capsule_capsule,
    capsule_halfspace,
    pose,
    segment_segment,
)

from dualpuma import puma
from dualpuma.collision import clearance_batch
from dualpuma.errors import JointError, ParameterError, PoseError
from dualpuma.model import Cell, Obstacle, World

LIM = puma.JOINT_LIMITS



@pytest.fixture(scope="module")
def cell():
    base = Cell.default()
    obstacles = (
        Obstacle(name="crate", shape="box", size=(0.3, 0.2, 0.25), T_world_obstacle=pose(pin.rpy.rpyToMatrix(0.1, 0.2, 0.3), (1.5, 0.35, 0.35))),
        Obstacle(name="ball", shape="sphere", size=(0.12,), T_world_obstacle=pose(p=(1.45, -0.45, 0.5))),
        Obstacle(name="post", shape="capsule", size=(0.05, 0.5), T_world_obstacle=pose(p=(1.5, -0.2, 0.25))),
    )
    return dataclasses.replace(base, obstacles=obstacles)


@pytest.fixture(scope="module")
def world(cell):
    return World(cell)


def arm_segments(world, side, q):
    """World capsule segments of one arm from its own single-arm Pinocchio model (not the World's)."""
    arm = world.arms[side]
    data = arm.model.createData()
    pin.forwardKinematics(arm.model, data, q)
    Tb = world.T_world_base[side]
    out = {}
    for c in arm.capsules:
        M = Tb @ data.oMi[c.joint].homogeneous @ c.placement
        h = 0.5 * c.length * M[:3, 2]
        out[f"{side}/{c.name}"] = (M[:3, 3] - h, M[:3, 3] + h, c.radius)
    return out


def reference_distance(world, cell, shapes, a, b):
    A, B = shapes[a], shapes[b]
    if B[0] == "halfspace":
        A, B = B, A
    if A[0] == "halfspace":
        if B[0] == "capsule":
            return capsule_halfspace(B[1], cell.floor_z)
        T, size = B[1]  # box: its lowest corner
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * (np.asarray(size) / 2)
        return float((corners @ T[:3, :3].T + T[:3, 3])[:, 2].min() - cell.floor_z)
    if A[0] == "box" and B[0] == "capsule":
        A, B = B, A
    if A[0] == "capsule" and B[0] == "capsule":
        return capsule_capsule(A[1], B[1])
    if A[0] == "capsule" and B[0] == "box":
        return capsule_box(A[1], *B[1])
    if A[0] == "box" and B[0] == "box":
        return box_box(*A[1], *B[1])
    return None


def all_shapes(world, cell, qL, qR, T_wo):
    shapes = {n: ("capsule", s) for n, s in {**arm_segments(world, "left", qL), **arm_segments(world, "right", qR)}.items()}
    shapes["floor"] = ("halfspace", None)
    Tbar = T_wo @ np.asarray(cell.bar.T_object_bar)
    size = np.atleast_1d(cell.bar.size)
    if cell.bar.shape == "box":
        shapes["bar"] = ("box", (Tbar, size))
    else:
        h = 0.5 * size[1] * Tbar[:3, 2]
        shapes["bar"] = ("capsule", (Tbar[:3, 3] - h, Tbar[:3, 3] + h, size[0]))
    for ob in cell.obstacles:
        T = np.asarray(ob.pose_at(0.0))
        sz = np.atleast_1d(ob.size)
        if ob.shape == "box":
            shapes[f"obstacle/{ob.name}"] = ("box", (T, sz))
        elif ob.shape == "sphere":
            shapes[f"obstacle/{ob.name}"] = ("capsule", (T[:3, 3], T[:3, 3], sz[0]))
        else:
            h = 0.5 * sz[1] * T[:3, 2]
            shapes[f"obstacle/{ob.name}"] = ("capsule", (T[:3, 3] - h, T[:3, 3] + h, sz[0]))
    return shapes


def test_clearance_matches_independent_reference(world, cell):
    rng = np.random.default_rng(2024)
    n_pen = n_checked = 0
    box_pen = 0
    for _ in range(300):
        qL = rng.uniform(LIM[:, 0], LIM[:, 1])
        qR = rng.uniform(LIM[:, 0], LIM[:, 1])
        T_wo = pose(pin.rpy.rpyToMatrix(*rng.uniform(-np.pi, np.pi, 3)), rng.uniform([1.0, -0.6, 0.0], [2.0, 0.6, 1.0]))
        c = world.clearance(qL, qR, T_wo, per_pair=True)
        shapes = all_shapes(world, cell, qL, qR, T_wo)
        ref = np.array([reference_distance(world, cell, shapes, a, b) for a, b in world.pair_names], dtype=float)
        assert not np.isnan(ref).any()
        # box-box (bar vs crate): the alternating-projection reference converges slowly near contact,
        # so it is held to 1e-6 only when the boxes are clearly apart or clearly overlapping
        bb = np.array([shapes[a][0] == "box" and shapes[b][0] == "box" for a, b in world.pair_names])
        strict = ~bb | (np.abs(ref) > 5e-3)
        np.testing.assert_allclose(c.pair_distances[strict], ref[strict], atol=1e-6)
        assert np.all(np.abs(c.pair_distances[~strict] - ref[~strict]) < 5e-3)
        k = int(np.argmin(ref))
        if strict[k]:
            assert c.distance == pytest.approx(ref[k], abs=1e-6)
        assert c.distance == pytest.approx(c.pair_distances.min(), abs=1e-12)
        n_pen += int((ref < 0).any())
        box_pen += int(any(r < 0 and "bar" in p for r, p in zip(ref, world.pair_names)))
        n_checked += len(ref)
    assert n_pen > 100 and box_pen > 50  # penetrating configurations were exercised


def test_box_reference_agrees_with_dense_sampling():
    rng = np.random.default_rng(5)
    for _ in range(50):
        T = pose(pin.rpy.rpyToMatrix(*rng.uniform(-3, 3, 3)), rng.uniform(-0.2, 0.2, 3))
        size = rng.uniform(0.1, 0.4, 3)
        a0, a1 = rng.uniform(-0.8, 0.8, 3), rng.uniform(-0.8, 0.8, 3)
        d = capsule_box((a0, a1, 0.0), T, size)
        pts = box_surface_samples(T, size, n=60)
        ts = np.linspace(0, 1, 400)
        seg = a0 + ts[:, None] * (a1 - a0)
        dmin = np.min(np.linalg.norm(seg[:, None, :] - pts[None, :, :], axis=-1))
        if d > 0:
            assert d <= dmin + 1e-9 and dmin - d < 0.02  # sampling over-estimates by at most the grid size


def test_segment_reference_brute_force():
    rng = np.random.default_rng(9)
    ts = np.linspace(0, 1, 801)
    for _ in range(100):
        p0, p1, q0, q1 = rng.uniform(-1, 1, (4, 3))
        P = p0 + ts[:, None] * (p1 - p0)
        Q = q0 + ts[:, None] * (q1 - q0)
        brute = np.min(np.linalg.norm(P[:, None] - Q[None], axis=-1))
        d = segment_segment(p0, p1, q0, q1)
        assert d <= brute + 1e-12 and brute - d < 5e-3


def test_pair_filtering(world):
    names = set(world.pair_names)
    assert ("left/gripper", "bar") not in names and ("right/gripper", "bar") not in names
    assert ("left/forearm", "bar") in names and ("right/upper_arm", "bar") in names
    assert ("left/pedestal", "floor") not in names and ("left/column", "floor") not in names
    assert ("left/forearm", "floor") in names and ("bar", "floor") in names
    assert ("left/forearm", "right/forearm") in names and ("left/gripper", "right/upper_arm") in names
    assert ("bar", "obstacle/crate") in names and ("left/pedestal", "obstacle/crate") in names
    assert len(names) == len(world.pair_names)


def test_default_start_is_clear_and_chain_closed():
    cell = Cell.default()
    w = World(cell)
    qL, qR = cell.left.q_home, cell.right.q_home
    c = w.clearance(qL, qR)
    assert c.distance >= cell.safety_margin
    TL, TR = w.hand_poses(qL, qR)
    np.testing.assert_allclose(TL, cell.T_world_object_start @ cell.grasp_left.T_object_hand, atol=1e-12)
    np.testing.assert_allclose(TR, cell.T_world_object_start @ cell.grasp_right.T_object_hand, atol=1e-12)
    # the implicit bar pose (carried by the left hand) equals the explicit one
    assert w.clearance(qL, qR, cell.T_world_object_start).distance == pytest.approx(c.distance, abs=1e-12)
    a, b = c.witness
    assert np.linalg.norm(a - b) == pytest.approx(abs(c.distance), abs=1e-9)


def test_batch_matches_single(world):
    rng = np.random.default_rng(1)
    QL = rng.uniform(LIM[:, 0], LIM[:, 1], (200, 6))
    QR = rng.uniform(LIM[:, 0], LIM[:, 1], (200, 6))
    d, idx = clearance_batch(world, QL, QR)
    for i in range(0, 200, 7):
        c = world.clearance(QL[i], QR[i])
        assert d[i] == pytest.approx(c.distance, abs=1e-9) and world.pair_names[idx[i]] == c.pair  # GJK warm starts


def test_moving_obstacle_is_checked_at_time(cell):
    agv = Obstacle(name="agv", shape="box", size=(0.4, 0.4, 0.3), T_world_obstacle=pose(p=(0.0, -0.25, 0.15)), velocity=(1.0, 0.0, 0.0), t_start=0.0, t_end=3.0)
    w = World(dataclasses.replace(cell, obstacles=(agv,)))
    qL, qR = cell.left.q_home, cell.right.q_home
    far = w.clearance(qL, qR, t=0.0)
    assert far.pair[1] != "obstacle/agv" or far.distance > 0.3
    near = [w.clearance(qL, qR, t=t) for t in np.linspace(0, 3, 31)]
    hit = [c for c in near if c.pair[1] == "obstacle/agv" or c.pair[0] == "obstacle/agv"]
    assert hit and min(c.distance for c in hit) < 0.0  # the AGV drives through the pedestal at some time
    d, _ = clearance_batch(w, np.tile(qL, (31, 1)), np.tile(qR, (31, 1)), t=np.linspace(0, 3, 31))
    np.testing.assert_allclose(d, [c.distance for c in near], atol=1e-12)


def test_bad_input_errors(world):
    q = np.zeros(6)
    with pytest.raises(JointError):
        world.clearance(np.zeros(5), q)
    with pytest.raises(JointError):
        world.clearance(q, np.full(6, np.nan))
    with pytest.raises(PoseError):
        world.clearance(q, q, T_world_object=np.ones((4, 4)))
    with pytest.raises(ParameterError):
        world.clearance(q, q, t=float("nan"))
    with pytest.raises(ParameterError):
        clearance_batch(world, np.zeros((3, 6)), np.zeros((2, 6)))


def test_excluded_wrist_bar_pairs_are_really_constant():
    """The wrist-bar pairs are left out as adjacent (the bar rides on the next link). Check with coal
    directly that, for the PUMA, their distance stays 50 mm (to 0.02 mm) for every configuration."""
    import coal

    cell = Cell.default()
    world = World(cell)
    assert not any("wrist" in a and b == "bar" for a, b in world.pair_names)
    gm = world.geom_model
    names = [g.name for g in world.geoms]
    bar = gm.geometryObjects[world.bar_id].geometry
    rng = np.random.default_rng(4)
    seen = []
    for side in ("left", "right"):
        w = names.index(f"{side}/wrist")
        wrist = gm.geometryObjects[w].geometry
        for _ in range(200):
            qL = cell.left.q_home + rng.normal(0, 0.4, 6)
            qR = cell.right.q_home + rng.normal(0, 0.4, 6)
            T = world.object_from_left(qL)
            if side == "right":  # put the right hand on its grasp of that object pose
                from dualpuma.kinematics import hands_from_object

                _, TR = hands_from_object(cell, T)
                sols, valid = puma.ik_all(TR)
                if not valid.any():
                    continue
                qR = sols[int(np.argmax(valid))]
            world.clearance(qL, qR, T)
            Mw, Mb = world.geom_data.oMg[w], world.geom_data.oMg[world.bar_id]
            res = coal.DistanceResult()
            d = coal.distance(wrist, coal.Transform3s(Mw.rotation, Mw.translation), bar,
                              coal.Transform3s(Mb.rotation, Mb.translation), coal.DistanceRequest(), res)
            seen.append(d)
    assert len(seen) > 250 and np.ptp(seen) < 2e-5 and min(seen) > 0.049  # 50 mm, constant to 0.02 mm


def test_one_world_queried_from_several_threads(cell, rng):
    """A World (and its cached kernel) may be shared by threads: each thread writes into its own
    Pinocchio/coal data, so concurrent queries give exactly the single-threaded answers."""
    import threading

    from dualpuma.collision import clearance_batch

    w = World(cell)
    QL = cell.left.q_home + rng.normal(0, 0.2, (300, 6))
    QR = cell.right.q_home + rng.normal(0, 0.2, (300, 6))
    ref = [w.min_distance(a, b) for a, b in zip(QL, QR)]
    ref_batch = clearance_batch(w, QL, QR, method="kernel")
    out: dict[int, list] = {}
    errors = []

    def work(k: int) -> None:
        try:
            got = []
            for _ in range(3):
                got.append([w.min_distance(a, b) for a, b in zip(QL, QR)])
                d, i = clearance_batch(w, QL, QR, method="kernel")
                got.append((d.tolist(), i.tolist()))
            out[k] = got
        except Exception as e:  # noqa: BLE001 - reported below
            errors.append(e)

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    for got in out.values():
        for single, batch in zip(got[::2], got[1::2]):
            assert single == ref
            assert batch == (ref_batch[0].tolist(), ref_batch[1].tolist())


@pytest.mark.parametrize("name", ["default", "ur5_pair", "mixed_puma_ur5"])
def test_every_pair_that_can_come_within_the_margin_is_checked(name):
    """An arm-arm capsule pair was left out when the capsules' reach spheres about their bases could
    not overlap, but in the UR cells such pairs were only 7-8 mm apart at worst: within the 20 mm
    margin, unchecked. Now a pair is left out only when it stays farther apart than the margin, and
    ``checked_margin`` says how far every left-out pair stays. Checked on random configurations of
    both arms with the reference segment distance: no left-out pair comes within it."""
    from dualpuma.model import example_cell

    cell = example_cell(name)
    world = World(cell)
    assert world.checked_margin >= cell.safety_margin
    checked = set(world.pair_names)
    rng = np.random.default_rng(4)
    lim = {s: world.arms[s].limits for s in ("left", "right")}
    base = {s: getattr(cell, s).T_world_base[:3, 3] for s in ("left", "right")}
    worst, reach = np.inf, {}
    for _ in range(400):
        q = {s: rng.uniform(lim[s][:, 0], lim[s][:, 1]) for s in ("left", "right")}
        seg = world.segments(q["left"], q["right"])
        for a, (p0, p1, r) in seg.items():  # how far each capsule reaches from its base (sampled: at most its reach)
            side = a.split("/")[0]
            reach[a] = max(reach.get(a, 0.0), max(np.linalg.norm(p0 - base[side]), np.linalg.norm(p1 - base[side])) + r)
        for a, ca in seg.items():
            for b, cb in seg.items():
                if a.startswith("left/") and b.startswith("right/") and (a, b) not in checked:
                    worst = min(worst, capsule_capsule(ca, cb))
    assert worst >= world.checked_margin
    # every left-out pair's bases are farther apart than both capsules' sampled reaches and the margin
    # (the old rule, reach spheres not overlapping, left out UR pairs whose gap was 7-8 mm)
    d_bases = float(np.linalg.norm(base["left"] - base["right"]))
    for a in (k for k in reach if k.startswith("left/")):
        for b in (k for k in reach if k.startswith("right/")):
            if (a, b) not in checked:
                assert d_bases - reach[a] - reach[b] > cell.safety_margin, (a, b)


def test_a_margin_beyond_what_the_world_checks_is_refused():
    """Pairs proven farther apart than ``checked_margin`` (self-collision pairs never within 50 mm,
    arm-arm pairs out of reach) are left out: a planner margin of 80 mm passed configurations where
    such a pair was 64 mm apart. Such a margin is refused where it is asked, and the message says
    how to get it (a cell with that margin checks them)."""
    from dualpuma import FallbackParams, StrivingParams, plan
    from dualpuma.planning import time_plan

    cell = Cell.default()
    world = World(cell)
    m = world.checked_margin + 0.01
    A = cell.T_world_object_start
    B = A.copy()
    B[:3, 3] += (0.0, 0.0, 0.05)
    p = plan(cell, A, B, StrivingParams(margin=m), world=world)
    assert p.status == "invalid_input" and "safety_margin of at least" in p.reason
    # the fallback's own margin too, before Striving runs (it raised out of plan() when Striving froze)
    fb = plan(cell, A, B, StrivingParams(fallback=True, fallback_params=FallbackParams(margin=m)), world=world)
    assert fb.status == "invalid_input" and "fallback_params.margin" in fb.reason
    with pytest.raises(ParameterError, match="checked for"):
        world.permitted(cell.left.q_home, cell.right.q_home, margin=m)
    ok = plan(cell, A, B, world=world)
    with pytest.raises(ParameterError, match="checked for"):
        time_plan(ok, world, margin=m)
    wide = World(dataclasses.replace(cell, safety_margin=m))
    assert wide.checked_margin >= m and len(wide.pair_names) > len(world.pair_names)


def test_the_ur_close_pairs_documented_are_the_ones_left_out_of_the_capsules_and_mapped():
    """docs/robots.md names the UR pairs that are always close but can touch, checked on their meshes
    by contact maps: they must be exactly the left-out pairs of one arm whose links are not
    neighbours and whose capsules' distance changes with the joints (the PUMA's forearm-gripper
    meets at its spherical wrist: its collision cylinders never touched in a reviewer's 3,000
    configurations), and the pairs the contact maps are derived for."""
    from dualpuma.model import example_cell
    from dualpuma.model.contact import close_pairs
    from dualpuma.model.pairs import verdicts

    world = World(example_cell("ur5_pair"))
    arm = world.arms["left"]
    joint = {c.name: c.joint for c in arm.capsules}
    close = {(v.a, v.b) for v in verdicts(arm) if v.kind == "adjacent" and abs(joint[v.a] - joint[v.b]) >= 2}
    assert close == {("base_link", "upper_arm_link"), ("forearm_link", "wrist_2_link"), ("wrist_1_link", "wrist_3_link")}
    assert {(a, b) for a, b, _ in close_pairs(arm)} == close
    for a, b in close:
        assert (f"left/{a}", f"left/{b}") not in world.pair_names
    text = " ".join((Path(__file__).resolve().parents[1] / "docs" / "robots.md").read_text().split())
    assert "forearm–wrist_2, base–upper arm and wrist_1–wrist_3" in text
