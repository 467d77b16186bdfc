"""Value equality of the public results that hold arrays (dualpuma.values): a result computed twice
is equal to itself and hashes alike; one that differs in any field is not equal. Before, `==` on
them raised numpy's ValueError (the truth value of an element-wise comparison).

The expected verdicts come from comparing the fields here, with numpy's element-wise equality
(NaN equal to NaN), not from dualpuma.values."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from dualpuma import Cell, World, puma
from dualpuma.envelope import ideal_envelope, real_envelope, solve_real
from dualpuma.kinematics import Arm, solve_dual, solve_path
from dualpuma.planning import FallbackParams, interpolate_object, rrt_connect
from dualpuma.scenarios import routine


def fields_equal(a, b) -> bool:
    """Every field equal: arrays element for element (NaN equal to NaN), tuples and lists item by
    item, nested dataclasses field by field."""
    if type(a) is not type(b):
        return False
    return all(_equal(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))


def _equal(x, y) -> bool:
    if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
        x, y = np.asarray(x), np.asarray(y)
        if x.shape != y.shape:
            return False
        if x.dtype.kind in "fc":
            return bool(np.all((x == y) | (np.isnan(x) & np.isnan(y))))
        return bool(np.all(x == y))
    if isinstance(x, (tuple, list)):
        return type(x) is type(y) and len(x) == len(y) and all(_equal(u, v) for u, v in zip(x, y))
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return fields_equal(x, y)
    if isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y):
        return True
    return x == y


C = Cell.default()
A = C.T_world_object_start
Q0 = (C.left.q_home, C.right.q_home)


def _ik(q):
    return puma.ik(puma.fk(np.asarray(q, dtype=float)))


def _pairs():
    """(name, make(variant)) with variant 0 and 1 giving different values."""
    B = A.copy()
    B[:3, 3] += (-0.1, -0.05, 0.05)
    w = World(C)
    return [
        ("IKResult", lambda v: _ik([0.1 * v, -0.5, 0.4, 0.2, 0.6, -0.3])),
        ("IKResult unreachable", _far),
        ("Clearance", lambda v: w.clearance(Q0[0] + 0.01 * v, Q0[1], A)),
        ("DualSolution", lambda v: solve_dual(w, B if v else A, Q0)),
        ("PathSolution", lambda v: solve_path(w, interpolate_object(A, B, 4 + v), Q0)),
        ("IdealEnvelope", lambda v: ideal_envelope(1.0, 2.5 + 0.1 * v, 1.0)),
        ("RealMembership", lambda v: solve_real(C, A[:3, 3][None] + [[0.0, 0.0, 0.05 * v], [3.0, 0.0, 0.0]],
                                                A[:3, :3], world=w)),
        ("Routine", lambda v: routine(7 + v)),
        ("RealEnvelope", lambda v: real_envelope(C, 0.2 + 0.05 * v)),
        ("Capsule", lambda v: Arm.load("puma560").capsules[v]),
        ("FallbackResult", lambda v: dataclasses.replace(
            rrt_connect(w, A, Q0, B, FallbackParams(), 0), time_s=1.0 + v)),
    ]


def _far(v):
    T = np.eye(4)
    T[:3, 3] = (3.0 + v, 0.0, 0.0)  # out of reach: q None or NaN, status unreachable
    return puma.ik(T)


@pytest.mark.parametrize(("name", "make"), _pairs(), ids=[n for n, _ in _pairs()])
def test_a_result_computed_twice_is_equal_and_hashes_alike(name, make):
    a, again, other = make(0), make(0), make(1)
    if name == "FallbackResult":
        again = dataclasses.replace(again, time_s=a.time_s)
    if again is a:  # a routine is built once
        again = dataclasses.replace(a)
    assert a is not again and fields_equal(a, again), name
    assert a == again and hash(a) == hash(again) and not (a != again)  # noqa: SIM202 - __ne__ too
    assert not fields_equal(a, other) and a != other
    assert a != "something else" and len({a, again}) == 1


def test_equal_numbers_hash_alike_whatever_their_dtype():
    from dualpuma.planning import Problem

    a, b = Problem(C, np.eye(4), A), Problem(C, np.eye(4, dtype=np.int64), A)
    assert np.array_equal(a.start, b.start) and a == b and hash(a) == hash(b)
    z, w = Problem(C, np.array([np.nan, -0.0]), A), Problem(C, np.array([np.nan, 0.0]), A)
    assert z == w and hash(z) == hash(w)  # NaN equals NaN, -0.0 equals 0.0: so their hashes
    assert Problem(C, np.eye(4), A) != Problem(C, 2.0 * np.eye(4), A)
