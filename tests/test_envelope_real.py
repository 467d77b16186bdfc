"""Real coordinated work envelope: membership against Pinocchio FK and an independent numeric IK,
volume convergence, the x-z boundary, the CLI."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import numpy as np
import pinocchio as pin
import pytest

from dualpuma import Arm, Cell, puma
from dualpuma.coordination import hands_from_object
from dualpuma.envelope import contains_real, marching_squares, real_envelope
from dualpuma.envelope_ideal import contains_ideal
from dualpuma.errors import ParameterError


@pytest.fixture(scope="module")
def cell():
    return Cell.default()


def _targets(cell, p):
    T = cell.T_world_object_start.copy()
    T[:3, 3] = p
    return hands_from_object(cell, T)


def _numeric_ik(arm: Arm, T: np.ndarray, rng, restarts: int = 12, iters: int = 80) -> bool:
    """Independent check: damped least squares on Pinocchio from random in-limit seeds."""
    lo, hi = arm.limits[:, 0], arm.limits[:, 1]
    target = pin.SE3(T[:3, :3], T[:3, 3])
    fid = arm.model.getFrameId(arm.hand_frame) if hasattr(arm, "hand_frame") else arm.model.nframes - 1
    for _ in range(restarts):
        q = rng.uniform(lo, hi)
        for _ in range(iters):
            pin.framesForwardKinematics(arm.model, arm.data, q)
            M = arm.data.oMf[fid]
            err = pin.log6(M.actInv(target)).vector
            if np.linalg.norm(err) < 1e-10:
                return True
            J = pin.computeFrameJacobian(arm.model, arm.data, q, fid, pin.LOCAL)
            q = np.clip(q + J.T @ np.linalg.solve(J @ J.T + 1e-6 * np.eye(6), err), lo, hi)
    return False


def test_membership_against_fk_and_numeric_ik(cell):
    rng = np.random.default_rng(5)
    arms = {s: Arm.puma560() for s in ("left", "right")}
    P = rng.uniform([0.6, -1.2, 0.0], [2.4, 0.6, 1.5], (400, 3))
    inside = contains_real(cell, P)
    assert 40 < inside.sum() < 360
    n_out_checked = 0
    for p, ins in zip(P, inside):
        TL, TR = _targets(cell, p)
        if ins:
            for s, T in (("left", TL), ("right", TR)):
                sols, valid = puma.ik_all(T)  # scalar path (the envelope uses the batch kernel)
                q = sols[int(np.argmax(valid))]
                np.testing.assert_allclose(arms[s].fk(q), T, atol=1e-9)
                assert np.all(q >= arms[s].limits[:, 0] - 1e-12) and np.all(q <= arms[s].limits[:, 1] + 1e-12)
        elif n_out_checked < 25:
            n_out_checked += 1
            assert not (_numeric_ik(arms["left"], TL, rng) and _numeric_ik(arms["right"], TR, rng)), p
    assert n_out_checked == 25


def test_numeric_ik_reference_is_able_to_succeed(cell):
    """Guard: the reference really finds solutions where they exist (else the check above is vacuous)."""
    rng = np.random.default_rng(1)
    TL, TR = _targets(cell, cell.T_world_object_start[:3, 3])
    assert _numeric_ik(Arm.puma560(), TL, rng) and _numeric_ik(Arm.puma560(), TR, rng)


def test_volume_converges_and_upper_half(cell):
    a, b = real_envelope(cell, 0.04), real_envelope(cell, 0.03)
    assert abs(a.volume_m3 - b.volume_m3) / b.volume_m3 < 0.01
    assert 0 < b.volume_upper_half_m3 < b.volume_m3
    assert np.all(contains_real(cell, b.points))
    np.testing.assert_allclose(len(b.points) * 0.03**3, b.volume_m3, rtol=1e-12)
    # the x-z boundary separates inside from outside in the plane y = y_start
    mid = b.xz_segments.mean(axis=1)
    assert len(mid) > 50 and np.allclose(mid[:, 1], cell.T_world_object_start[1, 3])


def test_marching_squares_on_a_disc():
    xs = ys = np.linspace(-1, 1, 201)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    segs = marching_squares((X**2 + Y**2 < 0.5**2).astype(float), xs, ys)
    length = np.linalg.norm(segs[:, 1] - segs[:, 0], axis=1).sum()
    assert abs(length - 2 * np.pi * 0.5) / (2 * np.pi * 0.5) < 0.1  # staircase of a binary field
    r = np.linalg.norm(segs.reshape(-1, 2), axis=1)
    assert np.all(np.abs(r - 0.5) < 0.011)


def test_bad_input(cell):
    for bad in (0.0, -1.0, float("nan"), 1.0):
        with pytest.raises(ParameterError):
            real_envelope(cell, bad)
    with pytest.raises(ParameterError):
        contains_real(cell, [[np.nan, 0, 0]])
    ur = dataclasses.replace(cell, right=dataclasses.replace(cell.right, robot="ur5"))
    with pytest.raises(ParameterError, match="closed-form"):
        contains_real(ur, [[1.5, -0.2, 0.3]])


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "dualpuma.cli", "envelope", *args], capture_output=True, text=True, timeout=300, check=False)


def test_cli_ideal_matches_monte_carlo():
    r = _cli("--ideal", "--reach", "1", "--base-distance", "2.5", "--bar-length", "1", "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    rng = np.random.default_rng(0)
    bl, br = np.array([-1.25, 0, 0]), np.array([1.25, 0, 0])
    box = np.array([[-0.75, 0.75], [-1.0, 1.0], [-1.0, 1.0]])  # contains the whole set (|x| <= D/2 - ... )
    n = 400_000
    P = rng.uniform(box[:, 0], box[:, 1], (n, 3))
    frac = contains_ideal(P, bl, br, 1.0, 1.0).mean()
    vol = frac * np.prod(box[:, 1] - box[:, 0])
    se = np.sqrt(frac * (1 - frac) / n) * np.prod(box[:, 1] - box[:, 0])
    assert abs(d["volume_m3"] - vol) < 4 * se + 1e-3
    assert d["volume_upper_half_m3"] == pytest.approx(d["volume_m3"] / 2, rel=1e-9)


def test_cli_real_matches_api_and_errors(cell):
    r = _cli("--resolution", "0.04", "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["volume_m3"] == pytest.approx(real_envelope(cell, 0.04).volume_m3, rel=1e-12)
    for args in (("--resolution", "-1"), ("--ideal", "--reach", "-1"), ("--cell", "/nonexistent.toml")):
        bad = _cli(*args)
        assert bad.returncode == 2 and "error" in bad.stderr and "Traceback" not in bad.stderr
