"""`World`: Pinocchio + coal structures built once from a :class:`~dualpuma.model.cell.Cell`.

One combined Pinocchio model holds both arms (12 joints: left then right, each prefixed
``left/`` and ``right/``). One ``GeometryModel`` holds a capsule per arm link (from the URDF's
collision cylinders, see urdf/make_puma560.py), the held bar, the obstacles and the floor. Distance
queries run in Pinocchio/coal's C++ (``computeDistances`` returns the arg-min pair); Python only
sets the joint vector and the poses of the bar and of moving obstacles.

Collision pairs (the filtering, documented):

* arm–arm: every left capsule with every right capsule that can come within the cell's margin m:
  dropped only when ``|b_L - b_R| - R_a - R_b > m`` (reach spheres about the bases; ``> 0`` left UR
  pairs 7 mm apart unchecked). ``World.checked_margin``: the largest margin all pairs are checked for
  but those left out by design (rigid, adjacent, grasp-held, constant to the floor); larger: refused.
* arm–obstacle: every capsule of both arms with every obstacle.
* bar–obstacle and bar–floor.
* arm–bar: every capsule except each arm's gripping link (``gripper``) and the link adjacent to it
  (``wrist``): the bar rides on the gripping link, so these proximities are fixed by the grasp (the
  usual adjacent-link exclusion of an SRDF; :meth:`World._held_by_grasp`).
* arm–floor: every capsule whose distance to the floor can change: the pedestal (fixed) and an
  upright column (turning about the vertical) stand on the floor and are left out; a tilted base
  keeps its column (:func:`~dualpuma.model.pairs.constant_to_floor`).
* self-collision inside one arm: the pairs :mod:`dualpuma.model.pairs` derives from the arm's
  geometry and joint limits (for the PUMA 560: forearm, wrist and gripper against the pedestal and
  the column, gripper against the shoulder; adjacent pairs and pairs proven never within 50 mm are
  left out, see :func:`~dualpuma.model.pairs.classify_self_pairs`).

Threads: a World is immutable once built (models, pairs, poses); the Pinocchio and coal *data* its
queries write into are kept per thread, so one World may be queried from several threads at once
(the viewer's loop and its planning worker). Objects derived from a World by other modules (the
clearance kernel, the planner's tables) live in its :class:`WorldCache`, never on the World itself.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

import coal
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..checks import flag, real, validate_joints, validate_pose
from ..errors import CellError, JointError, ParameterError, PoseError
from ..kinematics.arm import Arm
from ..kinematics.dual import SIDES
from ..lie import to_se3
from ..values import value_class
from .cache import WorldCache, history_free_data
from .pairs import constant_to_floor, excluded_bound, reach_radius, self_pairs

__all__ = ["Clearance", "GeometryInfo", "World"]

FloatArray = npt.NDArray[np.float64]


class _Scratch:
    """One thread's Pinocchio data, coal data and joint buffer for a World's queries."""

    __slots__ = ("data", "generation", "geom_data", "q")

    def __init__(self, world: World, generation: int) -> None:
        self.generation = generation
        self.data = world.model.createData()
        self.geom_data = world.new_geom_data()
        self.q = np.zeros(world.model.nq)


@dataclass(frozen=True, slots=True)
class GeometryInfo:
    """Description of one collision geometry of the World.

    Attributes:
        name: e.g. ``"left/forearm"``, ``"bar"``, ``"obstacle/box1"``, ``"floor"``.
        kind: ``"arm"``, ``"bar"``, ``"obstacle"`` or ``"floor"``.
        side: ``"left"``/``"right"`` for arm capsules, else ``""``.
        shape: ``"capsule"``, ``"box"``, ``"sphere"`` or ``"halfspace"``.
        size: capsule (radius, length), box (3 full extents), sphere (radius,), halfspace ().
    """

    name: str
    kind: str
    side: str
    shape: str
    size: tuple[float, ...]


@value_class
@dataclass(frozen=True, slots=True)
class Clearance:
    """Result of :meth:`World.clearance`.

    Attributes:
        distance: minimum signed distance over all checked pairs [m] (negative = penetration depth).
        pair: names of the two geometries achieving it.
        witness: nearest points on each (world frame) [m], shape (2, 3).
        pair_distances: per-pair distances [m] in :attr:`World.pair_names` order, if requested.
    """

    distance: float
    pair: tuple[str, str]
    witness: FloatArray
    pair_distances: FloatArray | None = field(default=None)

    def permitted(self, margin: float) -> bool:
        """True if the clearance is at least ``margin`` [m]."""
        return self.distance >= margin


def _coal_shape(shape: str, size: tuple[float, ...]) -> coal.ShapeBase:
    if shape == "box":
        return coal.Box(*size)
    if shape == "sphere":
        return coal.Sphere(size[0])
    if shape == "capsule":
        return coal.Capsule(size[0], size[1])
    raise ParameterError(f"unknown shape {shape!r}")


def _shape_of(obj) -> tuple[str, tuple[float, ...]]:
    """(shape, size) of a cell Bar/Obstacle: box size = full extents, sphere (r,), capsule (r, L)."""
    shape = str(obj.shape)
    size = tuple(float(v) for v in np.atleast_1d(obj.size))
    if shape == "sphere":
        size = size[:1]
    elif shape == "capsule":
        size = size[:2]
    return shape, size


class World:
    """Both arms, the bar, the obstacles and the floor of a Cell, ready for queries.

    Build once per cell (milliseconds) and reuse. Safe to query from several threads at once: the
    models are read-only and each thread writes into its own Pinocchio/coal data
    (:attr:`data`, :attr:`geom_data` are the calling thread's).

    Args:
        cell: the work cell.

    Raises:
        CellError: ``cell`` is not a Cell.
    """

    def __init__(self, cell) -> None:
        from .cell import Cell

        if not isinstance(cell, Cell):
            raise CellError(f"cell: expected a dualpuma Cell, got {type(cell).__name__}")
        self.cell = cell
        self.cache = WorldCache()
        self._local = threading.local()
        self._generation = 0
        self.arms: dict[str, Arm] = {s: Arm.load(getattr(cell, s).robot) for s in SIDES}
        self.T_world_base: dict[str, FloatArray] = {s: np.asarray(getattr(cell, s).T_world_base, float) for s in SIDES}
        self.T_base_inv: dict[str, FloatArray] = {s: np.linalg.inv(self.T_world_base[s]) for s in SIDES}
        self.T_object_hand: dict[str, FloatArray] = {
            s: np.asarray(getattr(cell, f"grasp_{s}").T_object_hand, float) for s in SIDES
        }
        self.model = pin.Model()
        self._joint_ids: dict[str, list[int]] = {}
        self.hand_frame_ids: dict[str, int] = {}
        for s in SIDES:
            self._append_arm(s)
        self._build_geometry()

    # ------------------------------------------------------------------ per-thread data
    def _scratch(self) -> _Scratch:
        try:
            sc = self._local.scratch
            if sc.generation == self._generation:
                return sc
        except AttributeError:
            pass
        sc = self._local.scratch = _Scratch(self, self._generation)
        return sc

    @property
    def data(self) -> pin.Data:
        """The calling thread's Pinocchio data of :attr:`model` (scratch of the last query)."""
        return self._scratch().data

    @property
    def geom_data(self) -> pin.GeometryData:
        """The calling thread's coal data of :attr:`geom_model` (placements and results of the
        last query)."""
        return self._scratch().geom_data

    def geometry(self, name: str) -> GeometryInfo:
        """The :class:`GeometryInfo` named ``name`` (e.g. ``"left/forearm"``).

        Raises:
            ParameterError: no such geometry.
        """
        i = self._geom_index.get(name) if isinstance(name, str) else None
        if i is None:
            raise ParameterError(f"unknown geometry {name!r}; geometries: {sorted(self._geom_index)}")
        return self.geoms[i]

    # ------------------------------------------------------------------ construction
    def _append_arm(self, side: str) -> None:
        src = self.arms[side].model
        base = to_se3(self.T_world_base[side])
        ids: list[int] = []
        for j in range(1, src.njoints):
            parent = 0 if src.parents[j] == 0 else ids[src.parents[j] - 1]
            placement = base * src.jointPlacements[j] if src.parents[j] == 0 else src.jointPlacements[j]
            jid = self.model.addJoint(parent, src.joints[j], placement, f"{side}/{src.names[j]}")
            self.model.appendBodyToJoint(jid, src.inertias[j], pin.SE3.Identity())
            ids.append(jid)
        self._joint_ids[side] = ids
        hand = self.arms[side].hand_frame_id
        fr = src.frames[hand]
        self.hand_frame_ids[side] = self.model.addFrame(
            pin.Frame(f"{side}/hand", ids[fr.parentJoint - 1], fr.placement, pin.FrameType.OP_FRAME)
        )

    def _add(self, info: GeometryInfo, joint: int, placement: pin.SE3, shape: coal.CollisionGeometry) -> int:
        gid = self.geom_model.addGeometryObject(pin.GeometryObject(info.name, joint, placement, shape))
        self.geoms.append(info)
        return gid

    def _build_geometry(self) -> None:
        self.geom_model = pin.GeometryModel()
        self.geoms: list[GeometryInfo] = []
        arm_ids: dict[str, list[tuple[int, float, bool]]] = {}
        for s in SIDES:
            arm = self.arms[s]
            arm_ids[s] = []
            offsets = [0.0] + [float(np.linalg.norm(M.translation)) for M in arm.model.jointPlacements[1:]]
            for c in arm.capsules:
                if c.joint == 0:
                    joint, placement = 0, to_se3(self.T_world_base[s] @ c.placement)
                else:
                    joint, placement = self._joint_ids[s][c.joint - 1], to_se3(c.placement)
                info = GeometryInfo(f"{s}/{c.name}", "arm", s, "capsule", (c.radius, c.length))
                gid = self._add(info, joint, placement, coal.Capsule(c.radius, c.length))
                reach = reach_radius(arm.model, offsets, c.joint, c.placement, c.length, c.radius)
                arm_ids[s].append((gid, reach, c.joint >= 5 and self._held_by_grasp(arm, c)))
        bar = self.cell.bar
        shape, size = _shape_of(bar)
        self.T_object_bar = np.asarray(bar.T_object_bar, float)
        # The bar rides on the left hand's joint (closed chain): T_hand_bar = inv(T_object_hand) T_object_bar.
        # An explicit T_world_object overrides its placement for that query.
        hand = self.model.frames[self.hand_frame_ids["left"]]
        bar_in_joint = hand.placement * to_se3(np.linalg.inv(self.T_object_hand["left"]) @ self.T_object_bar)
        self.bar_id = self._add(
            GeometryInfo("bar", "bar", "", shape, size), hand.parentJoint, bar_in_joint, _coal_shape(shape, size)
        )
        self.obstacle_ids: list[int] = []
        for ob in self.cell.obstacles:
            shape, size = _shape_of(ob)
            gid = self._add(
                GeometryInfo(f"obstacle/{ob.name}", "obstacle", "", shape, size),
                0,
                to_se3(np.asarray(ob.pose_at(0.0), float)),
                _coal_shape(shape, size),
            )
            self.obstacle_ids.append(gid)
        self.moving = [
            (gid, ob) for gid, ob in zip(self.obstacle_ids, self.cell.obstacles) if np.any(np.asarray(ob.velocity) != 0.0)
        ]
        floor_z = float(self.cell.floor_z)
        self.floor_id = self._add(
            GeometryInfo("floor", "floor", "", "halfspace", ()), 0, pin.SE3.Identity(), coal.Halfspace(np.array([0.0, 0.0, 1.0]), floor_z)
        )
        pairs: list[tuple[int, int]] = []
        d_bases, m = float(np.linalg.norm(self.T_world_base["left"][:3, 3] - self.T_world_base["right"][:3, 3])), float(self.cell.safety_margin)
        gaps = [(ga, gb, d_bases - ra - rb) for ga, ra, _ in arm_ids["left"] for gb, rb, _ in arm_ids["right"]]
        pairs += [(ga, gb) for ga, gb, gap in gaps if gap <= m]  # arm-arm: all that can come within the margin
        far = [math.inf] + [gap for _, _, gap in gaps if gap > m]  # the others: farther apart than this everywhere [m]
        index = {g.name: i for i, g in enumerate(self.geoms)}
        for s in SIDES:  # self-collision: the derived list of model/pairs.py
            pairs += [(index[f"{s}/{a}"], index[f"{s}/{b}"]) for a, b in self_pairs(self.arms[s], m)]
        #: the largest margin [m] every pair is checked for: pairs proven farther apart are left out (and,
        #: by design, rigid, adjacent, grasp-held and constant-to-floor pairs at any margin)
        self.checked_margin = min(far + [excluded_bound(self.arms[s], m) for s in SIDES])
        up = np.array([0.0, 0.0, 1.0])
        for s in SIDES:
            for gid, _, is_grip in arm_ids[s]:
                pairs += [(gid, o) for o in self.obstacle_ids]
                if not is_grip:
                    pairs.append((gid, self.bar_id))
                if not constant_to_floor(self.model, self.geom_model.geometryObjects[gid], up):
                    pairs.append((gid, self.floor_id))
        pairs += [(self.bar_id, o) for o in self.obstacle_ids]
        pairs.append((self.bar_id, self.floor_id))
        for a, b in pairs:
            self.geom_model.addCollisionPair(pin.CollisionPair(a, b))
        self.pair_ids: list[tuple[int, int]] = pairs
        self.pair_names: tuple[tuple[str, str], ...] = tuple((self.geoms[a].name, self.geoms[b].name) for a, b in pairs)
        self._geom_index = {g.name: i for i, g in enumerate(self.geoms)}
        # every pair active, coal's warm start off: copied for each new data (cheaper than a build)
        self._geom_template, self.history_free = history_free_data(self.geom_model)

    def new_geom_data(self) -> pin.GeometryData:
        """A new coal data of :attr:`geom_model` for the caller's own queries: every pair active and
        coal's warm start off (:func:`~dualpuma.model.cache.history_free_data`), no query run yet."""
        return self._geom_template.copy()

    @staticmethod
    def _held_by_grasp(arm: Arm, c) -> bool:
        """True for capsules the grasp makes adjacent to the bar: the gripping link (last joint)
        and the link before it (the PUMA's wrist). Like an SRDF's adjacent-link exclusions, their
        proximity to the held bar is fixed by design (the bar rides on the gripping link)."""
        last = arm.model.njoints - 1
        return c.joint >= last - 1

    def reset(self) -> None:
        """Forget every cached query state, so that a sequence of queries gives bit-identical
        results whatever ran before (the planners call it for determinism). With a coal that lets
        the warm start be turned off (:attr:`history_free`, today's) there is none and this is a
        no-op; otherwise every thread's data and per-thread cache entries are renewed."""
        if not self.history_free:
            self._generation += 1
            self.cache.renew()

    # ------------------------------------------------------------------ kinematics
    def q_full(self, q_left: npt.ArrayLike, q_right: npt.ArrayLike) -> FloatArray:
        """Both arms' joints as the combined model's q (12,) [rad] (the calling thread's buffer).

        Raises:
            JointError: either is not one finite joint vector of shape (6,).
        """
        return self._joints(self._scratch().q, q_left, q_right)

    @staticmethod
    def _joints(q: FloatArray, q_left, q_right) -> FloatArray:
        a = validate_joints(q_left, name="q_left")
        b = validate_joints(q_right, name="q_right")
        if a.shape != (6,) or b.shape != (6,):
            raise JointError(f"q_left, q_right: expected one joint vector of shape (6,) each, got {a.shape}, {b.shape}; "
                             "for many configurations use dualpuma.collision.clearance_batch")
        q[:6] = a
        q[6:] = b
        return q

    def hand_poses(self, q_left: npt.ArrayLike, q_right: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """World poses (4, 4) of both hand frames (the PUMA's wrist centre) [m].

        Raises:
            JointError: malformed joints.
        """
        sc = self._scratch()
        data = sc.data
        pin.forwardKinematics(self.model, data, self._joints(sc.q, q_left, q_right))
        return tuple(  # type: ignore[return-value]
            pin.updateFramePlacement(self.model, data, self.hand_frame_ids[s]).homogeneous for s in SIDES
        )

    def object_from_left(self, q_left: npt.ArrayLike) -> FloatArray:
        """``T_world_object`` implied by the left hand's grasp (closed chain, eq. 5.3)."""
        T_bh = self.arms["left"].fk(q_left)
        return self.T_world_base["left"] @ T_bh @ np.linalg.inv(self.T_object_hand["left"])

    # ------------------------------------------------------------------ clearance
    def _update(self, q_left, q_right, T_world_object, t: float) -> pin.GeometryData:
        """Place every geometry for one configuration; returns the thread's coal data."""
        sc = self._scratch()
        gd = sc.geom_data
        pin.updateGeometryPlacements(self.model, sc.data, self.geom_model, gd, self._joints(sc.q, q_left, q_right))
        if T_world_object is not None:
            T_wo = validate_pose(T_world_object, name="T_world_object")
            if T_wo.shape != (4, 4):
                raise PoseError(f"T_world_object: expected one pose (4, 4), got {T_wo.shape}")
            gd.oMg[self.bar_id] = to_se3(T_wo @ self.T_object_bar)
        for gid, ob in self.moving:
            gd.oMg[gid] = to_se3(ob.pose_at(t))
        return gd

    def clearance(
        self,
        q_left: npt.ArrayLike,
        q_right: npt.ArrayLike,
        T_world_object: npt.ArrayLike | None = None,
        t: float = 0.0,
        *,
        per_pair: bool = False,
    ) -> Clearance:
        """Minimum signed distance between all checked pairs at one configuration.

        Args:
            q_left, q_right: joints [rad], shape (6,).
            T_world_object: bar frame (4, 4) [m]; default: implied by the left grasp.
            t: time [s] for moving obstacles.
            per_pair: also return every pair's distance.

        Returns:
            :class:`Clearance` (negative distance = penetration depth).

        Raises:
            JointError, PoseError: malformed input.
        """
        t = real(t, "t", unit="s")
        per_pair = flag(per_pair, "per_pair")
        gd = self._update(q_left, q_right, T_world_object, t)
        idx = pin.computeDistances(self.geom_model, gd)
        res = gd.distanceResults[idx]
        a, b = self.pair_names[idx]
        dists = None
        if per_pair:
            dists = np.array([r.min_distance for r in gd.distanceResults])
            dists.setflags(write=False)
        w = np.array([res.getNearestPoint1(), res.getNearestPoint2()])
        w.setflags(write=False)
        return Clearance(float(res.min_distance), (a, b), w, dists)

    def min_distance(self, q_left, q_right, T_world_object=None, t: float = 0.0) -> tuple[float, int]:
        """Fast path: (minimum signed distance [m], pair index into :attr:`pair_names`).

        Raises:
            JointError, PoseError, ParameterError: malformed input.
        """
        gd = self._update(q_left, q_right, T_world_object, real(t, "t", unit="s"))
        idx = pin.computeDistances(self.geom_model, gd)
        return gd.distanceResults[idx].min_distance, idx

    def permitted(self, q_left, q_right, T_world_object=None, t: float = 0.0, margin: float | None = None) -> bool:
        """True if every checked pair is at least ``margin`` apart [m] (default: the cell's margin).

        Raises:
            JointError, PoseError, ParameterError: malformed input; a margin above :attr:`checked_margin`.
        """
        m = float(self.cell.safety_margin if margin is None else self.covered(real(margin, "margin", unit="m")))
        return self.min_distance(q_left, q_right, T_world_object, t)[0] >= m

    def covered(self, margin: float, name: str = "margin") -> float:
        """``margin`` [m] if every pair that can come within it is checked (:attr:`checked_margin`),
        else ParameterError (pairs proven farther apart are left out; a cell with that margin checks them)."""
        if float(margin) > self.checked_margin:
            raise ParameterError(f"{name}: {float(margin):g} m is more than the {self.checked_margin:.4f} m the pairs of "
                                 f"this cell are checked for; give the cell a safety_margin of at least {float(margin):g} m")
        return float(margin)

    def segments(self, q_left: npt.ArrayLike, q_right: npt.ArrayLike) -> dict[str, tuple[FloatArray, FloatArray, float]]:
        """World segment end points and radius of every arm capsule: name -> (p0, p1, radius)."""
        gd = self._update(q_left, q_right, None, 0.0)
        out = {}
        for gid, info in enumerate(self.geoms):
            if info.shape != "capsule" or info.kind != "arm":
                continue
            M = gd.oMg[gid].homogeneous
            half = 0.5 * info.size[1] * M[:3, 2]
            out[info.name] = (M[:3, 3] - half, M[:3, 3] + half, info.size[0])
        return out
