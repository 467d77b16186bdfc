"""An independent clearance reference for whole motions (used by the certified-motion property
test): Pinocchio FK of each arm's own model, capsules built here from the arm's URDF capsules, the
bar carried by the left hand, obstacles at the query time, and coal's distance on fresh shapes for
every pair that matters — not the World's geometry model, pair list, kernel or batched queries.

Pairs: every left capsule with every right capsule; every capsule, and the bar, with every obstacle;
the bar and every capsule whose height can change with the floor (all but those fixed to the base
and a round one on the vertical first joint's axis); every capsule but those of the last two joints
(the gripping link and the one before it: the held bar rides on them) with the bar; and inside each
arm every capsule pair that model/pairs.py did not find adjacent or rigid (its ``checked`` and
``never`` pairs: the proven-far ones cost nothing here)."""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin

from dualpuma.kinematics import Arm
from dualpuma.model.pairs import verdicts

_FAR = 0.05  # pairs whose bounding spheres are farther apart than margin + this are skipped [m]


def _tf(T):
    return coal.Transform3s(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))


class MotionReference:
    """Minimum clearance of configurations of a cell (see the module docstring)."""

    def __init__(self, cell) -> None:
        self.cell = cell
        self.arms = {s: Arm.load(getattr(cell, s).robot) for s in ("left", "right")}
        self.data = {s: a.model.createData() for s, a in self.arms.items()}
        self.base = {s: np.asarray(getattr(cell, s).T_world_base, float) for s in ("left", "right")}
        self.inv_grasp_left = np.linalg.inv(np.asarray(cell.grasp_left.T_object_hand, float))
        self.caps = {s: [(c, coal.Capsule(c.radius, c.length), c.radius + 0.5 * c.length) for c in a.capsules]
                     for s, a in self.arms.items()}
        bar = cell.bar
        self.bar_shape, self.bar_r = self._shape(bar.shape, np.atleast_1d(bar.size))
        self.obstacles = [(ob, *self._shape(ob.shape, np.atleast_1d(ob.size))) for ob in cell.obstacles]
        self.self_pairs = {s: [(v.a, v.b) for v in verdicts(a) if v.kind in ("checked", "never")]
                           for s, a in self.arms.items()}
        # by joint index (any arm): the last two joints hold the bar; the floor never nears what is
        # fixed to the base or turns on a vertical first axis (with an upright base)
        self.holding, self.floor_free = set(), set()
        for s, a in self.arms.items():
            last = a.model.njoints - 1
            up = np.allclose(self.base[s][:3, 2], [0.0, 0.0, 1.0], atol=1e-12)
            M1 = a.model.jointPlacements[1].homogeneous
            for c in a.capsules:
                if c.joint >= last - 1:
                    self.holding.add(f"{s}/{c.name}")
                on_axis1 = (c.joint == 1 and np.linalg.norm(np.cross(c.placement[:3, 2], [0, 0, 1])) < 1e-9
                            and np.linalg.norm(c.placement[:2, 3]) < 1e-9 and np.allclose(M1[:3, 2], [0, 0, 1]))
                if up and (c.joint == 0 or on_axis1):
                    self.floor_free.add(f"{s}/{c.name}")

    def bar_path(self, A, B, q0, n: int):
        """Both arms' joints (n, 12) (left then right) holding the bar at n equal steps along its
        path from pose A to pose B (:func:`geodesic_poses`), each arm tracked with Pinocchio alone
        (:func:`track_hand`) from q0 (12,) at A."""
        poses = geodesic_poses(A, B, np.arange(1, n + 1) / n)
        out = []
        for k, s in enumerate(("left", "right")):
            to_hand = np.linalg.inv(self.base[s]), np.asarray(getattr(self.cell, f"grasp_{s}").T_object_hand, float)
            out.append(track_hand(self.arms[s], [to_hand[0] @ T @ to_hand[1] for T in poses],
                                  np.asarray(q0[6 * k : 6 * k + 6], float)))
        return np.hstack(out)

    def plan_path_min(self, p, margin: float, fine: int = 20, end_tol: float = 1e-6):
        """The lowest clearance of a plan ``p`` along the bar's path between its rows, the arms
        holding it (:meth:`bar_path`, ``fine`` poses per step, from each row's joints), at the times
        interpolated between the rows' times, its first row included: ``(distance [m], pair, step,
        s)`` (exact where below ``margin + 0.05``). AssertionError where the tracking does not end
        within ``end_tol`` [rad] of the next row's joints (the closed chain does not follow the plan
        there)."""
        Q = np.hstack([p.q_left, p.q_right])
        d, pair = self.clearance(Q[0, :6], Q[0, 6:], float(p.t[0]), margin)
        worst = (d, pair, 0, 0.0)
        for i in range(Q.shape[0] - 1):
            path = self.bar_path(p.T_world_object[i], p.T_world_object[i + 1], Q[i], fine)
            assert np.abs(path[-1] - Q[i + 1]).max() < end_tol, f"step {i}: the tracking ends elsewhere"
            for k, q in enumerate(path, start=1):
                d, pair = self.clearance(q[:6], q[6:], float(p.t[i] + k / fine * (p.t[i + 1] - p.t[i])), margin)
                if d < worst[0]:
                    worst = (d, pair, i, k / fine)
        return worst

    @staticmethod
    def _shape(kind: str, size):
        if kind == "box":
            return coal.Box(*map(float, size)), 0.5 * float(np.linalg.norm(size))
        if kind == "sphere":
            return coal.Sphere(float(size[0])), float(size[0])
        return coal.Capsule(float(size[0]), float(size[1])), float(size[0]) + 0.5 * float(size[1])

    def clearance(self, q_left, q_right, t: float, margin: float) -> tuple[float, str]:
        """(minimum distance over the pairs, its pair) — exact where it is below ``margin + 0.05``,
        else a lower bound above that."""
        world = {}
        for s, q in (("left", q_left), ("right", q_right)):
            arm, data = self.arms[s], self.data[s]
            pin.forwardKinematics(arm.model, data, np.asarray(q, float))
            pin.updateFramePlacements(arm.model, data)
            for c, shape, r in self.caps[s]:
                Tj = np.eye(4) if c.joint == 0 else data.oMi[c.joint].homogeneous
                world[f"{s}/{c.name}"] = (self.base[s] @ Tj @ c.placement, shape, r)
            if s == "left":
                hand = self.base[s] @ data.oMf[arm.hand_frame_id].homogeneous
                T_bar = hand @ self.inv_grasp_left @ np.asarray(self.cell.bar.T_object_bar, float)
        world["bar"] = (T_bar, self.bar_shape, self.bar_r)
        for ob, shape, r in self.obstacles:
            world[f"obstacle/{ob.name}"] = (np.asarray(ob.pose_at(t), float), shape, r)
        best = (np.inf, "")
        names = list(world)
        pairs = []
        left = [n for n in names if n.startswith("left/")]
        right = [n for n in names if n.startswith("right/")]
        obst = [n for n in names if n.startswith("obstacle/")]
        pairs += [(a, b) for a in left for b in right]
        pairs += [(a, o) for a in left + right + ["bar"] for o in obst]
        pairs += [(a, "bar") for a in left + right if a not in self.holding]
        for s in ("left", "right"):
            pairs += [(f"{s}/{a}", f"{s}/{b}") for a, b in self.self_pairs[s]]
        for a, b in pairs:
            Ta, sa, ra = world[a]
            Tb, sb, rb = world[b]
            lb = float(np.linalg.norm(Ta[:3, 3] - Tb[:3, 3])) - ra - rb
            if lb > margin + _FAR and lb > best[0]:
                continue
            d = coal.distance(sa, _tf(Ta), sb, _tf(Tb), coal.DistanceRequest(), coal.DistanceResult())
            if d < best[0]:
                best = (d, f"{a} – {b}")
        z0 = float(self.cell.floor_z)
        for n in left + right:  # capsules whose height can change, with the floor
            if n in self.floor_free:
                continue
            T, shape, _ = world[n]
            half = 0.5 * shape.halfLength * 2.0 * T[:3, 2]
            d = min(T[2, 3] - half[2], T[2, 3] + half[2]) - shape.radius - z0
            if d < best[0]:
                best = (d, f"{n} – floor")
        T, shape, _ = world["bar"]
        if isinstance(shape, coal.Box):
            corners = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T * shape.halfSide
            d = float((corners @ T[:3, :3].T + T[:3, 3])[:, 2].min()) - z0
        elif isinstance(shape, coal.Capsule):
            d = float(T[2, 3] - abs(shape.halfLength * T[2, 2])) - shape.radius - z0
        else:
            d = float(T[2, 3]) - z0 - self.bar_r
        if d < best[0]:
            best = (d, "bar – floor")
        return best


def track_hand(arm, T_targets, q):
    """Differential IK with Pinocchio alone: Gauss-Newton from the previous joints at each target
    hand pose (in the arm's base frame), the continuous motion that holds the hand on its path.
    Returns the joints at every target (len(T_targets), 6)."""
    model, fid = arm.model, arm.frame_id(None)
    data = model.createData()
    out = []
    for T in T_targets:
        for _ in range(50):
            pin.forwardKinematics(model, data, q)
            err = pin.log6(pin.updateFramePlacement(model, data, fid).actInv(pin.SE3(T))).vector
            if np.linalg.norm(err) < 1e-13:
                break
            J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)
            q = q + np.linalg.lstsq(J, err, rcond=None)[0]
        out.append(q)
    return np.array(out).reshape(-1, 6)


def geodesic_poses(A, B, fractions):
    """Poses (K, 4, 4) at ``fractions`` (K,) of the way from pose A to pose B along the bar's path:
    translation linear, rotation about one fixed axis (Pinocchio's exp3 and log3)."""
    w = pin.log3(A[:3, :3].T @ B[:3, :3])
    out = np.tile(np.eye(4), (len(fractions), 1, 1))
    for T, f in zip(out, fractions):
        T[:3, :3] = A[:3, :3] @ pin.exp3(f * w)
        T[:3, 3] = A[:3, 3] + f * (B[:3, 3] - A[:3, 3])
    return out
