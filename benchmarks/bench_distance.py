"""Distance-query benchmarks (group "distance"). Ratios against baselines in the same run: a naive
Python loop over coal.distance (one call per pair, transforms built in Python), the loop of one
Pinocchio/coal C++ call per configuration, and the seed's 16x16 node search.

The batch figures (``extra_info["configs_per_s"]``) are configurations per second on one core:
``test_batch_10k_kernel`` (the vectorised kernel, ``clearance_batch``'s default for batches) and
``test_batch_10k_configurations`` (the per-configuration C++ loop, ``method="coal"``). The kernel's
results are asserted equal to the naive loop's."""

import coal
import numpy as np
import pinocchio as pin
import pytest

from dualpuma import puma
from dualpuma.collision import batch_kernel, clearance_batch, node_search
from dualpuma.model import Cell, World

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
    """Baseline: one Pinocchio/coal C++ call (FK + placements + all pairs) per configuration."""
    d, _ = benchmark.pedantic(
        clearance_batch, args=(WORLD, QL, QR), kwargs={"method": "coal"}, rounds=5, iterations=1, warmup_rounds=1
    )
    benchmark.extra_info["configs_per_s"] = len(QL) / benchmark.stats.stats.median
    assert d.shape == (10_000,)


def _naive_pair_distances() -> np.ndarray:
    """Every pair's distance at every configuration by the naive loop (coal.distance per pair)."""
    gm, gd, model, data = WORLD.geom_model, pin.GeometryData(WORLD.geom_model), WORLD.model, WORLD.model.createData()
    geoms = [g.geometry for g in gm.geometryObjects]
    pairs = [(p.first, p.second) for p in gm.collisionPairs]
    req = coal.DistanceRequest()
    out = np.empty((len(QL), len(pairs)))
    for i in range(len(QL)):
        pin.forwardKinematics(model, data, np.concatenate([QL[i], QR[i]]))
        pin.updateGeometryPlacements(model, data, gm, gd)
        tf = [coal.Transform3s(M.rotation, M.translation) for M in gd.oMg]
        for k, (a, b) in enumerate(pairs):
            out[i, k] = coal.distance(geoms[a], tf[a], geoms[b], tf[b], req, coal.DistanceResult())
    return out


def _assert_equals_naive(d: np.ndarray, idx: np.ndarray) -> None:
    """The kernel's minimum equals the naive loop's to 1e-9 m, and its pair holds that minimum."""
    naive = _naive_pair_distances()
    best = naive.min(axis=1)
    assert np.abs(d - best[: len(d)]).max() < 1e-9
    assert np.abs(naive[np.arange(len(d)), idx] - best[: len(d)]).max() < 1e-9


@pytest.mark.benchmark(group="distance")
def test_batch_10k_kernel(benchmark):
    """The vectorised exact kernel on the same 10,000 configurations."""
    kernel = batch_kernel(WORLD)  # built once per World (about 1 ms), as clearance_batch does
    Q = np.hstack([QL, QR])
    d, idx = benchmark.pedantic(kernel, args=(Q,), rounds=7, iterations=1, warmup_rounds=1)
    benchmark.extra_info["configs_per_s"] = len(QL) / benchmark.stats.stats.median
    _assert_equals_naive(d, idx)
    d2, idx2 = clearance_batch(WORLD, QL, QR)  # the public entry point takes the kernel
    np.testing.assert_array_equal(d2, d)
    np.testing.assert_array_equal(idx2, idx)


@pytest.mark.benchmark(group="distance")
def test_batch_1k_chunk_kernel(benchmark):
    """The kernel through clearance_batch on a 1,000-configuration chunk (validation included)."""
    d, idx = benchmark.pedantic(clearance_batch, args=(WORLD, QL[:1000], QR[:1000]), rounds=20, iterations=1, warmup_rounds=1)
    benchmark.extra_info["configs_per_s"] = 1000 / benchmark.stats.stats.median
    d_all, idx_all = clearance_batch(WORLD, QL, QR)
    np.testing.assert_array_equal(d, d_all[:1000])
    np.testing.assert_array_equal(idx, idx_all[:1000])


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
def test_seed_node_search_16x16(benchmark):
    Tl, Tr = CELL.left.T_world_base, CELL.right.T_world_base
    nxt = _cycle(len(QL))

    def run():
        i = nxt()
        return node_search(Tl, QL[i], Tr, QR[i])

    benchmark(run)


@pytest.mark.benchmark(group="distance")
@pytest.mark.parametrize("name", ["default", "agv", "routine7_box", "routine8_overhang", "slot_field"])
def test_kernel_per_cell(benchmark, name):
    """The batch kernel on 10,000 configurations near each shipped cell's start (and the slot field):
    ``extra_info["configs_per_s"]``."""
    from dualpuma.model.cell_file import example_cell
    from dualpuma.scenarios import slot_field_cell

    cell = slot_field_cell()[0] if name == "slot_field" else example_cell(name)
    world = World(cell)
    kernel = batch_kernel(world)
    r = np.random.default_rng(0)
    Q = np.hstack([cell.left.q_home + r.normal(0, 0.2, (10_000, 6)), cell.right.q_home + r.normal(0, 0.2, (10_000, 6))])
    d, _ = benchmark.pedantic(kernel, args=(Q,), rounds=7, iterations=1, warmup_rounds=1)
    benchmark.extra_info["configs_per_s"] = len(Q) / benchmark.stats.stats.median
    benchmark.extra_info["pairs"] = len(world.pair_names)
    assert d.shape == (10_000,)
