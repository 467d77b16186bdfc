"""Tests for dualpuma.envelope_ideal (exact coordinated work envelope, thesis section 2.6)."""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dualpuma.envelope.ideal import (
    IdealEnvelope,
    closed_form_volume,
    contains_ideal,
    ideal_envelope,
)
from dualpuma.errors import ParameterError

# (reach R, base distance D, bar length L): the thesis example, r > R, short bar, close bases
CASES = [(1.0, 2.5, 1.0), (1.0, 1.5, 3.0), (0.8, 1.2, 0.4), (1.0, 0.3, 1.2)]
EXAMPLE_VOLUME = 0.46690961408952  # m^3, R = 1, D = 2.5, L = 1 (whole envelope)


# ----------------------------------------------------------------------------- brute force
def _fibonacci_sphere(n: int) -> np.ndarray:
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = math.pi * (1.0 + 5.0**0.5) * k
    s = np.sqrt(1.0 - z * z)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=-1)


def _h(p, u, bl, br, reach, r):
    """min slack of the two reach constraints for midpoint p and orientation u (>= 0: ok)."""
    return np.minimum(
        reach - np.linalg.norm(p + r * u - bl, axis=-1),
        reach - np.linalg.norm(p - r * u - br, axis=-1),
    )


def brute_force(points, bl, br, reach, bar_length, n_dirs=4000):
    """Independent membership test by sampling the bar direction u.

    Stage 1 samples u densely on the sphere (Fibonacci lattice).  Stage 2 refines without the
    cap-angle theory of the module: the maximiser of h(u) = min(h1, h2) is either an
    unconstrained maximiser of h1 (u = -a/|a|) or of h2 (u = b/|b|), or lies on the "ridge"
    h1 = h2, which is the circle (a + b) . u = (|b|^2 - |a|^2) / (2 r) on the sphere; h1 is
    unimodal along it, so dense sampling plus zooming finds its maximum.

    Returns:
        (h_grid, h_refined): best slack [m] over the lattice, and over lattice plus stage 2.
        h >= 0 certifies feasibility (the maximiser is an explicit u).
    """
    pts = np.asarray(points, float).reshape(-1, 3)
    r = bar_length / 2.0
    dirs = _fibonacci_sphere(n_dirs)
    h_grid = np.empty(len(pts))
    h_ref = np.empty(len(pts))
    for lo in range(0, len(pts), 200):
        p = pts[lo : lo + 200]
        hg = np.max(_h(p[:, None, :], dirs[None, :, :], bl, br, reach, r), axis=1)
        a, b = p - bl, p - br
        cands = []
        for v in (-a, b):  # a zero vector means h_i is constant: any unit u will do
            nv = np.linalg.norm(v, axis=1, keepdims=True)
            cands.append(np.where(nv > 0, v / np.where(nv > 0, nv, 1.0), [1.0, 0.0, 0.0]))
        best = np.max(np.stack([_h(p, c, bl, br, reach, r) for c in cands]), 0)
        if r > 0.0:
            n = a + b
            nn = np.linalg.norm(n, axis=1)
            t0 = (np.sum(b * b, 1) - np.sum(a * a, 1)) / (2 * r * np.maximum(nn, 1e-300))
            ok = (nn > 1e-12) & (np.abs(t0) <= 1.0)
            nh = n / np.maximum(nn, 1e-300)[:, None]
            e1 = np.cross(nh, [0.3, 0.5, 0.81])
            e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
            e2 = np.cross(nh, e1)
            rad = np.sqrt(np.clip(1.0 - t0 * t0, 0.0, None))
            centre, width = np.zeros(len(p)), np.full(len(p), np.pi)
            for _ in range(6):
                beta = centre[:, None] + width[:, None] * np.linspace(-1, 1, 801)[None, :]
                u = t0[:, None, None] * nh[:, None] + rad[:, None, None] * (
                    np.cos(beta)[..., None] * e1[:, None] + np.sin(beta)[..., None] * e2[:, None]
                )
                hr = _h(p[:, None, :], u, bl, br, reach, r)
                k = np.argmax(hr, axis=1)
                centre, width = beta[np.arange(len(p)), k], width / 200.0
            best = np.where(ok, np.maximum(best, hr[np.arange(len(p)), k]), best)
        h_grid[lo : lo + 200] = hg
        h_ref[lo : lo + 200] = np.maximum(hg, best)
    return h_grid, h_ref


def _bases(distance):
    return np.array([-distance / 2, 0.0, 0.0]), np.array([distance / 2, 0.0, 0.0])


# ----------------------------------------------------------------------------- membership
@pytest.mark.parametrize("reach,dist,length", CASES)
def test_membership_matches_brute_force_random_points(reach, dist, length):
    env = ideal_envelope(reach, dist, length)
    bl, br = env.base_left, env.base_right
    rho = 1.1 * max(float(np.max(np.abs(b[:, 2]))) for b in env.boundary)
    xs = 1.1 * max(float(np.max(np.abs(b[:, 0]))) for b in env.boundary)
    rng = np.random.default_rng(42)
    pts = rng.uniform([-xs, -rho, -rho], [xs, rho, rho], size=(2000, 3))
    wide = rng.uniform(-(reach + length), reach + length, size=(400, 3))
    pts = np.concatenate([pts, wide])
    got = contains_ideal(pts, bl, br, reach, length)
    h_grid, h_ref = brute_force(pts, bl, br, reach, length)
    assert np.all(got[h_grid >= 0.0])  # a sampled u is a proof of feasibility
    assert np.all(got[h_ref >= 1e-12])
    assert not np.any(got[h_ref <= -1e-12])  # refinement finds a u whenever one exists
    assert np.mean(np.abs(h_ref) > 1e-9) > 0.99
    assert 0.2 < got.mean() < 0.8  # the sample really tests both answers


@pytest.mark.parametrize("reach,dist,length", CASES)
def test_boundary_points_both_sides(reach, dist, length):
    env = ideal_envelope(reach, dist, length, resolution=64)
    bl, br = env.base_left, env.base_right
    rng = np.random.default_rng(7)
    inner, outer = [], []
    eps = 1e-6 * reach
    for line in env.boundary:
        tang = np.gradient(line, axis=0)
        normal = np.stack([tang[:, 2], np.zeros(len(line)), -tang[:, 0]], axis=-1)
        normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
        keep = np.abs(line[:, 2]) > 1e-3  # away from the axis, where arcs meet at corners
        inner.append(line[keep] - eps * normal[keep])
        outer.append(line[keep] + eps * normal[keep])
    p_in, p_out = np.concatenate(inner), np.concatenate(outer)
    # spin about the base line (the x axis) to leave the x-z plane
    ang = rng.uniform(0.0, 2.0 * np.pi, size=len(p_in))
    c, s = np.cos(ang), np.sin(ang)

    def spin(p):
        return np.stack([p[:, 0], -s * p[:, 2], c * p[:, 2]], axis=-1)

    a_in = contains_ideal(spin(p_in), bl, br, reach, length)
    a_out = contains_ideal(spin(p_out), bl, br, reach, length)
    assert len(p_in) > 50
    assert np.mean(a_in != a_out) > 0.97  # exactly one of each pair is inside
    both = np.concatenate([spin(p_in), spin(p_out)])
    got = np.concatenate([a_in, a_out])
    sub = rng.choice(len(both), size=min(600, len(both)), replace=False)
    _, h_ref = brute_force(both[sub], bl, br, reach, length)
    sure = np.abs(h_ref) > 1e-11
    assert sure.mean() > 0.95
    assert np.array_equal(got[sub][sure], h_ref[sure] > 0.0)


@pytest.mark.parametrize("reach,dist,length", CASES[:2])
def test_boundary_polylines_lie_on_the_boundary_and_close_up(reach, dist, length):
    env = ideal_envelope(reach, dist, length)
    pts = np.concatenate([b[::3] for b in env.boundary])
    _, h_ref = brute_force(pts, env.base_left, env.base_right, reach, length)
    assert np.max(np.abs(h_ref)) < 1e-12
    ends = np.concatenate([np.stack([b[0], b[-1]]) for b in env.boundary])
    dmat = np.linalg.norm(ends[:, None] - ends[None, :], axis=-1) + np.eye(len(ends))
    assert np.max(np.min(dmat, axis=1)) < 1e-6  # every end meets another end: closed loop


def test_swapped_hands_give_the_same_set():
    reach, dist, length = CASES[0]
    bl, br = _bases(dist)
    pts = np.random.default_rng(3).uniform([-0.4, -0.8, -0.8], [0.4, 0.8, 0.8], size=(600, 3))
    _, h_swap = brute_force(pts, br, bl, reach, length)  # left hand now serves the right end
    got = contains_ideal(pts, bl, br, reach, length)
    sure = np.abs(h_swap) > 1e-12
    assert np.array_equal(got[sure], h_swap[sure] > 0)
    assert np.array_equal(got, contains_ideal(pts, br, bl, reach, length))


@settings(max_examples=60, deadline=None)
@given(
    reach=st.floats(0.2, 3.0),
    dist=st.floats(0.0, 6.0),
    length=st.floats(0.0, 4.0),
    seed=st.integers(0, 2**31),
)
def test_membership_invariant_under_rigid_motion(reach, dist, length, seed):
    rng = np.random.default_rng(seed)
    bl, br = _bases(dist)
    pts = rng.uniform(-2.0 * reach - length, 2.0 * reach + length, size=(300, 3))
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    t = rng.normal(size=3)
    a = contains_ideal(pts, bl, br, reach, length)
    b = contains_ideal(pts @ q.T + t, q @ bl + t, q @ br + t, reach, length)
    clear = _margin(pts, bl, br, reach, length) > 1e-9  # skip points numerically on the boundary
    assert np.array_equal(a[clear], b[clear])
    # necessary condition: the midpoint lies within R of the bases' midpoint
    assert not np.any(a & (np.linalg.norm(pts, axis=-1) > reach + 1e-12))


def _margin(pts, bl, br, reach, length):
    """Smallest |slack| of the three conditions of the exact test (distance to a sign flip)."""
    from dualpuma.envelope.ideal import membership_slacks

    return np.min(np.abs(np.stack(membership_slacks(pts, bl, br, reach, length))), axis=0)


def test_coincident_bases_without_a_bar_are_one_ball_drawn_once():
    """D = 0, L = 0: the two reach balls are one; its meridian circle was drawn twice."""
    env = ideal_envelope(1.0, 0.0, 0.0)
    assert len(env.boundary) == 1 and env.volume_m3 == pytest.approx(4.0 / 3.0 * math.pi, rel=1e-9)
    np.testing.assert_allclose(np.linalg.norm(env.boundary[0] - 0.5 * (env.base_left + env.base_right), axis=1), 1.0,
                               atol=1e-12)
    # a numpy float is a real like any other (rtol refused a float32 that reach took)
    assert ideal_envelope(1.0, 2.5, 1.0, rtol=np.float32(1e-6)).volume_m3 == pytest.approx(0.46691, abs=1e-5)


def test_zero_length_bar_is_the_lens_of_the_reach_balls():
    bl, br = _bases(1.2)
    pts = np.random.default_rng(1).uniform(-1.5, 1.5, size=(5000, 3))
    lens = (np.linalg.norm(pts - bl, axis=1) <= 1.0) & (np.linalg.norm(pts - br, axis=1) <= 1.0)
    assert np.array_equal(contains_ideal(pts, bl, br, 1.0, 0.0), lens)


# ----------------------------------------------------------------------------- volume
@pytest.mark.parametrize("reach,dist,length", CASES)
def test_volume_matches_monte_carlo(reach, dist, length):
    env = ideal_envelope(reach, dist, length)
    bl, br = env.base_left, env.base_right
    half = reach  # the envelope lies within R of the bases' midpoint
    rng = np.random.default_rng(2024)
    n = 400_000
    pts = rng.uniform(-half, half, size=(n, 3))
    inside = contains_ideal(pts, bl, br, reach, length)
    box = (2 * half) ** 3
    p = inside.mean()
    sigma = box * math.sqrt(p * (1 - p) / n)
    assert abs(env.volume_m3 - box * p) < 3 * sigma
    upper = inside & (pts[:, 2] >= 0.0)
    pu = upper.mean()
    assert abs(env.volume_upper_half_m3 - box * pu) < 3 * box * math.sqrt(pu * (1 - pu) / n)


def test_volume_by_independent_ray_integration():
    """Star-shaped about the bases' midpoint: V = 2 pi/3 * int r(theta)^3 sin(theta) dtheta."""
    reach, dist, length = CASES[0]
    bl, br = _bases(dist)
    t, w = np.polynomial.legendre.leggauss(200)
    total = 0.0
    edges = np.linspace(0.0, np.pi, 9)
    for lo, hi in itertools.pairwise(edges):
        th = 0.5 * (lo + hi) + 0.5 * (hi - lo) * t
        d = np.stack([np.cos(th), np.zeros_like(th), np.sin(th)], axis=-1)
        # star-shaped check along each ray
        radii = np.linspace(0.0, 0.7, 300)
        inside = contains_ideal(d[:, None, :] * radii[None, :, None], bl, br, reach, length)
        assert np.all(np.diff(inside.astype(int), axis=1) <= 0)
        a, b = np.zeros(len(th)), np.full(len(th), 0.7)
        for _ in range(55):
            m = 0.5 * (a + b)
            ok = contains_ideal(d * m[:, None], bl, br, reach, length)
            a, b = np.where(ok, m, a), np.where(ok, b, m)
        total += 0.5 * (hi - lo) * np.sum(w * a**3 * np.sin(th))
    ray_volume = 2.0 * np.pi / 3.0 * total
    assert ray_volume == pytest.approx(ideal_envelope(reach, dist, length).volume_m3, rel=2e-6)


@pytest.mark.parametrize("reach,dist,length", CASES)
def test_volume_converges_with_resolution(reach, dist, length):
    coarse = ideal_envelope(reach, dist, length, resolution=16)
    fine = ideal_envelope(reach, dist, length, resolution=512)
    assert coarse.volume_m3 == pytest.approx(fine.volume_m3, rel=1e-2)
    assert coarse.volume_m3 == pytest.approx(fine.volume_m3, rel=1e-9)
    assert fine.volume_error_m3 < 1e-9 * fine.volume_m3


@pytest.mark.parametrize(
    "reach,dist,length,expected",
    [
        (1.0, 1.2, 0.0, math.pi * (4 + 1.2) * (2 - 1.2) ** 2 / 12),  # lens
        (1.3, 0.0, 1.0, 4 / 3 * math.pi * (1.3**2 - 0.25) ** 1.5),  # coincident bases
        (0.9, 1.4, 1.4, 4 / 3 * math.pi * 0.9**3),  # L = D: parallelogram
        (1.0, 0.0, 0.0, 4 / 3 * math.pi),
    ],
)
def test_quadrature_matches_closed_form(reach, dist, length, expected):
    env = ideal_envelope(reach, dist, length)
    assert env.volume_closed_form_m3 == pytest.approx(expected, rel=1e-14)
    assert closed_form_volume(reach, dist, length) == env.volume_closed_form_m3
    assert env.volume_m3 == pytest.approx(expected, rel=1e-9)
    assert len(env.boundary) > 0


def test_nearly_degenerate_geometry_is_continuous():
    ball = closed_form_volume(1.0, 0.0, 1.0)
    assert ideal_envelope(1.0, 1e-6, 1.0).volume_m3 == pytest.approx(ball, rel=1e-5)
    assert ideal_envelope(1.0, 1e-3, 1.0).volume_m3 > ball  # spreading the bases helps here
    lens = closed_form_volume(1.0, 1.2, 0.0)
    assert ideal_envelope(1.0, 1.2, 1e-6).volume_m3 == pytest.approx(lens, rel=1e-4)


def test_general_case_has_no_closed_form():
    assert ideal_envelope(1.0, 2.5, 1.0).volume_closed_form_m3 is None


@pytest.mark.parametrize(
    "reach,dist,length",
    [(1.0, 3.5, 1.0), (1.0, 3.0, 1.0), (1.0, 0.5, 2.6), (1.0, 0.0, 2.0), (0.5, 10.0, 0.0)],
)
def test_empty_envelope_has_zero_volume(reach, dist, length):
    env = ideal_envelope(reach, dist, length)
    assert env.volume_m3 == 0.0 and env.volume_upper_half_m3 == 0.0
    assert env.boundary == ()
    assert env.volume_closed_form_m3 == 0.0
    pts = np.random.default_rng(0).uniform(-3, 3, size=(2000, 3))
    assert not contains_ideal(pts, env.base_left, env.base_right, reach, length).any()


# ----------------------------------------------------------------------------- the seed example
def test_seed_example_exact_volume_and_thesis_estimate():
    env = ideal_envelope(1.0, 2.5, 1.0)
    assert env.volume_m3 == pytest.approx(EXAMPLE_VOLUME, rel=1e-11)
    assert env.volume_upper_half_m3 == pytest.approx(EXAMPLE_VOLUME / 2, rel=1e-11)
    thesis = 2.0 / 3.0 * math.pi * (3 / 4) * (2 / 3) ** 2  # eq. (2.2), x1 = 3/4, x2 = 2/3
    assert thesis == pytest.approx(2.0 / 9.0 * math.pi, rel=1e-15)
    assert env.volume_upper_half_m3 / thesis == pytest.approx(0.3344, abs=1e-3)
    # with the true axial half-width x1 = R + L/2 - D/2 = 1/4 the same formula is close
    assert env.volume_upper_half_m3 == pytest.approx(2 / 27 * math.pi, rel=5e-3)
    # the thesis's "sum of the two robots' envelopes" (two half-balls of radius 1 m)
    assert 2 * (2 / 3 * math.pi) == pytest.approx(4 / 3 * math.pi)


def test_seed_example_extents():
    bl, br = _bases(2.5)
    top = math.sqrt(1.0 - 0.75**2)  # bar level, hands 3/4 m horizontally from their bases
    pts = np.array(
        [
            [0.25 - 1e-9, 0, 0],
            [0.25 + 1e-7, 0, 0],
            [0, 0, top - 1e-9],
            [0, 0, top + 1e-7],
            [-0.25 + 1e-9, 0, 0],
            [-0.25 - 1e-7, 0, 0],
            [0, top - 1e-9, 0],
            [0, top + 1e-7, 0],
        ]
    )
    assert contains_ideal(pts, bl, br, 1.0, 1.0).tolist() == [True, False] * 4


# ----------------------------------------------------------------------------- API details
def test_result_is_frozen_and_read_only():
    env = ideal_envelope(1.0, 2.5, 1.0, resolution=16)
    assert isinstance(env, IdealEnvelope)
    with pytest.raises(dataclasses.FrozenInstanceError):
        env.volume_m3 = 1.0  # type: ignore[misc]
    with pytest.raises(ValueError):
        env.boundary[0][0, 0] = 1.0
    with pytest.raises(ValueError):
        env.base_left[0] = 1.0
    assert all(b.ndim == 2 and b.shape[1] == 3 for b in env.boundary)
    assert np.allclose(np.concatenate(env.boundary)[:, 1], 0.0)


def test_custom_base_positions_move_the_boundary_plane():
    bl, br = np.array([1.0, 2.0, 0.5]), np.array([1.0 + 2.5 * 0.6, 2.0 + 2.5 * 0.8, 0.5])
    env = ideal_envelope(1.0, 2.5, 1.0, base_left=bl, base_right=br)
    assert env.volume_m3 == pytest.approx(EXAMPLE_VOLUME, rel=1e-11)
    pts = np.concatenate(env.boundary)
    axis = (br - bl) / 2.5
    normal = np.cross(axis, [0.0, 0.0, 1.0])
    assert np.allclose((pts - bl) @ normal, 0.0, atol=1e-12)  # vertical plane through bases
    assert np.ptp(pts[:, 2]) > 1.2  # spans above and below the base height
    _, h_ref = brute_force(pts[::11], bl, br, 1.0, 1.0)
    assert np.max(np.abs(h_ref)) < 1e-12


BAD = [
    ({"reach": 0.0}, "reach"),
    ({"reach": -1.0}, "reach"),
    ({"reach": float("nan")}, "reach"),
    ({"reach": float("inf")}, "reach"),
    ({"reach": "one"}, "reach"),
    ({"base_distance": -0.1}, "base_distance"),
    ({"base_distance": float("inf")}, "base_distance"),
    ({"bar_length": -1.0}, "bar_length"),
    ({"bar_length": float("nan")}, "bar_length"),
    ({"resolution": 0}, "resolution"),
    ({"resolution": 7}, "resolution"),
    ({"resolution": 2.5}, "resolution"),
    ({"resolution": True}, "resolution"),
    ({"resolution": 10**6}, "resolution"),
    ({"rtol": 0.0}, "rtol"),
    ({"rtol": 0.5}, "rtol"),
    ({"base_left": np.zeros(3)}, "base_left"),
    ({"base_left": np.zeros(3), "base_right": np.ones(3)}, "base_distance"),
    ({"base_left": np.zeros(2), "base_right": np.ones(3)}, "base_left"),
    ({"base_left": [0, 0, 0], "base_right": [np.nan, 0, 0]}, "base_right"),
]


@pytest.mark.parametrize("override,name", BAD)
def test_ideal_envelope_rejects_bad_parameters(override, name):
    kwargs = {"reach": 1.0, "base_distance": 2.5, "bar_length": 1.0} | override
    with pytest.raises(ParameterError) as info:
        ideal_envelope(**kwargs)
    assert name in str(info.value)
    if name in ("reach", "base_distance", "bar_length", "resolution", "rtol"):
        assert "[" in str(info.value) or "(" in str(info.value)  # states the valid range


@pytest.mark.parametrize(
    "args,name",
    [
        ((np.zeros((4, 2)), [0, 0, 0], [1, 0, 0], 1.0, 1.0), "points"),
        ((np.zeros((4, 3)), [0, 0], [1, 0, 0], 1.0, 1.0), "base_left"),
        ((np.zeros((4, 3)), [0, 0, 0], [1, 0, np.inf], 1.0, 1.0), "base_right"),
        ((np.zeros((4, 3)), [0, 0, 0], [1, 0, 0], 0.0, 1.0), "reach"),
        ((np.zeros((4, 3)), [0, 0, 0], [1, 0, 0], 1.0, -2.0), "bar_length"),
        ((np.zeros((4, 3)), [0, 0, 0], [1, 0, 0], 1.0, float("nan")), "bar_length"),
    ],
)
def test_contains_rejects_bad_parameters(args, name):
    from dualpuma.envelope import membership_slacks

    with pytest.raises(ParameterError, match=name):
        contains_ideal(*args)
    with pytest.raises(ParameterError, match=name):  # it raised numpy's errors, or took a negative reach
        membership_slacks(*args)
    if name in ("reach", "bar_length"):
        with pytest.raises(ParameterError, match=name):
            closed_form_volume(args[3], 1.0, args[4])


def test_contains_shapes_and_nonfinite_points():
    bl, br = _bases(2.5)
    pts = np.zeros((2, 5, 3))
    assert contains_ideal(pts, bl, br, 1.0, 1.0).shape == (2, 5)
    assert contains_ideal(np.array([np.nan, 0, 0]), bl, br, 1.0, 1.0).shape == ()
    assert not contains_ideal(np.array([[np.nan, 0, 0], [np.inf, 0, 0]]), bl, br, 1.0, 1.0).any()
