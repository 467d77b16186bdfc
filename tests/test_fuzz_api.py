"""Fuzz of the public API: every public function of the subpackages (tests/fuzz_targets.py) is
called with one argument replaced by a generated bad value — strings, None, dicts, sets, ragged and
nested lists, NaN/inf, huge and negative integers, bools, complex numbers, arrays of every dtype and
shape, and the valid value itself mutated (a NaN or a huge entry planted, its shape changed, a batch
dimension added). Only a :class:`~dualpuma.errors.DualpumaError` may come out (or a result, such as a
Plan with status ``invalid_input``): never a ValueError, TypeError, IndexError, KeyError,
AttributeError, Boost.Python ArgumentError, OverflowError or MemoryError.

The number of inputs tried is counted and printed by the last test (about 100 per function).
"""

from __future__ import annotations

import math
import os
import warnings
from collections import Counter

import numpy as np
import pytest
from fuzz_targets import FUZZ_RANDOM, NOT_FUZZED, TARGETS, Target, public_callables
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from dualpuma.errors import DualpumaError

EXAMPLES = int(os.environ.get("DUALPUMA_FUZZ_EXAMPLES", "100"))  # per function (the file runs in ~25 s)
TRIED: Counter = Counter()
ESCAPED: list[str] = []

_SPECIAL = [None, "", "abc", "puma560", b"x", {}, {"a": 1}, set(), (), [], object(), 1 + 2j, True, False,
            0, 1, -1, 7, 8, 2**31, 2**63, 2**64, -(2**64), 10**30, 10**400, 0.0, -0.0, 1e-300, 1e300, -1e300,
            math.nan, math.inf, -math.inf, np.float64("nan"), np.int64(-5), np.bool_(True), lambda: 0,
            [[1, 2], [3]], [[[1.0]] * 4] * 4, [1.0, "a"], [None] * 6, ["a"] * 6, {"x": [1, 2, 3]},
            np.array("abc"), np.array([1, 2, 3], dtype=object), np.zeros((0,)), np.zeros((0, 6)),
            np.zeros((0, 4, 4)), np.zeros((2, 6)), np.tile(np.eye(4), (2, 1, 1)), np.eye(4), np.eye(3),
            np.zeros(6), np.full(6, np.nan), np.full((4, 4), np.inf), -np.eye(4), 10**9]

_DTYPES = st.sampled_from([np.float64, np.float32, np.int64, np.int8, np.bool_, np.complex128, np.dtype("U3"),
                           np.dtype("datetime64[s]")])


def _bad_values() -> st.SearchStrategy:
    floats = st.floats(allow_nan=True, allow_infinity=True)
    return st.one_of(
        st.sampled_from(_SPECIAL),
        floats,
        st.integers(min_value=-(2**80), max_value=2**80),
        st.text(max_size=12),
        st.lists(st.one_of(floats, st.integers(-(10**20), 10**20), st.none(), st.text(max_size=2)), max_size=8),
        st.lists(st.lists(floats, max_size=7), max_size=5),
        hnp.arrays(_DTYPES, hnp.array_shapes(min_dims=0, max_dims=4, min_side=0, max_side=6)),
    )


def _mutated(valid: object, data: st.DataObject) -> object:
    """The valid value changed a little: the inputs most likely to reach past the first check."""
    if isinstance(valid, tuple) and len(valid) == 2 and all(isinstance(v, np.ndarray) for v in valid):
        k = data.draw(st.integers(0, 1))
        parts = list(valid)
        parts[k] = _mutated(parts[k], data)
        return tuple(parts)
    if not isinstance(valid, np.ndarray) or valid.size == 0:
        return data.draw(_bad_values())
    a = np.array(valid, dtype=np.float64)
    how = data.draw(st.sampled_from(["plant", "scale", "batch", "drop", "extra", "list", "ints", "transpose"]))
    if how == "plant":
        a.flat[data.draw(st.integers(0, a.size - 1))] = data.draw(st.sampled_from([math.nan, math.inf, -math.inf,
                                                                                  1e300, -1e300, 1e-300]))
        return a
    if how == "scale":
        return a * data.draw(st.sampled_from([1e300, -1.0, 1e-300, 0.0, 1e6]))
    if how == "batch":
        return np.repeat(a[None], data.draw(st.integers(0, 3)), axis=0)
    if how == "drop":
        return a.reshape(-1)[:-1]
    if how == "extra":
        return np.append(a.reshape(-1), 0.0)
    if how == "list":
        return a.tolist()
    if how == "ints":
        return a.astype(np.int64)
    return a.T


def _call(t: Target, data: st.DataObject) -> None:
    args = [f() for f in t.args]
    kwargs = {k: f() for k, f in t.kwargs.items()}
    slots = [("a", i) for i in range(len(args))] + [("k", k) for k in kwargs]
    if not slots:
        return
    n_bad = data.draw(st.integers(1, min(2, len(slots))))
    for kind, key in data.draw(st.permutations(slots))[:n_bad]:
        valid = args[key] if kind == "a" else kwargs[key]
        bad = _mutated(valid, data) if data.draw(st.booleans()) else data.draw(_bad_values())
        if kind == "a":
            args[key] = bad
        else:
            kwargs[key] = bad
    TRIED[t.name] += 1
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t.fn(*args, **kwargs)
    except DualpumaError as e:
        assert str(e), f"{t.name}: a DualpumaError without a message"
    except BaseException as e:
        ESCAPED.append(f"{t.name}: {type(e).__name__}: {e}"[:300])
        raise AssertionError(f"{t.name} raised {type(e).__name__} (not a DualpumaError): {e}"[:2000]) from e


@pytest.fixture(scope="module", autouse=True)
def _in_a_temporary_directory(tmp_path_factory):
    """Fuzzed file names (``save_cell(cell, "abc")``) land in a temporary directory, not in the tree."""
    old = os.getcwd()
    os.chdir(tmp_path_factory.mktemp("fuzz_cwd"))
    yield
    os.chdir(old)


@pytest.mark.parametrize("target", TARGETS, ids=[t.name for t in TARGETS])
@settings(max_examples=EXAMPLES, deadline=None, database=None, derandomize=not FUZZ_RANDOM,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much])
@given(data=st.data())
def test_only_dualpuma_errors_escape(target: Target, data: st.DataObject) -> None:
    _call(target, data)


@pytest.mark.parametrize("target", TARGETS, ids=[t.name for t in TARGETS])
def test_the_valid_call_works(target: Target) -> None:
    """The template each fuzz case breaks is itself a valid call (else the fuzz would only test the
    first check); the two file targets point at missing paths on purpose."""
    args = [f() for f in target.args]
    kwargs = {k: f() for k, f in target.kwargs.items()}
    if target.name in ("dualpuma.load_cell", "dualpuma.save_cell"):
        with pytest.raises(DualpumaError):
            target.fn(*args, **kwargs)
    else:
        target.fn(*args, **kwargs)


def test_every_public_function_is_fuzzed() -> None:
    covered = {".".join(t.name.split(".")[:2]) for t in TARGETS}
    missing = sorted(p for p in public_callables() if p not in covered and p.split(".")[1] not in NOT_FUZZED)
    assert not missing, f"public functions without a fuzz target or a reason in NOT_FUZZED: {missing}"


def test_every_parameter_is_fuzzed() -> None:
    """Each target's call names every parameter of its function (the ones the targets did not list
    are added at their defaults: tests/fuzz_targets.py), so a new parameter is fuzzed at once; before,
    27 parameters of seven targets were never drawn (``plan``'s ``t_start``, ``rrt_connect``'s
    ``certified``, 16 of the planner settings, ``Problem``'s optional fields, ...), and
    ``rrt_connect(certified="x")`` raised an AttributeError."""
    import inspect

    for t in TARGETS:
        try:
            params = [p for p in inspect.signature(t.fn).parameters.values() if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]
        except (TypeError, ValueError):
            continue
        named = {p.name for p in params[: len(t.args)]} | set(t.kwargs)
        assert {p.name for p in params} <= named, (t.name, sorted({p.name for p in params} - named))


def test_zz_report(capsys) -> None:
    """Runs last in this file: how many inputs were tried, and that none escaped."""
    total = sum(TRIED.values())
    with capsys.disabled():
        print(f"\nfuzz (API): {total} generated inputs over {len(TRIED)} functions, "
              f"{len(ESCAPED)} generic exceptions escaped")
    if TRIED:  # (empty when this test is selected alone)
        assert total >= 0.9 * EXAMPLES * len(TRIED) and not ESCAPED, ESCAPED[:5]
