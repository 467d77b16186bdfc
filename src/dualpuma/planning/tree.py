"""The RRT-Connect fallback's search trees over object poses (:mod:`.rrt`)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import ParameterError

__all__ = ["Tree", "joined"]

FloatArray = npt.NDArray[np.float64]


def _quat(R: FloatArray) -> FloatArray:
    return np.asarray(pin.Quaternion(R).coeffs(), dtype=float)


class Tree:
    """A search tree: per node the object pose, both arms' joints, the parent, the output steps of
    the edge from the parent, the time at the node and its clearance; nearest-node queries in the SE(3) metric
    ``|dp| + w * angle`` over all nodes at once. A node can be pruned with its subtree (:meth:`prune`):
    it stays in the arrays (indices do not change) but is never returned as a nearest node again."""

    def __init__(self, T: FloatArray, qL: FloatArray, qR: FloatArray, t: float, d: float = float("nan")) -> None:
        self.T, self.qL, self.qR = [T], [qL], [qR]
        self.parent, self.n, self.t, self.d = [-1], [0], [t], [d]
        self.pos = np.zeros((64, 3))
        self.quat = np.zeros((64, 4))
        self.pos[0], self.quat[0] = T[:3, 3], _quat(T[:3, :3])
        self.dead = np.zeros(64, dtype=bool)
        self.n_pruned = 0  # nodes pruned so far

    def __len__(self) -> int:
        return len(self.T)

    def add(
        self, T: FloatArray, qL: FloatArray, qR: FloatArray, parent: int, n: int, t: float, d: float = float("nan")
    ) -> int:
        k = len(self.T)
        if k == self.pos.shape[0]:
            self.pos = np.vstack([self.pos, np.zeros_like(self.pos)])
            self.quat = np.vstack([self.quat, np.zeros_like(self.quat)])
            self.dead = np.concatenate([self.dead, np.zeros_like(self.dead)])
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
        """The ``k`` nearest nodes to T in the metric ``|dp| + w * angle`` (pruned ones never):
        [(index, distance)], nearest first."""
        n = len(self.T)
        dots = np.abs(self.quat[:n] @ _quat(T[:3, :3]))
        d = np.linalg.norm(self.pos[:n] - T[:3, 3], axis=1) + w * 2.0 * np.arccos(
            np.minimum(dots, 1.0)
        )
        if self.n_pruned:
            d[self.dead[:n]] = np.inf
            k = min(k, n - self.n_pruned)
        idx = np.argsort(d, kind="stable")[:k]
        return [(int(i), float(d[i])) for i in idx]

    def prune(self, i: int) -> int:
        """Prune node i (not a root) and every node below it; returns how many were newly pruned."""
        if self.parent[i] < 0:
            raise ParameterError(f"node {i} is a root: a root is never pruned")
        n = len(self.T)
        before = int(self.dead[:n].sum())
        self.dead[i] = True
        for j in range(i + 1, n):  # a child is always added after its parent
            if self.dead[self.parent[j]]:
                self.dead[j] = True
        self.n_pruned = int(self.dead[:n].sum())
        return self.n_pruned - before

    def chain(self, i: int) -> list[int]:
        out = []
        while i >= 0:
            out.append(i)
            i = self.parent[i]
        return out

    def chain_joints(self, i: int) -> tuple[FloatArray, FloatArray]:
        """Both arms' joints at node i and at each node on from it to its root: (K, 6) each [rad]."""
        chain = self.chain(i)
        return np.array([self.qL[k] for k in chain]), np.array([self.qR[k] for k in chain])


def joined(ts: Tree, i_s: int, tg: Tree, i_g: int, n_conn: int
           ) -> tuple[list[tuple[FloatArray, int]], list[tuple[Tree, int] | None]]:
    """The path from the start tree's root to node ``i_s``, an edge of ``n_conn`` output steps to
    the goal tree's node ``i_g``, and on to the goal tree's root: its waypoints ``[(pose, output
    steps from the previous)]`` and, for each, the tree edge that leads into it as ``(tree, the
    node at its far end from the root)`` (None for the first waypoint's and the connecting edge)."""
    chain = list(reversed(ts.chain(i_s)))
    way = [(ts.T[k], ts.n[k]) for k in chain]
    edge_of: list[tuple[Tree, int] | None] = [None] + [(ts, k) for k in chain[1:]]
    way.append((tg.T[i_g], n_conn))
    edge_of.append(None)
    for k in tg.chain(i_g)[:-1]:  # the goal tree's edge from node k to its parent
        way.append((tg.T[tg.parent[k]], tg.n[k]))
        edge_of.append((tg, k))
    return way, edge_of
