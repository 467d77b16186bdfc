"""Certified motion alone (group "planner"): ``certify_chords`` on 240 random 4-chord paths near
the obstacles of four hard-set problems (boxes, overhang, two slotted plates), every configuration
keeping the margin, as the fallback's edges and shortcuts ask it. ``extra_info``: chords, chords
certified and configurations queried (a change of the bounds or the subdivision shows there)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dualpuma import World
from dualpuma.collision import clearance_batch
from dualpuma.planning.certify import certify_chords, motion_bounds, pair_weights
from dualpuma.scenarios.hard import problems_from_json

FIXTURE = Path(__file__).parent / "fixtures" / "hard_set.json"
MARGIN = 0.02


@pytest.fixture(scope="module")
def chord_paths():
    probs = {p.tag: p for p in problems_from_json(FIXTURE.read_text())}
    rng = np.random.default_rng(0)
    cases = []
    for tag in ("boxes-0", "overhang-3", "slot-0", "slot-6"):
        p = probs[tag]
        world = World(p.cell)
        pair_weights(world)  # built once per World (timed in the routine-8 cold benchmark)
        reach, v = motion_bounds(world)
        q0 = np.concatenate(p.q_start)
        n = 0
        while n < 60:
            Q = np.cumsum(np.vstack([q0 + rng.normal(0, 0.12, 12), rng.normal(0, 0.06, (4, 12))]), axis=0)
            d, _ = clearance_batch(world, Q[:, :6], Q[:, 6:], method="coal")
            if d.min() >= MARGIN:
                cases.append((world, Q, d, reach, v))
                n += 1
    return cases


def _certify_all(cases):
    out = [certify_chords(w, Q, d, np.arange(Q.shape[0], dtype=float), MARGIN, r, v) for w, Q, d, r, v in cases]
    return sum(c.n_ok for c in out), sum(c.queries for c in out)


@pytest.mark.benchmark(group="planner")
def test_certify_chords_hard_set_paths(benchmark, chord_paths):
    ok, queries = benchmark(_certify_all, chord_paths)
    benchmark.extra_info.update(chords=4 * len(chord_paths), certified=ok, queries=queries)
    assert 0 < ok < 4 * len(chord_paths)
