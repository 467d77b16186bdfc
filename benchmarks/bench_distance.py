"""Distance-query benchmarks (group "distance"). Ratios against two baselines in the same run:
a naive Python loop over coal.distance (one call per pair, transforms built in Python) and the
seed's 16x16 node search."""

import coal
import numpy as np
import pinocchio as pin
import pytest

from dualpuma import puma
from dualpuma.cell import Cell
from dualpuma.clearance import clearance_batch, node_search
from dualpuma.world import World

LIM = puma.JOINT_LIMITS
CELL = Cell.default()
WORLD = World(CELL)
rng = np.random.default_rng(0)
# configurations near the default start (the planner's regime), 10,000 of them
QL = CELL.left.q_home + rng.normal(0, 0.2, (10_000, 6))
QR = CELL.right.q_home + rng.normal(0, 0.2, (10_000, 6))


def _cycle(n):
    it = iter(range(10**12))
    return lambda: next(it) % n


@pytest.mark.benchmark(group="distance")
def test_coal_capsule_capsule_single_query(benchmark):
    a, b = coal.Capsule(0.05, 0.4), coal.Capsule(0.07, 0.3)
    Ta = coal.Transform3s(np.eye(3), np.array([0.0, 0.0, 0.0]))
    Tb = coal.Transform3s(pin.rpy.rpyToMatrix(0.3, 0.2, 0.1), np.array([0.3, 0.1, 0.05]))
    req, res = coal.DistanceRequest(), coal.DistanceResult()

    def run():
        res.clear()
        return coal.distance(a, Ta, b, Tb, req, res)

    d = benchmark(run)
    assert d > 0


@pytest.mark.benchmark(group="distance")
def test_full_dual_arm_clearance(benchmark):
    nxt = _cycle(len(QL))

    def run():
        i = nxt()
        return WORLD.clearance(QL[i], QR[i])

    c = benchmark(run)
    benchmark.extra_info["pairs"] = len(WORLD.pair_names)
    assert np.isfinite(c.distance)


@pytest.mark.benchmark(group="distance")
def test_min_distance_fast_path(benchmark):
    nxt = _cycle(len(QL))

    def run():
        i = nxt()
        return WORLD.min_distance(QL[i], QR[i])

    benchmark(run)


@pytest.mark.benchmark(group="distance")
def test_batch_10k_configurations(benchmark):
    d, idx = benchmark.pedantic(clearance_batch, args=(WORLD, QL, QR), rounds=5, iterations=1, warmup_rounds=1)
    benchmark.extra_info["configs_per_s"] = len(QL) / benchmark.stats.stats.median
    assert d.shape == (10_000,)


@pytest.mark.benchmark(group="distance")
def test_naive_python_loop_over_coal(benchmark):
    """Baseline: FK through Pinocchio, then one coal.distance call per pair from Python."""
    gm, gd, model, data = WORLD.geom_model, pin.GeometryData(WORLD.geom_model), WORLD.model, WORLD.model.createData()
    geoms = [g.geometry for g in gm.geometryObjects]
    req = coal.DistanceRequest()
    pairs = [(p.first, p.second) for p in gm.collisionPairs]
    nxt = _cycle(len(QL))

    def run():
        i = nxt()
        q = np.concatenate([QL[i], QR[i]])
        pin.forwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, gm, gd)
        tf = [coal.Transform3s(M.rotation, M.translation) for M in gd.oMg]
        best = np.inf
        for a, b in pairs:
            res = coal.DistanceResult()
            best = min(best, coal.distance(geoms[a], tf[a], geoms[b], tf[b], req, res))
        return best

    benchmark(run)
    # the naive loop and the World's C++ loop agree on the first configurations
    for i in range(20):
        q = np.concatenate([QL[i], QR[i]])
        pin.forwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, gm, gd)
        tf = [coal.Transform3s(M.rotation, M.translation) for M in gd.oMg]
        naive = min(coal.distance(geoms[a], tf[a], geoms[b], tf[b], req, coal.DistanceResult()) for a, b in pairs)
        assert abs(naive - WORLD.min_distance(QL[i], QR[i])[0]) < 2e-6


@pytest.mark.benchmark(group="distance")
def test_batch_10k_kernel(benchmark):
    d, idx = benchmark.pedantic(clearance_batch, args=(WORLD, QL, QR), kwargs={"method": "kernel"}, rounds=5,
                                iterations=1, warmup_rounds=1)
    benchmark.extra_info["configs_per_s"] = len(QL) / benchmark.stats.stats.median
    d_coal, _ = clearance_batch(WORLD, QL, QR)
    np.testing.assert_allclose(d, d_coal, atol=2e-6)



@pytest.mark.benchmark(group="distance")
def test_seed_node_search_16x16(benchmark):
    Tl, Tr = CELL.left.T_world_base, CELL.right.T_world_base
    nxt = _cycle(len(QL))

    def run():
        i = nxt()
        return node_search(Tl, QL[i], Tr, QR[i])

    benchmark(run)
