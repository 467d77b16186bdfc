"""``dualpuma envelope`` run as a subprocess: its JSON against independent computations (a direct
minimisation over the bar direction for the idealised model, closed forms, a Monte Carlo estimate
with the public IK for the real cell) and clear errors with exit code 2 for bad arguments."""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from dualpuma import Cell, World, puma, save_cell
from dualpuma.envelope import real_envelope
from dualpuma.kinematics import hands_from_object


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "dualpuma.cli", "envelope", *args], capture_output=True, text=True, timeout=300, check=False
    )


def _json(*args: str) -> dict:
    r = _cli(*args, "--json")
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


# ------------------------------------------------------------------ independent idealised model
def _worst_reach(x: np.ndarray, rho: np.ndarray, a: float, r: float, n_phi: int = 512) -> np.ndarray:
    """min over bar directions u of max(|O + r u - B_left|, |O - r u - B_right|) for O = (x, 0, rho),
    bases (-a, 0, 0), (a, 0, 0). Each hand's admissible u form a spherical cap centred in the plane of
    O and the bases, and two caps that meet also meet on the great circle through their centres, so
    searching u = (cos phi, 0, sin phi) suffices: a grid, then ternary search around the best angle."""

    def f(x, rho, phi):
        c, s = r * np.cos(phi), r * np.sin(phi)
        return np.maximum(np.hypot(x + c + a, rho + s), np.hypot(x - c - a, rho - s))

    grid = np.linspace(-np.pi, np.pi, n_phi, endpoint=False)
    out = np.empty(len(x))
    for k in range(0, len(x), 2048):  # chunks keep the (points, angles) temporaries small
        xc, rc = x[k : k + 2048], rho[k : k + 2048]
        best = grid[np.argmin(f(xc[:, None], rc[:, None], grid[None, :]), axis=1)]
        lo, hi = best - 2 * np.pi / n_phi, best + 2 * np.pi / n_phi
        for _ in range(40):
            m1, m2 = lo + (hi - lo) / 3, hi - (hi - lo) / 3
            left = f(xc, rc, m1) < f(xc, rc, m2)
            hi, lo = np.where(left, m2, hi), np.where(left, lo, m1)
        out[k : k + 2048] = f(xc, rc, 0.5 * (lo + hi))
    return out


def _ideal_volume(R: float, D: float, L: float, nx: int = 300, nrho: int = 100) -> float:
    """V = integral of the cross-section area A(x) = pi * sum(rho_hi^2 - rho_lo^2) (midpoint rule in x),
    the rho intervals found by sampling each ray and bisecting every in/out change to 1e-12 m."""
    a, r = D / 2, L / 2
    x_max = R + r - a
    if x_max <= 0:
        return 0.0
    xs = -x_max + (np.arange(nx) + 0.5) * (2 * x_max / nx)
    rho = np.linspace(0.0, R + r, nrho)
    X, P = np.meshgrid(xs, rho, indexing="ij")
    inside = (_worst_reach(X.ravel(), P.ravel(), a, r) <= R).reshape(X.shape)
    area = np.zeros(nx)
    i, j = np.nonzero(inside[:, 1:] != inside[:, :-1])
    lo, hi = rho[j], rho[j + 1]
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        m = _worst_reach(xs[i], mid, a, r) <= R
        same = m == inside[i, j]
        lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
    edge = 0.5 * (lo + hi)
    sign = np.where(inside[i, j], -1.0, 1.0)  # entering (+ rho^2 lower end) or leaving the set
    np.add.at(area, i, -sign * edge**2)
    assert not inside[:, -1].any()  # rho = R + r is outside: every in-interval was closed above
    return float(math.pi * area.sum() * (2 * x_max / nx))


def test_independent_ideal_reference_reproduces_closed_forms():
    """Guard on the reference itself: the L = D ball and the L = 0 lens."""
    assert _ideal_volume(1.0, 1.0, 1.0) == pytest.approx(4 / 3 * math.pi, rel=2e-5)
    assert _ideal_volume(1.0, 1.5, 0.0) == pytest.approx(math.pi * 5.5 * 0.25 / 12, rel=2e-5)


def test_ideal_seed_example_against_independent_integration():
    d = _json("--ideal", "--reach-mm", "1000", "--base-distance-mm", "2500", "--bar-length-mm", "1000")
    ref = _ideal_volume(1.0, 2.5, 1.0)
    assert d["model"] == "ideal"
    assert d["volume_m3"] == pytest.approx(ref, rel=2e-5)
    assert d["volume_upper_half_m3"] == pytest.approx(ref / 2, rel=2e-5)  # a solid of revolution about the base line
    assert d["volume_m3"] == pytest.approx(0.466910, abs=5e-7) and d["volume_upper_half_m3"] == pytest.approx(0.233455, abs=5e-7)
    assert d["seed_estimate_upper_half_m3"] == pytest.approx(2 / 9 * math.pi)
    assert 0 <= d["volume_error_m3"] < 1e-8


def test_ideal_boundary_lies_on_the_independent_boundary():
    d = _json("--ideal", "--reach", "1000", "--base-distance", "2500", "--bar-length", "1000")  # old names: mm
    pts = np.concatenate([np.asarray(line) for line in d["xz_boundary_m"]])
    assert pts.shape[1] == 3 and len(pts) > 50
    np.testing.assert_allclose(pts[:, 1], 0.0, atol=1e-12)
    w = _worst_reach(pts[:, 0], np.abs(pts[:, 2]), 1.25, 0.5, n_phi=4096)
    np.testing.assert_allclose(w, 1.0, atol=1e-6)  # on the boundary: the best bar direction just reaches


@pytest.mark.parametrize(
    ("R", "D", "L", "volume"),
    [
        (1.0, 1.0, 1.0, 4 / 3 * math.pi),  # L = D: ball of radius R about the midpoint
        (1.0, 1.5, 0.0, math.pi * (4 + 1.5) * (2 - 1.5) ** 2 / 12),  # L = 0: lens of two balls
        (0.8, 0.0, 0.6, 4 / 3 * math.pi * (0.64 - 0.09) ** 1.5),  # D = 0: ball of radius sqrt(R^2 - r^2)
        (1.0, 3.5, 1.0, 0.0),  # D > 2R + L: empty
    ],
)
def test_ideal_closed_forms(R, D, L, volume):
    d = _json("--ideal", "--reach-mm", str(R * 1000), "--base-distance-mm", str(D * 1000), "--bar-length-mm",
              str(L * 1000))
    assert d["volume_m3"] == pytest.approx(volume, rel=1e-8, abs=1e-12)
    assert d["volume_upper_half_m3"] == pytest.approx(volume / 2, rel=1e-8, abs=1e-12)


# ------------------------------------------------------------------ real cell
def test_real_default_cell_against_monte_carlo():
    """Uniform points, membership by hands_from_object + the public batch puma.ik_all + the floor."""
    d = _json("--resolution-mm", "40")
    cell = Cell.default()
    h = d["resolution_m"]
    assert d["model"] == "real" and h == 0.04 and not d["clearance_checked"] and d["floor_excluded"]
    assert d["volume_m3"] == pytest.approx(d["points"] * h**3, rel=1e-12)
    B = np.asarray(d["bounds_m"])
    rng = np.random.default_rng(3)
    n = 300_000
    P = rng.uniform(B[:, 0], B[:, 1], (n, 3))
    T = np.tile(np.asarray(cell.T_world_object_start), (n, 1, 1))
    T[:, :3, 3] = P
    TL, TR = hands_from_object(cell, T)
    inside = puma.ik_all(TL)[1].any(axis=1) & puma.ik_all(TR)[1].any(axis=1) & (P[:, 2] >= cell.floor_z)
    box = float(np.prod(B[:, 1] - B[:, 0]))
    for flags, vol in ((inside, d["volume_m3"]), (inside & (P[:, 2] >= d["z_split_m"]), d["volume_upper_half_m3"])):
        f = flags.mean()
        sigma = math.sqrt(f * (1 - f) / n) * box
        assert abs(vol - f * box) < 4 * sigma + 0.002 * vol, (vol, f * box, sigma)
    assert d["z_split_m"] == pytest.approx(0.6604)
    for line in d["xz_boundary_m"]:  # closed polylines in the plane y = y_slice
        assert line[0] == line[-1] and len(line) > 10
        np.testing.assert_allclose(np.asarray(line)[:, 1], d["y_slice_m"])


def test_real_cell_file_and_clearance(tmp_path):
    cell = Cell.default()
    T = np.array(cell.right.T_world_base)
    T[0, 3] += 0.2  # bases 1.2 m apart; home joints that hold the bar from there (a cell's must)
    H = cell.T_world_object_start @ cell.grasp_right.T_object_hand
    q = puma.ik(np.linalg.inv(T) @ H, q_near=cell.right.q_home).q
    moved = dataclasses.replace(cell, right=dataclasses.replace(cell.right, T_world_base=T, q_home=q), name="moved")
    path = save_cell(moved, tmp_path / "moved.toml")
    d = _json("--cell", str(path), "--resolution-mm", "50")
    assert d["cell"] == "moved"
    assert d["volume_m3"] == pytest.approx(real_envelope(moved, 0.05).volume_m3, rel=1e-12)
    assert d["volume_m3"] != pytest.approx(_json("--resolution", "50")["volume_m3"], rel=1e-3)
    c = _json("--resolution-mm", "50", "--clearance")
    assert c["clearance_checked"]
    assert c["volume_m3"] == pytest.approx(real_envelope(cell, 0.05, world=World(cell)).volume_m3, rel=1e-12)
    assert c["volume_m3"] < _json("--resolution-mm", "50")["volume_m3"]


def test_text_output_in_millimetres_and_degrees():
    """The printed summary speaks millimetres and degrees like every flag (volumes in m³); --json
    stays SI. It used to print the JSON's keys and SI values ("reach_m: 1.0" after --reach-mm 1000)."""
    r = _cli("--ideal")
    d = _json("--ideal")
    assert r.returncode == 0
    assert r.stdout.startswith("ideal work envelope: reach 1000 mm, base distance 2500 mm, bar length 1000 mm\n")
    assert f"volume {d['volume_m3']:.6f} m³" in r.stdout and f"upper half {d['volume_upper_half_m3']:.6f} m³" in r.stdout
    assert f"(eq. 2.2): {2 * math.pi / 9:.6f} m³" in r.stdout  # the thesis's own estimate, 2 pi / 9
    real = _cli("--resolution-mm", "50")
    e = _json("--resolution-mm", "50")
    assert real.returncode == 0 and "_m" not in real.stdout and "_m" not in r.stdout  # no SI field names
    # the default cell holds the bar upside down: R = diag(1, -1, -1) = Rx(180 deg)
    assert "start orientation (roll 180.0, pitch 0.0, yaw 0.0 deg)" in real.stdout
    (x0, x1), (y0, y1), (z0, z1) = e["bounds_m"]
    assert f"bounds: x {x0 * 1e3:.0f}..{x1 * 1e3:.0f} mm, y {y0 * 1e3:.0f}..{y1 * 1e3:.0f} mm, " \
           f"z {z0 * 1e3:.0f}..{z1 * 1e3:.0f} mm" in real.stdout
    assert f"volume {e['volume_m3']:.4f} m³, above z = {e['z_split_m'] * 1e3:.0f} mm" in real.stdout
    assert f"{e['points']:,} of {e['grid_points']:,} grid points on a 50 mm grid" in real.stdout


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--resolution", "-1"), "resolution"),
        (("--resolution-mm", "1"), "resolution"),
        (("--resolution", "0.025"), "millimetres"),  # the old metre value: refused with a hint
        (("--resolution", "5"), "e.g. --resolution 25 is 0.025 m"),  # an example in range (1000 is not)
        (("--resolution", "abc"), "invalid float"),
        (("--ideal", "--reach", "-1"), "reach"),
        (("--ideal", "--reach-mm", "nan"), "reach"),
        (("--ideal", "--reach", "1"), "millimetres"),
        (("--ideal", "--bar-length-mm", "-0.5"), "bar-length"),
        (("--ideal", "--base-distance-mm", "inf"), "base-distance"),
        (("--ideal", "--reach-mm", "2e6"), "reach"),
        (("--ideal", "--cell", "default"), "--cell"),
        (("--reach", "2000"), "--ideal"),
        (("--cell", "/nonexistent/cell.toml"), "nonexistent"),
    ],
)
def test_bad_arguments_exit_2_without_traceback(args, message):
    r = _cli(*args, "--json")
    assert r.returncode == 2
    assert "error" in r.stderr and message in r.stderr and "Traceback" not in r.stderr
    assert r.stdout == ""
