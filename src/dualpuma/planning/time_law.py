"""The time law of one joint path (used by :mod:`.timing`): a cubic spline through joint samples in
a path parameter s (:func:`spline`), toppra's time-optimal rest-to-rest s(t) under joint velocity
and acceleration limits (:func:`time_optimal`: TOPP-RA with ``JointVelocityConstraint`` +
``JointAccelerationConstraint``, constant path acceleration between its gridpoints, the grid
refined where the true limits are exceeded between gridpoints), and that law evaluated in numpy
(:func:`evaluate`: s, joints, velocities and accelerations at given times; :func:`time_at`: the
time at given s). A law is ``(s_i, sd_i, t_i)``: gridpoints, path speeds and times.

Why toppra: it follows a given geometric path exactly with one time law for all joints
(TOPP-RA, Pham & Pham 2018), handles 12 joints in milliseconds, is maintained on PyPI with wheels,
and needs no network; ruckig is a point-to-point generator that does not follow a given path (its
waypoint mode calls a cloud service), which would tear the closed chain apart.
"""

from __future__ import annotations

import functools

import numpy as np
import numpy.typing as npt

__all__ = ["evaluate", "spline", "time_at", "time_optimal"]

FloatArray = npt.NDArray[np.float64]


def spline(W: FloatArray):
    """``(path, s)``: toppra's cubic spline through joint samples W (K, dof) in a path parameter s
    in [0, 1] proportional to the joint-space arc length (repeated samples dropped), and the
    samples' s."""
    import toppra as ta

    d = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(W, axis=0), axis=1))])
    keep = np.concatenate([[True], np.diff(d) > 1e-12])
    s = d[keep] / max(d[-1], 1e-300)
    return ta.SplineInterpolator(s, W[keep]), s


@functools.lru_cache(maxsize=32)
def _constraints(v: bytes, a: bytes, dof: int) -> tuple:
    """toppra's joint velocity and acceleration constraints for limits v, a ((dof,) float64 bytes
    [rad/s], [rad/s^2]), kept: they hold only the limits (the path is given to each solve), and
    toppra formats every limit into a description string when it builds them (~7 % of time_plan)."""
    from toppra import constraint

    return (constraint.JointVelocityConstraint(np.frombuffer(v).reshape(dof).copy()),
            constraint.JointAccelerationConstraint(np.frombuffer(a).reshape(dof).copy()))


def time_optimal(path, v: FloatArray, a: FloatArray, v_true: FloatArray, a_true: FloatArray):
    """The time-optimal rest-to-rest law ``(s_i, sd_i, t_i)`` of ``path`` under joint limits v
    [rad/s], a [rad/s^2] given to toppra (or None when it finds none). toppra enforces them at its
    gridpoints only: where the true limits ``v_true``, ``a_true`` are exceeded between them
    (checked at 8 points per grid interval) the grid is refined there and it runs again."""
    import toppra.algorithm as algo

    v, a = (np.ascontiguousarray(x, dtype=np.float64) for x in (v, a))
    cons = _constraints(v.tobytes(), a.tobytes(), v.shape[0])
    grid = None
    law = None
    for _ in range(6):
        inst = algo.TOPPRA(list(cons), path, gridpoints=grid, parametrizer="ParametrizeConstAccel")
        inst.compute_parameterization(0.0, 0.0)
        data = inst.problem_data
        if data.sd_vec is None or data.gridpoints is None or not np.all(np.isfinite(data.sd_vec)):
            return law
        ss = np.asarray(data.gridpoints, float).ravel()
        sd = np.maximum(np.asarray(data.sd_vec, float).ravel(), 0.0)
        dt = 2.0 * np.diff(ss) / np.maximum(sd[:-1] + sd[1:], 1e-300)
        law = (ss, sd, np.concatenate([[0.0], np.cumsum(dt)]))
        t = (law[2][:-1, None] + np.linspace(0.0, 1.0, 9)[None, 1:] * dt[:, None]).ravel()
        _, _, qd, qdd = evaluate(path, law, t)
        over = np.maximum(np.abs(qd) / v_true, np.abs(qdd) / a_true).max(axis=1).reshape(-1, 8).max(axis=1)
        bad = np.flatnonzero(over > 1.0)
        if bad.size == 0:
            break
        grid = np.union1d(ss, 0.5 * (ss[bad] + ss[bad + 1]))
    return law


def evaluate(path, law, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """s, q, qd, qdd at times t of a piece (constant path acceleration between gridpoints)."""
    ss, sd, ts = law
    k = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, ss.shape[0] - 2)
    h = t - ts[k]
    u = (sd[k + 1] ** 2 - sd[k] ** 2) / (2.0 * np.maximum(ss[k + 1] - ss[k], 1e-300))
    s = np.minimum(ss[k] + sd[k] * h + 0.5 * u * h * h, ss[-1])
    v = sd[k] + u * h
    d1 = path(s, 1)
    return s, path(s), d1 * v[:, None], path(s, 2) * (v * v)[:, None] + d1 * u[:, None]


def time_at(law, s: FloatArray) -> FloatArray:
    """The times [s] at which a law reaches path parameters s."""
    ss, sd, ts = law
    k = np.clip(np.searchsorted(ss, s, side="right") - 1, 0, ss.shape[0] - 2)
    u = (sd[k + 1] ** 2 - sd[k] ** 2) / (2.0 * np.maximum(ss[k + 1] - ss[k], 1e-300))
    ds = s - ss[k]
    disc = np.sqrt(np.maximum(sd[k] ** 2 + 2.0 * u * ds, 0.0))
    h = np.where(np.abs(u) > 1e-12, (disc - sd[k]) / np.where(np.abs(u) > 1e-12, u, 1.0),
                 ds / np.maximum(sd[k], 1e-300))
    return ts[k] + h
