"""Joint-limit wrapping with a reference outside the limits (issue 13, item 4): every solution
marked valid lies inside the limits and still reaches the pose (checked with the arm's FK)."""

from __future__ import annotations

import numpy as np
import pytest

from dualpuma.kinematics import Arm, puma
from dualpuma.kinematics.limits import wrap


def test_reference_outside_the_limits_gives_solutions_inside():
    T = puma.fk(np.zeros(6))
    r = puma.ik(T, q_near=[0, 0, 0, 20, 0, 20])
    lim = puma.JOINT_LIMITS
    assert r.ok
    assert np.all(r.q >= lim[:, 0] - 1e-12) and np.all(r.q <= lim[:, 1] + 1e-12), r.q
    np.testing.assert_allclose(puma.fk(r.q), T, atol=1e-9)


@pytest.mark.parametrize("far", [20.0, -20.0, 7.0, -100.0])
def test_ik_all_valid_rows_inside_limits(far, rng):
    arm = Arm.puma560()
    lim = arm.limits
    for _ in range(200):
        q = rng.uniform(lim[:, 0], lim[:, 1])
        T = puma.fk(q)
        ref = q.copy()
        ref[[3, 5]] = far + rng.normal(0, 1, 2)
        for sols, valid in (puma.ik_all(T, q_near=ref), tuple(a[0] for a in puma.ik_all(T[None], q_near=ref))):
            assert valid.any()
            for s in sols[valid]:
                assert np.all(s >= lim[:, 0] - 1e-12) and np.all(s <= lim[:, 1] + 1e-12), s
                np.testing.assert_allclose(arm.fk(s), T, atol=1e-8)


def test_wrap_wide_range_nearest_to_clipped_reference():
    lo, hi = -4.6, 4.6
    theta = np.array([0.3, 0.3, 0.3, np.nan])
    ref = np.array([0.0, 6.0, 20.0, 0.0])
    a, inside = wrap(theta, ref, lo, hi)
    np.testing.assert_allclose(a[:3], [0.3, 0.3 + 2 * np.pi - 2 * np.pi, 0.3])  # nearest to the clipped ref
    # ref 6.0 -> clipped 4.6: candidates 0.3 and 0.3 + 2 pi = 6.58 (outside): 0.3 stays
    assert inside[:3].all() and not inside[3]
    a, inside = wrap(np.array([2.0]), np.array([4.6]), lo, hi)
    np.testing.assert_allclose(a, [2.0])  # 2.0 - 2 pi = -4.28 is farther from 4.6
