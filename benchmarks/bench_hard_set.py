"""The general planner on the hard set (group "planner"), OMPL's RRTConnect beside it in the same
run, on the same problems, with the same validity (benchmarks/ompl_peer.py).

The set: benchmarks/fixtures/hard_set.json, 36 problems (12 each of boxes, overhang, slot; see
dualpuma.scenarios.hard and benchmarks/make_hard_set.py). Ours: ``plan(..., GENERAL_PARAMS)`` (the
straight run, then the SE(3) fallback, certified motion, the whole path smoothed), a World built per
problem beforehand. Success: reached within 10 s. Figures in ``extra_info``: median and p90 planning
time, success rate, path lengths; the OMPL test adds the per-problem length ratio ours / OMPL's after
its simplifier, of the translation and of the SE(3) metric, which counts the bar's turning too
(benchmarks/path_metrics.py). OMPL comes with ``pip install 'dualpuma[bench]'`` (``make bench`` installs it).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from path_metrics import lengths

from dualpuma import World, plan
from dualpuma.scenarios.hard import GENERAL_PARAMS, problems_from_json

FIXTURE = Path(__file__).parent / "fixtures" / "hard_set.json"
LIMIT = 10.0  # [s] success within this
RESULTS: dict[str, dict] = {}


@pytest.fixture(scope="module")
def hard_set():
    probs = problems_from_json(FIXTURE.read_text())
    assert len(probs) >= 30
    return probs, [World(p.cell) for p in probs]


def _stats(times, ok) -> dict:
    t = np.array(times)
    return {"n": len(t), "median_s": float(np.median(t)), "p90_s": float(np.percentile(t, 90)),
            "max_s": float(t.max()), "success": float(np.mean(ok))}


def _ours(probs, worlds, rng=None) -> dict:
    rows = []
    for p, w in zip(probs, worlds):
        tic = time.perf_counter()
        r = plan(p.cell, p.start, p.goal, GENERAL_PARAMS, q_start=p.q_start, world=w, rng=rng)
        el = time.perf_counter() - tic
        rows.append({"tag": p.tag, "time_s": el, "ok": bool(r.reached and el <= LIMIT), "length": r.path_length,
                     "metric": lengths(r.T_world_object)[1], "steps": r.n_steps})
    return {"rows": rows, **_stats([x["time_s"] for x in rows], [x["ok"] for x in rows])}


@pytest.mark.benchmark(group="planner")
def test_hard_set_general_planner(benchmark, hard_set):
    probs, worlds = hard_set
    res = benchmark.pedantic(_ours, args=(probs, worlds), rounds=1, iterations=1)
    RESULTS["ours"] = res
    benchmark.extra_info.update({k: v for k, v in res.items() if k != "rows"})
    benchmark.extra_info["per_family_median_s"] = {
        f: float(np.median([x["time_s"] for x in res["rows"] if x["tag"].startswith(f)]))
        for f in ("boxes", "overhang", "slot")}
    benchmark.extra_info["failed"] = [x["tag"] for x in res["rows"] if not x["ok"]]
    assert res["success"] >= 0.9, benchmark.extra_info["failed"]  # the target is 1.0: see the README


@pytest.mark.benchmark(group="planner")
def test_hard_set_ompl_rrtconnect(benchmark, hard_set):
    try:
        import ompl_peer
    except ImportError as e:  # the peer is part of the benchmark run: install it, do not skip it
        pytest.fail(f"OMPL is needed for this benchmark: pip install 'dualpuma[bench]' ({e})")
    probs, worlds = hard_set

    def run():
        rows = []
        for p, w in zip(probs, worlds):
            o = ompl_peer.solve(p, w, LIMIT)
            rows.append({"tag": p.tag, **o})
        return {"rows": rows, **_stats([x["time_s"] for x in rows], [x["ok"] for x in rows])}

    res = benchmark.pedantic(run, rounds=1, iterations=1)
    benchmark.extra_info.update({k: v for k, v in res.items() if k != "rows"})
    ours = RESULTS.get("ours") or _ours(probs, worlds)
    both = [(a, b) for a, b in zip(ours["rows"], res["rows"]) if a["ok"] and b["ok"]]
    if both:
        for key, name in (("length", "length_ratio"), ("metric", "metric_ratio")):
            ratio = np.array([a[key] / b[key] for a, b in both])
            benchmark.extra_info.update({f"{name}_median": float(np.median(ratio)),
                                         f"{name}_p90": float(np.percentile(ratio, 90)), f"{name}_max": float(ratio.max())})
        benchmark.extra_info["both_solved"] = len(both)
        benchmark.extra_info["ours_vs_ompl_median_time"] = ours["median_s"] / res["median_s"]


SEEDS = range(6)  # the search is randomised and its time heavy-tailed: one seed is one draw


@pytest.mark.benchmark(group="planner")
def test_hard_set_six_seeds(benchmark, hard_set):
    """Ours over seeds 0-5 (216 searches): the median, p90 and maximum over all of them, success
    within 10 s, and each seed's median (how far one seed's figures are from the distribution's)."""
    probs, worlds = hard_set

    def run():
        per_seed = [_ours(probs, worlds, seed) for seed in SEEDS]
        rows = [x for r in per_seed for x in r["rows"]]
        return {**_stats([x["time_s"] for x in rows], [x["ok"] for x in rows]),
                "seed_medians_s": [r["median_s"] for r in per_seed], "sum_s": float(sum(x["time_s"] for x in rows)),
                "failed": [(s, x["tag"]) for s, r in zip(SEEDS, per_seed) for x in r["rows"] if not x["ok"]]}

    res = benchmark.pedantic(run, rounds=1, iterations=1)
    benchmark.extra_info.update(res)
    assert res["success"] >= 0.9, res["failed"]
