"""Benchmarks for dualpuma.envelope_ideal (pytest-benchmark, group "envelope").

Run: .venv/bin/python -m pytest benchmarks/bench_envelope.py --benchmark-only -q
"""

from __future__ import annotations

import numpy as np
import pytest

from dualpuma.envelope_ideal import contains_ideal, ideal_envelope

EXAMPLE = (1.0, 2.5, 1.0)  # thesis section 2.6: R = 1 m, D = 2.5 m, L = 1 m


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
    from dualpuma import Cell
    from dualpuma.envelope import real_envelope

    env = benchmark.pedantic(real_envelope, args=(Cell.default(),), rounds=3, iterations=1)
    benchmark.extra_info["volume_m3"] = env.volume_m3
    assert 0.85 < env.volume_m3 < 0.95
