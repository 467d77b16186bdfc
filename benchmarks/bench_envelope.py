"""Work-envelope benchmarks (pytest-benchmark, group "envelope"): the idealised model
(dualpuma.envelope_ideal) and the real cell (dualpuma.envelope) at its default 25 mm resolution, with
the batch membership against a scalar per-point loop on the same 10,000 points.

Run: .venv/bin/python -m pytest benchmarks/bench_envelope.py --benchmark-only -q
"""

from __future__ import annotations

import numpy as np
import pytest

from dualpuma import Cell, World, puma
from dualpuma.envelope import contains_real, real_envelope
from dualpuma.envelope.ideal import contains_ideal, ideal_envelope
from dualpuma.kinematics import hands_from_object

EXAMPLE = (1.0, 2.5, 1.0)  # thesis section 2.6: R = 1 m, D = 2.5 m, L = 1 m
CELL = Cell.default()
POINTS = np.random.default_rng(0).uniform([0.85, -0.95, -0.3], [2.15, 0.95, 1.6], size=(10_000, 3))


@pytest.mark.benchmark(group="envelope")
def test_bench_ideal_envelope_default_resolution(benchmark):
    env = benchmark(ideal_envelope, *EXAMPLE)
    assert env.volume_m3 == pytest.approx(0.46690961408952, rel=1e-10)


@pytest.mark.benchmark(group="envelope")
def test_bench_contains_ideal_100k(benchmark):
    pts = np.random.default_rng(0).uniform([-0.3, -0.7, -0.7], [0.3, 0.7, 0.7], size=(100_000, 3))
    bl, br = np.array([-1.25, 0.0, 0.0]), np.array([1.25, 0.0, 0.0])
    inside = benchmark(contains_ideal, pts, bl, br, 1.0, 1.0)
    assert inside.shape == (100_000,) and 0.2 < inside.mean() < 0.8


@pytest.mark.benchmark(group="envelope")
def test_real_envelope_default_resolution(benchmark):
    """Cell.default(), start orientation, 25 mm grid, floor excluded, no clearance."""
    env = benchmark.pedantic(real_envelope, args=(CELL,), rounds=5, iterations=1, warmup_rounds=1)
    benchmark.extra_info.update(volume_m3=env.volume_m3, upper_half_m3=env.volume_upper_half_m3, grid_points=env.grid_points)
    assert env.resolution == 0.025 and 0.89 < env.volume_m3 < 0.92


@pytest.mark.benchmark(group="envelope")
def test_real_envelope_with_clearance_40mm(benchmark):
    world = World(CELL)
    env = benchmark.pedantic(real_envelope, args=(CELL, 0.04), kwargs={"world": world}, rounds=3, iterations=1)
    benchmark.extra_info["volume_m3"] = env.volume_m3
    assert env.clearance_checked and 0.5 < env.volume_m3 < 0.9


@pytest.mark.benchmark(group="envelope")
def test_contains_real_10k_points(benchmark):
    inside = benchmark(contains_real, CELL, POINTS)
    assert 0.1 < inside.mean() < 0.6


@pytest.mark.benchmark(group="envelope")
def test_contains_real_10k_points_scalar_loop_baseline(benchmark):
    """Baseline: hands_from_object + the scalar puma.ik_all per point (what a plain loop costs)."""

    def loop():
        out = np.zeros(len(POINTS), dtype=bool)
        T = CELL.T_world_object_start.copy()
        for n, p in enumerate(POINTS):
            T[:3, 3] = p
            TL, TR = hands_from_object(CELL, T)
            out[n] = puma.ik_all(TL)[1].any() and puma.ik_all(TR)[1].any()
        return out

    inside = benchmark.pedantic(loop, rounds=3, iterations=1)
    np.testing.assert_array_equal(inside, contains_real(CELL, POINTS))
