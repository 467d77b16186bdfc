"""The planner's margin test (coal collision with a security margin) against coal's distances."""

import numpy as np
import pytest

from dualpuma import World
from dualpuma.collision.batch import KERNEL_MARGIN_MIN, below_margin, min_clearance
from dualpuma.model import example_cell


def configs(cell, rng, n, spread=0.6):
    q0 = np.concatenate([cell.left.q_home, cell.right.q_home]).astype(float)
    return q0 + rng.uniform(-spread, spread, (n, 12))


@pytest.mark.parametrize("name", ["routine8_overhang", "agv"])
def test_below_margin_agrees_with_distances(name, rng):
    cell = example_cell(name)
    w = World(cell)
    Q = configs(cell, rng, 400)
    t = rng.uniform(0.0, 4.0, 400)  # the AGV moves
    d = np.array([w.min_distance(q[:6], q[6:], t=ti)[0] for q, ti in zip(Q, t)])
    for margin in (0.0, 0.02, 0.1):
        np.testing.assert_array_equal(below_margin(w, Q[:60], t[:60], margin), d[:60] < margin)
        assert 0 < np.sum(d < margin) < len(d)  # both answers occur
    # at the margin itself: each configuration's own distance +- 1e-5 m
    near = np.flatnonzero(d > 0.001)[:40]
    for eps, expected in ((1e-5, True), (-1e-5, False)):
        got = [below_margin(w, Q[i : i + 1], t[i : i + 1], float(d[i] + eps))[0] for i in near]
        assert all(g == expected for g in got)


def test_large_batches_use_exact_distances(rng):
    cell = example_cell("routine8_overhang")
    w = World(cell)
    Q = configs(cell, rng, KERNEL_MARGIN_MIN + 10)
    t = np.zeros(len(Q))
    d, _ = min_clearance(w, Q, t)
    ref = np.array([w.min_distance(q[:6], q[6:])[0] for q in Q])
    np.testing.assert_allclose(d, ref, atol=1e-6)
    np.testing.assert_array_equal(below_margin(w, Q, t, 0.02), d < 0.02)


def test_distances_do_not_depend_on_query_history(rng):
    """coal's warm start is off: the same configurations in another order give bit-identical
    distances (what lets plan() skip rebuilding the World's data)."""
    cell = example_cell("routine8_overhang")
    w = World(cell)
    assert w.history_free
    Q = configs(cell, rng, 150, spread=0.3)
    first = [w.min_distance(q[:6], q[6:])[0] for q in Q]
    again = [w.min_distance(q[:6], q[6:])[0] for q in Q[::-1]][::-1]
    assert first == again


def test_min_clearance_equals_the_world_query(rng):
    """Small batches leave the pairs that never move out of the per-configuration query (computed
    once): same distances and pairs as the World's own query over all pairs, bit for bit."""
    from dualpuma.collision.batch import constant_pairs

    cell = example_cell("routine8_overhang")
    w = World(cell)
    sp = constant_pairs(w)
    names = [w.pair_names[k] for k in np.flatnonzero(sp.const)]
    assert len(names) == 11 and ("left/pedestal", "right/pedestal") in names
    assert all(g.endswith(("/pedestal", "/column")) or g.startswith("obstacle/") for pair in names for g in pair)
    Q = configs(cell, rng, 60, spread=1.0)
    d, k = min_clearance(w, Q, np.zeros(len(Q)))
    ref = [w.min_distance(q[:6], q[6:]) for q in Q]
    assert d.tolist() == [r[0] for r in ref] and k.tolist() == [r[1] for r in ref]
    # the constant minimum is those pairs' true distance in any configuration
    per_pair = w.clearance(Q[0][:6], Q[0][6:], per_pair=True).pair_distances
    assert sp.d_const == pytest.approx(per_pair[sp.const].min(), abs=1e-12)


def test_a_constant_pair_can_be_the_minimum(rng):
    """A box standing 10 mm from the left pedestal: that constant pair is every configuration's
    minimum, in both queries."""
    import dataclasses

    from dualpuma.model import Cell, Obstacle

    base = Cell.default()
    T = np.eye(4)
    T[:3, 3] = base.left.T_world_base[:3, 3] + (0.0, -(0.12 + 0.01 + 0.05), -0.5)  # pedestal r 0.12
    cell = dataclasses.replace(base, obstacles=(Obstacle("block", "box", [0.1, 0.1, 0.2], T),))
    w = World(cell)
    Q = configs(cell, rng, 20, spread=0.02)  # near the start pose, which is 50 mm clear otherwise
    d, k = min_clearance(w, Q, np.zeros(len(Q)))
    ref = [w.min_distance(q[:6], q[6:]) for q in Q]
    assert d.tolist() == [r[0] for r in ref] and k.tolist() == [r[1] for r in ref]
    assert {w.pair_names[i] for i in k} == {("left/pedestal", "obstacle/block")}
    assert d[0] == pytest.approx(0.01, abs=1e-9)
    assert below_margin(w, Q, np.zeros(len(Q)), 0.02).all() and not below_margin(w, Q, np.zeros(len(Q)), 0.005).any()


def test_reset_rebuilds_query_data_when_coal_keeps_history(rng):
    """If a coal build lacked the warm-start switch, reset() must rebuild the World's data and the
    planner queries' own data (else a plan's answers could depend on what ran before)."""
    from dualpuma.collision.batch import constant_pairs

    cell = example_cell("routine8_overhang")
    w = World(cell)
    sp, gd = constant_pairs(w), w.geom_data
    w.reset()  # history-free: nothing to forget, nothing rebuilt
    assert constant_pairs(w) is sp and w.geom_data is gd
    w.history_free = False  # as on a coal without enable_cached_gjk_guess
    w.reset()
    assert constant_pairs(w) is not sp and w.geom_data is not gd
    Q = configs(cell, rng, 30, spread=0.3)
    d, _ = min_clearance(w, Q, np.zeros(len(Q)))
    assert d.tolist() == [w.min_distance(q[:6], q[6:])[0] for q in Q]


def test_new_geom_data_is_a_fresh_history_free_copy(rng):
    """World.new_geom_data: every pair active, coal's warm start off, and independent of the World's
    own data and of other copies (a query in one changes nothing in another)."""
    import warnings

    import pinocchio as pin

    cell = example_cell("routine8_overhang")
    w = World(cell)
    a, b = w.new_geom_data(), w.new_geom_data()
    assert a is not b and a is not w.geom_data
    assert all(a.activeCollisionPairs) and len(a.distanceRequests) == len(w.pair_ids)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        assert not any(r.enable_cached_gjk_guess for r in list(a.distanceRequests) + list(a.collisionRequests))
    a.deactivateCollisionPair(0)
    a.collisionRequests[1].security_margin = 0.5
    assert b.activeCollisionPairs[0] and w.new_geom_data().collisionRequests[1].security_margin == 0.0
    q = configs(cell, rng, 1)[0]
    ref = w.min_distance(q[:6], q[6:])
    k = pin.computeDistances(w.model, w.model.createData(), w.geom_model, b, q)
    assert (b.distanceResults[k].min_distance, k) == ref


def test_distances_do_not_depend_on_what_another_world_asked_first():
    """coal's box support keeps a factor from its first call in a process (coal-library/coal#894):
    a capsule-box distance of mixed_puma_ur5 differed in its last bit in a process that had asked
    the default cell's clearance first. dualpuma fixes that factor at import, so two fresh
    processes asking in either order give the same bits (distances and every pair's)."""
    import subprocess
    import sys

    script = """
import sys
import numpy as np
from dualpuma import Cell, World
from dualpuma.model import example_cell
if sys.argv[1] == "default first":
    w = World(Cell.default())
    w.clearance(w.cell.left.q_home, w.cell.right.q_home)
m = example_cell("mixed_puma_ur5")
c = World(m).clearance(m.left.q_home, m.right.q_home, per_pair=True)
print(repr(c.distance), np.asarray(c.pair_distances).tobytes().hex())
"""
    runs = [subprocess.run([sys.executable, "-c", script, order], capture_output=True, text=True, check=True,
                           timeout=120).stdout for order in ("mixed alone", "default first")]
    assert runs[0] == runs[1] and runs[0].startswith("0.0314284303443944")
