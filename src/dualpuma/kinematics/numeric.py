"""Numeric IK for any 6-DOF arm: damped least squares on the SE(3) error, with restarts.

For arms without a closed form. Each start runs Gauss-Newton steps damped by ``damping`` on the
log of the pose error (``pin.log6``, Jacobian ``Jlog6 @ J``), joints clamped into their limits;
the first start is ``q_near`` (branch continuity: the solution nearest the previous joints comes
first), then zeros, then random joints from a fixed seed (deterministic).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from .ik import IKResult, IKStatus

__all__ = ["solve_dls"]

FloatArray = npt.NDArray[np.float64]


def solve_dls(
    model: pin.Model,
    data: pin.Data,
    frame_id: int,
    T: FloatArray,
    q_near: FloatArray | None,
    limits: FloatArray,
    *,
    tol: float = 1e-10,
    max_iter: int = 200,
    restarts: int = 30,
    damping: float = 1e-6,
    seed: int = 0,
) -> IKResult:
    """IK of frame ``frame_id`` to pose ``T`` (4, 4) [m] by damped least squares (trusted input).

    Args:
        model, data: the arm's Pinocchio model and a data to write into.
        q_near: first start [rad] (6,), or None.
        limits: (6, 2) joint limits [rad].
        tol: convergence threshold on |log6 error| (metres and radians mixed).

    Returns:
        :class:`IKResult` with ``branch = -1`` (no branch structure); ``unreachable`` when no start
        converges within the limits.
    """
    target = pin.SE3(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))
    lo, hi = limits[:, 0], limits[:, 1]
    rng = np.random.default_rng(seed)
    starts = [np.clip(q_near, lo, hi)] if q_near is not None else []
    starts.append(np.clip(np.zeros(6), lo, hi))
    starts += [rng.uniform(np.maximum(lo, -math.pi), np.minimum(hi, math.pi)) for _ in range(restarts)]
    best_err, best_q = math.inf, None
    eye = np.eye(6)
    nerr = math.inf
    for q0 in starts:
        q = q0.copy()
        for _ in range(max_iter):
            pin.forwardKinematics(model, data, q)
            M = pin.updateFramePlacement(model, data, frame_id)
            err = pin.log6(M.actInv(target)).vector
            nerr = float(np.linalg.norm(err))
            if nerr < tol:
                break
            J = pin.computeFrameJacobian(model, data, q, frame_id, pin.LOCAL)
            Jl = pin.Jlog6(M.actInv(target)) @ J
            dq = Jl.T @ np.linalg.solve(Jl @ Jl.T + damping * eye, err)
            q = np.clip(q + dq, lo, hi)
        if nerr < best_err:
            best_err, best_q = nerr, q
        if nerr < tol:
            break
    if best_q is None or best_err >= tol * 10:
        return IKResult(None, -1, IKStatus.UNREACHABLE,
                        f"numeric IK did not converge within limits (best residual {best_err:.2e} after "
                        f"{len(starts)} starts)")
    best_q.setflags(write=False)
    return IKResult(best_q, -1, IKStatus.OK)
