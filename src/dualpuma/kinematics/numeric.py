"""Numeric IK for any 6-DOF arm: damped least squares on the SE(3) error, with restarts.

For arms without a closed form. Each start runs Levenberg-Marquardt-like steps on the log of the
pose error (``pin.log6``, Jacobian ``Jlog6 @ J``), damping ``min(damping, |e|^2)`` (quadratic
convergence near a solution, robust far from it), joints clamped into their limits. The first
start is ``q_near`` (branch continuity: the solution nearest the previous joints comes first),
then the middle of the joint ranges, then random joints from a fixed seed drawn once per solver
(deterministic).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import RobotError
from .ik import IKResult, IKStatus

__all__ = ["DLSSolver"]

FloatArray = npt.NDArray[np.float64]


class DLSSolver:
    """Damped least squares IK of one frame of one model (read-only; the caller passes the data).

    Args:
        model: the arm's Pinocchio model.
        frame_id: the frame to place.
        limits: (6, 2) joint limits [rad] the restarts are drawn in.
        restarts: random starts after ``q_near`` and the range middle.
        seed: their generator's seed.

    Raises:
        RobotError: ``limits`` not finite numbers of shape (6, 2) with lower <= upper (the message
            names the joint; :func:`.urdf.read_arm` refuses such a URDF before).
    """

    def __init__(self, model: pin.Model, frame_id: int, limits: FloatArray, *, restarts: int = 30,
                 seed: int = 0) -> None:
        self.model, self.frame_id = model, frame_id
        limits = np.asarray(limits, dtype=float)
        if limits.shape != (6, 2):
            raise RobotError(f"limits: expected shape (6, 2) [rad], got {limits.shape}")
        for k, (lower, upper) in enumerate(limits):
            if not (math.isfinite(lower) and math.isfinite(upper) and lower <= upper):
                name = repr(model.names[k + 1]) if model.njoints == 7 else str(k + 1)
                raise RobotError(f"joint {name}: its limits must be finite with the lower not exceeding the upper, "
                                 f"got lower {math.degrees(lower):.1f} deg, upper {math.degrees(upper):.1f} deg")
        # one turn of each joint's range is enough: q and q + 2 pi place the arm alike
        lo = np.maximum(limits[:, 0], np.minimum(-math.pi, limits[:, 1] - 2.0 * math.pi))
        hi = np.minimum(limits[:, 1], lo + 2.0 * math.pi)
        self.starts = np.vstack([0.5 * (lo + hi), np.random.default_rng(seed).uniform(lo, hi, (restarts, 6))])
        self.starts.setflags(write=False)

    def solve(self, data: pin.Data, T: FloatArray, q_near: FloatArray | None, limits: FloatArray, *,
              tol: float = 1e-10, max_iter: int = 60, damping: float = 1e-6) -> IKResult:
        """IK to pose ``T`` (4, 4) [m] (trusted input); ``q_near`` (6,) [rad] or None."""
        model, fid = self.model, self.frame_id
        target = pin.SE3(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))
        lo, hi = limits[:, 0], limits[:, 1]
        starts = self.starts if q_near is None else np.vstack([np.clip(q_near, lo, hi), self.starts])
        best_err, best_q = math.inf, None
        eye, tol2 = np.eye(6), tol * tol
        for q0 in starts:
            q = np.clip(q0, lo, hi)
            e2 = math.inf
            for _ in range(max_iter):
                pin.forwardKinematics(model, data, q)
                err_pose = pin.updateFramePlacement(model, data, fid).actInv(target)
                err = pin.log6(err_pose).vector
                e2 = float(err @ err)
                if e2 < tol2:
                    break
                J = pin.Jlog6(err_pose) @ pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)
                lam = min(damping, e2)
                q = np.clip(q + J.T @ np.linalg.solve(J @ J.T + lam * eye, err), lo, hi)
            if e2 < best_err:
                best_err, best_q = e2, q
            if e2 < tol2:
                break
        if best_q is None or best_err >= 100.0 * tol2:
            return IKResult(None, -1, IKStatus.NOT_FOUND,
                            f"numeric IK found no solution within the joint limits (best residual "
                            f"{math.sqrt(best_err):.2e} after {len(starts)} starts); the pose may still be "
                            "reachable from other joints (Arm.ik's q_near)")
        best_q = best_q.copy()
        best_q.setflags(write=False)
        return IKResult(best_q, -1, IKStatus.OK)
