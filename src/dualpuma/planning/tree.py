"""The RRT-Connect fallback's search trees over object poses (:mod:`.rrt`)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pinocchio as pin

__all__ = ["Tree"]

FloatArray = npt.NDArray[np.float64]


def _quat(R: FloatArray) -> FloatArray:
    return np.asarray(pin.Quaternion(R).coeffs(), dtype=float)


class Tree:
    """A search tree: per node the object pose, both arms' joints, the parent, the output steps of
    the edge from the parent, the time at the node and its clearance; nearest-node queries in the SE(3) metric
    ``|dp| + w * angle`` over all nodes at once."""

    def __init__(self, T: FloatArray, qL: FloatArray, qR: FloatArray, t: float, d: float = float("nan")) -> None:
        self.T, self.qL, self.qR = [T], [qL], [qR]
        self.parent, self.n, self.t, self.d = [-1], [0], [t], [d]
        self.pos = np.zeros((64, 3))
        self.quat = np.zeros((64, 4))
        self.pos[0], self.quat[0] = T[:3, 3], _quat(T[:3, :3])

    def __len__(self) -> int:
        return len(self.T)

    def add(
        self, T: FloatArray, qL: FloatArray, qR: FloatArray, parent: int, n: int, t: float, d: float = float("nan")
    ) -> int:
        k = len(self.T)
        if k == self.pos.shape[0]:
            self.pos = np.vstack([self.pos, np.zeros_like(self.pos)])
            self.quat = np.vstack([self.quat, np.zeros_like(self.quat)])
        self.pos[k], self.quat[k] = T[:3, 3], _quat(T[:3, :3])
        self.T.append(T)
        self.qL.append(qL)
        self.qR.append(qR)
        self.parent.append(parent)
        self.n.append(n)
        self.t.append(t)
        self.d.append(d)
        return k

    def nearest(self, T: FloatArray, w: float, k: int = 1) -> list[tuple[int, float]]:
        """The ``k`` nearest nodes to T in the metric ``|dp| + w * angle``: [(index, distance)], nearest first."""
        n = len(self.T)
        dots = np.abs(self.quat[:n] @ _quat(T[:3, :3]))
        d = np.linalg.norm(self.pos[:n] - T[:3, 3], axis=1) + w * 2.0 * np.arccos(
            np.minimum(dots, 1.0)
        )
        idx = np.argsort(d, kind="stable")[:k]
        return [(int(i), float(d[i])) for i in idx]

    def chain(self, i: int) -> list[int]:
        out = []
        while i >= 0:
            out.append(i)
            i = self.parent[i]
        return out
