"""The batched certificate (planning/certify.py: all chords level by level, each configuration's
pair distances once) against an independent brute force: every chord densely sampled (200 poses)
with Pinocchio/coal's ``computeDistances`` over the World's pairs on fresh data. A certified chord
has no sample below the margin; a chord with a sample clearly below it is refused, and so is every
chord after it (the certificate is a prefix). Chords are random walks near the obstacles of the
hard set (boxes, overhangs, slotted plates: box-box pairs answered by coal, capsule-box and
capsule-capsule pairs) and near a moving ball."""

from __future__ import annotations

import dataclasses
import itertools
import math
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from planner_checks import ball_cell

from dualpuma import Cell, World
from dualpuma.collision.batch import entry_distances
from dualpuma.lie import to_se3
from dualpuma.model import Obstacle
from dualpuma.planning.certify import certify_chords
from dualpuma.planning.reach import motion_bounds
from dualpuma.scenarios.hard import problems_from_json

MARGIN = 0.02
FIXTURE = Path(__file__).parents[1] / "benchmarks" / "fixtures" / "hard_set.json"


class Brute:
    """Every pair's distance at a configuration and time, on a fresh GeometryData (no kernel, no
    batching, no certificate code) with coal's warm start off, so that a reference distance does not
    depend on the order the references are computed in (with it on they move by ~1e-6)."""

    def __init__(self, world: World) -> None:
        self.w = world
        self.data = world.model.createData()
        self.gd = pin.GeometryData(world.geom_model)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            for req in self.gd.distanceRequests:
                req.enable_cached_gjk_guess = False

    def pairs(self, q, t: float) -> np.ndarray:
        w, gd = self.w, self.gd
        pin.updateGeometryPlacements(w.model, self.data, w.geom_model, gd, q)
        for gid, ob in w.moving:
            gd.oMg[gid] = to_se3(ob.pose_at(t))
        pin.computeDistances(w.geom_model, gd)
        return np.array([r.min_distance for r in gd.distanceResults])

    def chord_min(self, qa, qb, ta: float, tb: float, samples: int = 200) -> float:
        return min(self.pairs(qa + s * (qb - qa), ta + s * (tb - ta)).min() for s in np.linspace(0.0, 1.0, samples))


def _walks(world: World, brute: Brute, q0, rng, n_walks: int, n_chords: int, sigma: float):
    """Random walks of n_chords chords from near q0 whose configurations all keep the margin."""
    out = []
    while len(out) < n_walks:
        Q = np.cumsum(np.vstack([q0 + rng.normal(0, 2 * sigma, 12), rng.normal(0, sigma, (n_chords, 12))]), axis=0)
        d = np.array([brute.pairs(q, 0.0).min() for q in Q])
        if d.min() >= MARGIN:
            out.append((Q, d))
    return out


def _clear_ended_chords(brute: Brute, q0, rng, tries: int, spread: float):
    """Of ``tries`` random chords (a near q0, b within ``spread`` [rad] per joint of a), those whose
    ends keep the margin: (a, b, their clearances (2,))."""
    for _ in range(tries):
        a = q0 + rng.normal(0, 0.15, 12)
        b = a + rng.normal(0, spread, 12)
        de = np.array([brute.pairs(a, 0.0).min(), brute.pairs(b, 0.0).min()])
        if de.min() >= MARGIN:
            yield a, b, de


def _setups(hard_worlds):
    """Per hard-set world: (problem, World, its Brute, motion bounds (reach, v_max), start joints (12,))."""
    for p, world in hard_worlds:
        yield (p, world, Brute(world), *motion_bounds(world), np.concatenate(p.q_start))


@pytest.fixture(scope="module")
def hard_worlds():
    probs = problems_from_json(FIXTURE.read_text())
    picked = [p for p in probs if p.tag in ("boxes-0", "overhang-3", "slot-0", "slot-6")]
    assert len(picked) == 4
    return [(p, World(p.cell)) for p in picked]


def test_certified_chords_keep_the_margin_and_violating_ones_are_refused(hard_worlds):
    rng = np.random.default_rng(7)
    certified = certified_near = refused_real = 0
    for p, world, brute, reach, v, q0 in _setups(hard_worlds):
        for Q, d in _walks(world, brute, q0, rng, 12, 4, 0.06):
            times = np.arange(Q.shape[0], dtype=float)
            cert = certify_chords(world, Q, d, times, MARGIN, reach, v)
            dense = np.array([brute.chord_min(Q[c], Q[c + 1], 0.0, 0.0) for c in range(Q.shape[0] - 1)])
            assert 0 <= cert.n_ok <= len(dense)
            assert np.all(dense[: cert.n_ok] >= MARGIN - 1e-9), (p.tag, dense, cert)
            clearly = np.flatnonzero(dense < MARGIN - 1e-3)
            if clearly.size:  # the first violating chord ends the certified prefix
                assert cert.n_ok <= clearly[0], (p.tag, dense, cert)
            if cert.n_ok < len(dense):
                assert cert.reason and (np.isnan(cert.distance) or cert.distance < MARGIN)
                if not np.isnan(cert.distance):
                    a, b = world.pair_names[cert.pair]
                    assert a in cert.reason and b in cert.reason and f"chord {cert.n_ok} " in cert.reason
            else:
                assert cert.reason == "" and cert.pair == -1
            certified += cert.n_ok
            certified_near += int(np.sum(dense[: cert.n_ok] < MARGIN + 0.01))
            refused_real += int(clearly.size > 0)
    # not vacuous: chords certified close to the margin, and chords refused for a real violation
    assert certified >= 40 and certified_near >= 5 and refused_real >= 5, (certified, certified_near, refused_real)


def test_a_violating_chord_after_clear_ones_ends_the_prefix_with_its_pair(hard_worlds):
    """Chords 0 and 1 clear, chord 2 crosses an obstacle between two clear ends: n_ok = 2."""
    rng = np.random.default_rng(11)
    found = 0
    for p, world, brute, reach, v, q0 in _setups(hard_worlds):
        for a, b, _ in _clear_ended_chords(brute, q0, rng, 400, 0.25):
            if brute.chord_min(a, b, 0.0, 0.0) >= MARGIN - 2e-3:
                continue
            Q = np.vstack([a - 2e-4, a - 1e-4, a, b])  # two tiny clear chords first
            d = np.array([brute.pairs(q, 0.0).min() for q in Q])
            if d.min() < MARGIN:
                continue
            cert = certify_chords(world, Q, d, np.zeros(4), MARGIN, reach, v)
            assert cert.n_ok == 2, cert
            if not np.isnan(cert.distance):
                k = cert.pair
                assert cert.distance < MARGIN and " – ".join(world.pair_names[k]) in cert.reason
            found += 1
            break
    assert found >= 2


def test_depth_limit_refuses_what_it_cannot_prove(hard_worlds):
    """With no halvings allowed, a chord that needs them is refused as too close (NaN distance);
    with the default depth the same chord is certified, and the brute force agrees it is clear."""
    rng = np.random.default_rng(3)
    p, world = hard_worlds[0]
    brute = Brute(world)
    reach, v = motion_bounds(world)
    for Q, d in _walks(world, brute, np.concatenate(p.q_start), rng, 60, 1, 0.03):
        full = certify_chords(world, Q, d, np.zeros(2), MARGIN, reach, v)
        if full.n_ok == 1 and full.queries > 2:
            assert brute.chord_min(Q[0], Q[1], 0.0, 0.0) >= MARGIN - 1e-9
            none = certify_chords(world, Q, d, np.zeros(2), MARGIN, reach, v, max_depth=0)
            assert none.n_ok == 0 and np.isnan(none.distance) and "0 halvings" in none.reason
            return
    pytest.fail("no chord needing halvings was drawn")


def test_moving_ball_chords_against_brute_force():
    """The arms stand still or move a little while a ball crosses near the bar (times matter)."""
    c0, _ = ball_cell((0.0, -0.4, 0.06), 0.03, (0.0, 0.4, 0.0), 2.0)
    world = World(c0)
    brute = Brute(world)
    reach, v = motion_bounds(world)
    q0 = np.concatenate([c0.left.q_home, c0.right.q_home])
    rng = np.random.default_rng(1)
    certified = refused = 0
    for _ in range(40):
        Q = q0 + np.cumsum(rng.normal(0, 0.01, (5, 12)), axis=0)
        early = int(rng.integers(1, 5))  # before the ball reaches the bar, then after it passed the pedestal
        times = np.concatenate([np.sort(rng.uniform(0.0, 0.8, early)), np.sort(rng.uniform(1.95, 2.0, 5 - early))])
        d = np.array([brute.pairs(q, t).min() for q, t in zip(Q, times)])
        if d.min() < MARGIN:
            continue
        cert = certify_chords(world, Q, d, times, MARGIN, reach, v)
        dense = np.array([brute.chord_min(Q[c], Q[c + 1], times[c], times[c + 1]) for c in range(4)])
        assert np.all(dense[: cert.n_ok] >= MARGIN - 1e-9)
        clearly = np.flatnonzero(dense < MARGIN - 1e-3)
        if clearly.size:
            assert cert.n_ok <= clearly[0]
            refused += 1
        certified += cert.n_ok
    assert certified >= 10 and refused >= 3, (certified, refused)


def test_entry_distances_equal_coal_per_pair():
    """Chosen (configuration, pair) entries, grouped by configuration (repeated pairs, and
    configurations without entries), at their own times."""
    c0 = Cell.default()
    T = np.eye(4)
    T[:3, 3] = (0.3, 0.1, 0.5)
    ball = Obstacle("ball", "sphere", [0.05], T, velocity=(0.1, 0.0, 0.0), t_start=0.0, t_end=5.0)
    box = Obstacle("box", "box", [0.2, 0.1, 0.3], np.eye(4))
    world = World(dataclasses.replace(c0, obstacles=(ball, box)))
    brute = Brute(world)
    rng = np.random.default_rng(2)
    q0 = np.concatenate([c0.left.q_home, c0.right.q_home])
    Q = q0 + rng.normal(0, 0.2, (7, 12))
    times = rng.uniform(0, 5, 7)
    P = len(world.pair_names)
    config = rng.integers(0, 7, 300)
    pairs = rng.integers(0, P, 300)
    order = np.argsort(config, kind="stable")
    config, pairs = config[order], pairs[order].tolist()
    cuts = np.searchsorted(config, np.arange(8)).tolist()
    got = entry_distances(world, Q, times, cuts, pairs)
    ref = np.array([brute.pairs(Q[i], times[i])[k] for i, k in zip(config, pairs)])
    np.testing.assert_allclose(got, ref, atol=1e-9, rtol=0)
    assert entry_distances(world, Q, times, [0] * 8, []) == []  # every configuration without entries
    some = [0, 0, 3, 3, 3, 5, 5, 5]  # entries only at configurations 1 and 4
    np.testing.assert_allclose(entry_distances(world, Q, times, some, pairs[:5]),
                               [brute.pairs(Q[1], times[1])[k] for k in pairs[:3]]
                               + [brute.pairs(Q[4], times[4])[k] for k in pairs[3:5]], atol=1e-9, rtol=0)


def test_margin_just_above_a_chords_dense_minimum_refuses_it(hard_worlds):
    """For chords whose middle dips below their ends, a margin 0.5 mm above the dense minimum must
    refuse the chord (a sample is below it), whatever the certificate's bounds (a bound loose by
    more than that fails here); 2 mm below it the chord keeps the margin, and the certificate
    proves most such chords (it is not refusing all)."""
    rng = np.random.default_rng(19)
    tested = proved = 0
    for p, world, brute, reach, v, q0 in _setups(hard_worlds):
        for Q, d in _walks(world, brute, q0, rng, 40, 1, 0.12):
            m = brute.chord_min(Q[0], Q[1], 0.0, 0.0)
            if not 0.0 <= m < d.min() - 0.003:
                continue
            tested += 1
            above = certify_chords(world, Q, d, np.zeros(2), m + 5e-4, reach, v)
            assert above.n_ok == 0, (p.tag, m, d, above)
            below = certify_chords(world, Q, d, np.zeros(2), m - 0.002, reach, v)
            proved += below.n_ok
    assert tested >= 10 and proved >= 0.8 * tested, (tested, proved)


def test_whole_world_reach_bounds_every_pair_along_chords():
    """The whole-World bound (motion_bounds: R_j from geometry_reach, joint axes' off-axis offsets)
    bounds every pair's change along random chords, sampled densely (consecutive samples), and so
    does each pair's own bound (pair_weights: a joint that turns a round geometry about its own
    axis, a column, a shoulder or a wrist on its own joint, counts nothing), whose weights are at most
    the whole-World reach."""
    from dualpuma.planning.reach import pair_weights
    from dualpuma.scenarios import random_problem

    for seed in (4, 11):
        prob = random_problem(seed, max_obstacles=4)
        world = World(prob.cell)
        brute = Brute(world)
        reach, _ = motion_bounds(world)
        W, _ = pair_weights(world)
        assert np.all(W <= reach + 1e-12)
        rng = np.random.default_rng(seed)
        q0 = np.concatenate([prob.cell.left.q_home, prob.cell.right.q_home])
        worst = tight = 0.0
        for _ in range(40):
            a = q0 + rng.normal(0, 0.4, 12)
            b = a + rng.normal(0, 0.15, 12)
            S = np.linspace(0.0, 1.0, 21)
            D = np.array([brute.pairs(a + s * (b - a), 0.0) for s in S])  # (21, P)
            step = np.abs(b - a) @ reach / 20  # the bound between consecutive samples
            change = np.abs(np.diff(D, axis=0)).max()
            assert change <= step + 1e-9, (seed, change, step)
            worst = max(worst, change / step)
            own, per_pair = np.abs(b - a) @ W.T / 20, np.abs(np.diff(D, axis=0)).max(axis=0)
            assert np.all(per_pair <= own + 1e-9), (seed, world.pair_names[int(np.argmax(per_pair - own))])
            tight = max(tight, float((per_pair / np.maximum(own, 1e-12))[own > 0].max()))
        assert worst > 0.2 and tight > 0.5  # the bounds are not vacuous



def test_between_clearance_is_a_lower_bound_and_exact_below_the_margin(hard_worlds, monkeypatch):
    """Poses between step configurations (joint-linear plus a perturbation, as IK sub-poses lie near
    the chord): the returned clearance never exceeds the brute force's; it is below the margin exactly
    where the brute force is (to coal's tolerance), and there it is the brute force's distance with
    its pair; poses whose neighbours are clear enough are proved by the bound without any query."""
    from dualpuma.planning import certify as certify_mod

    asked = []
    real = certify_mod.below_margin
    monkeypatch.setattr(certify_mod, "below_margin", lambda w, Q, t, m: asked.append(Q.shape[0]) or real(w, Q, t, m))
    rng = np.random.default_rng(5)
    below = proved = 0
    for p, world, brute, reach, v, q0 in _setups(hard_worlds):
        for sigma, walks in ((0.003, 3), (0.08, 10)):
            for Qe, de in _walks(world, brute, q0, rng, walks, 4, sigma):
                k = np.repeat(np.arange(Qe.shape[0] - 1), 4)
                s = np.tile([0.2, 0.4, 0.6, 0.8], Qe.shape[0] - 1)
                Q = Qe[k] + s[:, None] * (Qe[k + 1] - Qe[k]) + rng.normal(0, sigma / 6, (k.size, 12))
                asked.clear()
                d, pair = certify_mod.between_clearance(world, Qe, de, np.zeros(Qe.shape[0]), Q, np.zeros(k.size), k,
                                                        MARGIN, reach, v)
                ref = np.array([brute.pairs(q, 0.0) for q in Q])
                dmin = ref.min(axis=1)
                assert np.all(d <= dmin + 1e-6), (p.tag, d - dmin)
                differ = (d < MARGIN) != (dmin < MARGIN)
                assert np.all(np.abs(dmin[differ] - MARGIN) <= 1e-6), (p.tag, dmin[differ])
                low = d < MARGIN
                assert np.all(pair[low] >= 0) and np.all(pair[~low] == -1)
                np.testing.assert_allclose(d[low], dmin[low], atol=1e-6)
                np.testing.assert_allclose(ref[low, pair[low]], dmin[low], atol=1e-6)
                below += int(low.sum())
                proved += k.size - sum(asked)
    assert below >= 5 and proved >= 20, (below, proved)


def test_between_clearance_finds_a_pose_inside_between_clear_neighbours(hard_worlds):
    """Chords with both ends clear and points inside the margin between them (the case a bound
    that proved too much would miss): every such point is reported below the margin."""
    from dualpuma.planning.certify import between_clearance

    rng = np.random.default_rng(11)
    found = 0
    for p, world, brute, reach, v, q0 in _setups(hard_worlds):
        for a, b, de in _clear_ended_chords(brute, q0, rng, 300, 0.12):
            s = np.linspace(0.1, 0.9, 9)
            Q = a + s[:, None] * (b - a)
            dmin = np.array([brute.pairs(q, 0.0).min() for q in Q])
            if dmin.min() >= MARGIN - 1e-3:
                continue
            d, _ = between_clearance(world, np.vstack([a, b]), de, np.zeros(2), Q, np.zeros(9), np.zeros(9, dtype=np.int64),
                                     MARGIN, reach, v)
            assert np.all(d[dmin < MARGIN - 1e-6] < MARGIN), (p.tag, d, dmin)
            found += 1
    assert found >= 10, found


def test_the_bars_path_is_certified_against_brute_force(hard_worlds):
    """closed_chain: straight bar paths from each hard problem's start towards its goal (and
    towards goals moved by up to 60 mm, and 0.15 m-ish in random directions), both arms tracked with Pinocchio alone (the independent
    reference's tracking) at 20 poses per 30 mm; rows every 30 mm where they keep the margin, so
    that a motion between consecutive rows may cross what lies inside. The certified motions keep
    the margin at every tracked pose between their rows (every pair, brute force), the first one
    that clearly does not ends the certified prefix, and a refusal's distance is below the margin."""
    from motion_reference import MotionReference

    rng = np.random.default_rng(5)
    certified = certified_near = refused_real = 0
    for p, world, brute, reach, v, q0 in _setups(hard_worlds):
        ref = MotionReference(p.cell)
        for k in range(10):
            goal = p.goal.copy() if k < 3 else p.start.copy()
            goal[:3, 3] += (rng.uniform(-0.06, 0.06, 3) if k else 0.0) if k < 3 else rng.normal(0, 0.15, 3)
            n = max(2, math.ceil(float(np.linalg.norm(goal[:3, 3] - p.start[:3, 3])) / 0.03))
            fine = np.vstack([q0, ref.bar_path(p.start, goal, q0, 20 * n)])
            df = np.array([brute.pairs(q, 0.0).min() for q in fine])
            rows = np.array([i for i in range(0, 20 * n + 1, 20) if df[i] >= MARGIN])
            if rows.size < 2 or rows[0] != 0:
                continue
            Q, d = fine[rows], df[rows]
            cert = certify_chords(world, Q, d, np.zeros(rows.size), MARGIN, reach, v, closed_chain=True)
            dense = np.array([df[a : b + 1].min() for a, b in itertools.pairwise(rows)])
            assert np.all(dense[: cert.n_ok] >= MARGIN - 1e-9), (p.tag, dense, cert)
            clearly = np.flatnonzero(dense < MARGIN - 1e-3)
            if clearly.size:
                assert cert.n_ok <= clearly[0], (p.tag, dense, cert)
            if cert.n_ok < rows.size - 1:
                assert cert.reason and (np.isnan(cert.distance) or cert.distance < MARGIN)
            certified += cert.n_ok
            certified_near += int(np.sum(dense[: cert.n_ok] < MARGIN + 0.01))
            refused_real += int(clearly.size > 0)
    assert certified >= 20 and certified_near >= 3 and refused_real >= 2, (certified, certified_near, refused_real)


def _surface(shape: str, size, M, n: int = 4000, seed: int = 0) -> np.ndarray:
    """Points (n, 3) of a geometry's surface placed at M (4, 4), sampled (an independent
    description of its shape: box faces and corners, or a capsule's cylinder and caps, or a sphere)."""
    rng = np.random.default_rng(seed)
    size = np.asarray(size, float)
    if shape == "box":
        u = rng.uniform(-0.5, 0.5, (n, 3)) * size
        face = rng.integers(0, 3, n)
        u[np.arange(n), face] = np.sign(rng.uniform(-1, 1, n)) * 0.5 * size[face]
        u[:8] = np.array(list(itertools.product((-0.5, 0.5), repeat=3))) * size  # the corners too
    else:
        r, half = (size[0], 0.5 * size[1]) if shape == "capsule" else (size[0], 0.0)
        v = rng.normal(size=(n, 3))
        v /= np.linalg.norm(v, axis=1)[:, None]
        u = r * v
        u[:, 2] += np.where(v[:, 2] >= 0, half, -half)  # the caps' centres at +-half along z
        u[: n // 2, 2] = rng.uniform(-half, half, n // 2)  # and the cylinder between them
        u[: n // 2, :2] = r * v[: n // 2, :2] / np.linalg.norm(v[: n // 2, :2], axis=1)[:, None]
    M = np.asarray(M, float)
    return u @ M[:3, :3].T + M[:3, 3]


def _bar_surface(bar, n: int = 4000, seed: int = 0) -> np.ndarray:
    """Points (n, 3) of the bar's surface in the object frame."""
    return _surface(bar.shape, bar.size, bar.T_object_bar, n, seed)


def _bar_cells():
    """The hard set's box bar, and the same cell with a capsule and a sphere bar off the object's origin."""
    from dualpuma.model import Bar

    base = problems_from_json(FIXTURE.read_text())[0].cell
    T = np.eye(4)
    T[:3, :3] = pin.rpy.rpyToMatrix(0.3, -0.2, 0.5)
    T[:3, 3] = (0.04, -0.03, 0.02)
    return [base, dataclasses.replace(base, bar=Bar("capsule", np.array([0.03, 0.6]), T)),
            dataclasses.replace(base, bar=Bar("sphere", np.array([0.05]), T))]


_RIDES = {"bar": "left", "left/gripper": "left", "right/gripper": "right"}  # what the hands hold rigidly
_LINK_JOINT = {"column": 1, "shoulder": 2, "upper_arm": 2, "elbow": 3, "forearm": 3, "wrist": 5}  # the PUMA's links
_SPINS = {"column", "shoulder", "wrist"}  # capsules along their own joint's axis


def _rigid_radius(world, name: str) -> float:
    """The radius reach.rigid_pairs gives the geometry ``name`` (the same in each of its pairs)."""
    from dualpuma.planning.reach import JOINTS, rigid_pairs

    rig = rigid_pairs(world)
    got = {float(rig.rho[k]) for k, pair in enumerate(world.pair_names) if name in pair and rig.kind[k] != JOINTS
           and not set(pair) <= set(_RIDES)}
    assert len(got) == 1, (name, got)
    return got.pop()


def test_the_radius_and_kind_of_each_pair_riding_with_the_bar():
    """reach.rigid_pairs: the bar and both grippers (the PUMA's last links) ride with the object
    frame. Each one's radius bounds every sampled point of its surface about the object frame's
    origin and is within 2 mm of the farthest: the bar's from the cell, the grippers' placed by
    Pinocchio at the start's joints and expressed in the start's object frame. The kinds by name:
    against an obstacle, the floor or a pedestal, against the other hand, against an arm's link
    (with that link's own joint weights: its arm's joints up to its own, but not its own where that
    turns it about its axis), and the rest."""
    from dualpuma.planning.reach import BOTH, FIXED, JOINTS, LINK, pair_weights, rigid_pairs

    p0 = problems_from_json(FIXTURE.read_text())[0]
    for cell in _bar_cells():
        world = World(cell)
        far = float(np.linalg.norm(_bar_surface(cell.bar), axis=1).max())
        rho = _rigid_radius(world, "bar")
        assert far - 1e-12 <= rho <= far + 2e-3, (cell.bar.shape, rho, far)
        data, gd = world.model.createData(), pin.GeometryData(world.geom_model)
        pin.updateGeometryPlacements(world.model, data, world.geom_model, gd, np.concatenate(p0.q_start))
        to_object = np.linalg.inv(p0.start)
        for s in ("left", "right"):
            info = world.geometry(f"{s}/gripper")
            M = to_object @ gd.oMg[world.geom_model.getGeometryId(f"{s}/gripper")].homogeneous
            far = float(np.linalg.norm(_surface(info.shape, info.size, M), axis=1).max())
            rho = _rigid_radius(world, f"{s}/gripper")
            assert far - 1e-9 <= rho <= far + 2e-3, (s, rho, far)
        rig, (W, _) = rigid_pairs(world), pair_weights(world)
        for k, (a, b) in enumerate(world.pair_names):
            if a in _RIDES and b in _RIDES:
                want = BOTH
            elif a in _RIDES or b in _RIDES:
                g, h = (a, b) if a in _RIDES else (b, a)
                if h == "floor" or h.startswith("obstacle/") or h.endswith("/pedestal"):
                    want = FIXED
                else:
                    want = LINK
            else:
                want = JOINTS
            assert rig.kind[k] == want, (a, b, rig.kind[k], want)
            if want == LINK:  # the link's own motion: its arm's joints up to its own, but one turning it about its axis
                side, link = h.split("/")
                cols = [6 * (side == "right") + j - 1 for j in range(1, _LINK_JOINT[link] + 1)
                        if not (j == _LINK_JOINT[link] and link in _SPINS)]
                assert np.flatnonzero(rig.W_other[k]).tolist() == cols, (a, b, rig.W_other[k])
                if _RIDES[g] != side:  # a link of the other arm: its share of the pair's joint bound
                    assert np.array_equal(rig.W_other[k][cols], W[k][cols])
            else:
                assert not rig.W_other[k].any()
        assert {FIXED, BOTH, LINK, JOINTS} <= set(rig.kind.tolist())


def test_no_point_of_the_bar_moves_further_than_its_geodesic_bound():
    """Along random SE(3) geodesics (lie.slerp: what the arms follow between a plan's rows), every
    sampled point of the bar moves between two fractions by at most (s2 - s1)(|dp| + theta rho),
    theta from Pinocchio's log; the bound is attained within 10 % by some motion (it is not loose)."""
    from dualpuma.lie import slerp

    rng = np.random.default_rng(11)
    tight = 1.0
    for cell in _bar_cells():
        rho = _rigid_radius(World(cell), "bar")
        pts = _bar_surface(cell.bar, 600)
        for _ in range(40):
            A, B = np.eye(4), np.eye(4)
            A[:3, :3], B[:3, :3] = (pin.exp3(rng.normal(size=3) * s) for s in (1.0, rng.uniform(0.0, 1.2)))
            A[:3, 3], B[:3, 3] = rng.normal(0, 0.5, 3), rng.normal(0, 0.5, 3) * rng.uniform(0.0, 0.3)
            th = float(np.linalg.norm(pin.log3(A[:3, :3].T @ B[:3, :3])))
            s1, s2 = np.sort(rng.uniform(0.0, 1.0, 2))
            P1, P2 = slerp(A, B, np.array([s1, s2]))
            moved = np.linalg.norm(pts @ (P2[:3, :3] - P1[:3, :3]).T + (P2[:3, 3] - P1[:3, 3]), axis=1).max()
            bound = (s2 - s1) * (float(np.linalg.norm(B[:3, 3] - A[:3, 3])) + th * rho)
            assert moved <= bound + 1e-12, (cell.bar.shape, moved, bound)
        # turning 0.01 rad about an axis through the origin perpendicular to the farthest point
        far = pts[np.argmax(np.linalg.norm(pts, axis=1))]
        a = rng.normal(size=3)
        a -= far * (far @ a) / (far @ far)
        B = np.eye(4)
        B[:3, :3] = pin.exp3(0.01 * a / np.linalg.norm(a))
        P = slerp(np.eye(4), B, np.array([0.0, 1.0]))
        moved = np.linalg.norm(pts @ (P[1, :3, :3] - P[0, :3, :3]).T, axis=1).max()
        tight = min(tight, moved / (0.01 * rho))
    assert tight > 0.9, tight


def test_the_bars_motion_certifies_what_the_joints_cannot(hard_worlds):
    """The bar passing a wall 35 mm beyond its end, sideways in 20 mm rows (both arms tracked by the
    independent reference): along the bar's path the certificate needs no midpoint (the object
    frame's motion bounds the bar - wall pair: 0.5 (35 + 35 - 20) mm keeps 20 mm), where the joint
    bound of the same rows must halve (the chord mode queries midpoints); every tracked pose keeps
    the margin (brute force)."""
    p = hard_worlds[0][0]
    TB = p.start @ p.cell.bar.T_object_bar
    x, half = TB[:3, 0], 0.5 * float(p.cell.bar.size[0])  # the box bar's long axis
    T = TB.copy()
    T[:3, 3] = TB[:3, 3] + x * (half + 0.035 + 0.05)
    cell = dataclasses.replace(p.cell, obstacles=(Obstacle("wall", "box", np.array([0.1, 0.4, 0.4]), T),))
    side = np.cross(x, [0.0, 0.0, 1.0])
    _past_a_wall(cell, p, 0.1 * side / np.linalg.norm(side))


def _past_a_wall(cell, p, move, nearest=None) -> None:
    """The bar moved by ``move`` (3,) [m] from the problem's start in 20 mm rows past a wall 35 mm
    from the nearest geometry (``nearest``: that pair's names), both arms tracked by the independent
    reference, every tracked pose brute-force clear: certified along the bar's path with the chords'
    ends alone, where the joint bound of the same rows must halve (the chord mode queries midpoints)."""
    from motion_reference import MotionReference

    world, ref = World(cell), MotionReference(cell)
    brute, (reach, v) = Brute(world), motion_bounds(world)
    q0 = np.concatenate(p.q_start)
    goal = p.start.copy()
    goal[:3, 3] += move
    fine = np.vstack([q0, ref.bar_path(p.start, goal, q0, 100)])
    D = np.array([brute.pairs(q, 0.0) for q in fine])
    df = D.min(axis=1)
    assert df.min() >= MARGIN and abs(df[0] - 0.035) < 1e-6
    if nearest is not None:
        assert world.pair_names[int(D[0].argmin())] == nearest
    rows = np.arange(0, 101, 20)
    Q, d, t = fine[rows], df[rows], np.zeros(rows.size)
    held = certify_chords(world, Q, d, t, MARGIN, reach, v, closed_chain=True)
    chord = certify_chords(world, Q, d, t, MARGIN, reach, v)
    assert held.n_ok == chord.n_ok == rows.size - 1, (held, chord)
    assert held.queries <= rows.size < chord.queries, (held, chord)  # the chords' ends at most, no midpoint


def _hand_error(ref, Q, poses) -> float:
    """How far the tracked joints Q (K, 12) hold the hands from their grasps on the bar at ``poses``
    (K, 4, 4) [m or rad] (Pinocchio FK of each arm's own model)."""
    worst = 0.0
    for k, s in enumerate(("left", "right")):
        arm, grasp = ref.arms[s], np.asarray(getattr(ref.cell, f"grasp_{s}").T_object_hand, float)
        model, fid = arm.model, arm.frame_id(None)
        data = model.createData()
        for q, T in zip(Q[:, 6 * k : 6 * k + 6], poses):
            pin.framesForwardKinematics(model, data, q)
            want = pin.SE3(np.linalg.inv(ref.base[s]) @ T @ grasp)
            worst = max(worst, float(np.abs(pin.log6(data.oMf[fid].actInv(want)).vector).max()))
    return worst


def test_along_the_bars_path_no_pair_riding_with_it_changes_faster_than_its_bound(hard_worlds):
    """Along the bar's path, both arms tracked by the independent reference (Pinocchio alone), every
    pair's distance (brute force, per pair) changes between consecutive poses (1/n of the path) by
    no more than reach.rigid_pairs allows: a geometry riding with the bar against one no joint moves
    by (|dp| + theta rho) / n whatever the joints do, the two hands' pair not at all, a geometry
    riding with the bar against an arm's link by that plus the link's own joint bound. For most
    steps against fixed geometry the rigid bound is the smaller one than the joints' (that is what
    makes it useful)."""
    from motion_reference import MotionReference, geodesic_poses

    from dualpuma.planning.reach import BOTH, FIXED, LINK, pair_weights, rigid_pairs

    rng = np.random.default_rng(5)
    n, paths, tighter, steps = 40, 0, 0, 0
    for p, world in hard_worlds:
        ref, brute = MotionReference(p.cell), Brute(world)
        rig, (W, _) = rigid_pairs(world), pair_weights(world)
        fixed, both, other = rig.kind == FIXED, rig.kind == BOTH, rig.kind == LINK
        q0 = np.concatenate(p.q_start)
        for _ in range(3):
            goal = p.start.copy()
            goal[:3, :3] = goal[:3, :3] @ pin.exp3(rng.normal(0, 0.2, 3))
            goal[:3, 3] += rng.normal(0, 0.05, 3)
            Q = np.vstack([q0, ref.bar_path(p.start, goal, q0, n)])
            if _hand_error(ref, Q, geodesic_poses(p.start, goal, np.arange(n + 1) / n)) > 1e-9:
                continue  # out of the arms' reach: not a path of the bar
            paths += 1
            theta = float(np.linalg.norm(pin.log3(p.start[:3, :3].T @ goal[:3, :3])))
            rigid = (float(np.linalg.norm(goal[:3, 3] - p.start[:3, 3])) + theta * rig.rho) / n  # (P,)
            D = np.array([brute.pairs(q, 0.0) for q in Q])
            change, dq = np.abs(np.diff(D, axis=0)), np.abs(np.diff(Q, axis=0))
            assert np.all(change[:, fixed] <= rigid[fixed] + 1e-7), (p.tag, (change[:, fixed] - rigid[fixed]).max())
            assert np.all(change[:, both] <= 1e-7), (p.tag, change[:, both].max())
            allowed = rigid[other] + dq @ rig.W_other[other].T
            assert np.all(change[:, other] <= allowed + 1e-7), (p.tag, (change[:, other] - allowed).max())
            tighter += int(np.sum(rigid[fixed] < dq @ W[fixed].T))
            steps += n * int(fixed.sum())
    assert paths >= 8 and tighter >= 0.75 * steps, (paths, tighter, steps)


def test_the_grippers_motion_certifies_what_the_joints_cannot(hard_worlds):
    """A wall 35 mm beside the right gripper (10 mm further from the bar), the bar moved along it in
    20 mm rows (both arms tracked by the independent reference; every tracked pose brute-force
    clear, the gripper - wall pair the nearest): along the bar's path the certificate needs no
    midpoint, since the gripper rides with the object frame (0.5 (35 + 35 - 20) mm keeps 20 mm),
    where the joint bound of the same rows must halve (the chord mode queries midpoints)."""
    p = hard_worlds[0][0]
    assert p.tag == "boxes-0"
    a, b, r = World(p.cell).segments(*p.q_start)["right/gripper"]
    assert abs(a[0] - b[0]) < 1e-9 and abs(a[1] - b[1]) < 1e-9  # the gripper points straight down here
    T = np.eye(4)
    T[:3, 3] = (a[0] + 0.05, a[1] - r - 0.035 - 0.05, 0.19)
    cell = dataclasses.replace(p.cell, obstacles=(Obstacle("wall", "box", np.array([0.45, 0.1, 0.12]), T),))
    _past_a_wall(cell, p, np.array([0.1, 0.0, 0.0]), ("right/gripper", "obstacle/wall"))
