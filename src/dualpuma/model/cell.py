"""`Cell`: the frozen description of a work cell (two arm mounts, bar, grasps, obstacles, floor).

The seed's layout (``Cell.default()``) in SI: seed screen units map to world metres by
``p_world = 0.005 * (x, y, z - 5)`` (0.2 units per mm; the floor of the seed's drawing at z = 5 units
becomes z = 0). Shoulders at (1.0, 0, 0.6604) and (2.0, 0, 0.6604); start joints = the seed's FLAG2
values; grasps derived from them as the seed does (eq. 5.5).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from ..checks import choice, frozen_array, instance, points, real, text, validate_pose
from ..errors import CellError, RobotError
from ..kinematics.arm import KNOWN_ROBOTS, Arm, RobotSpec
from ..kinematics.dual import CLOSURE_LEVER, GRASP_TOL, pose_error
from ..kinematics.puma import fk
from ..values import value_class

__all__ = ["MAX_EXTENT", "MAX_GRASP_GAP", "MAX_MARGIN", "MAX_NAME", "MAX_OBSTACLES", "MOUNT_YAW", "SHAPES", "SIZE_COUNTS", "ArmMount", "Bar", "Cell", "Grasp", "Obstacle", "check_margin", "seed_units_to_world"]

FloatArray = npt.NDArray[np.float64]
SHAPES = ("box", "sphere", "capsule")  #: obstacle and bar shapes
#: how many sizes each shape takes [m]: a box its 3 full extents, a sphere its radius, a capsule its radius and length
SIZE_COUNTS = {"box": 3, "sphere": 1, "capsule": 2}


MAX_NAME = 200  #: longest name of a cell, an arm or an obstacle [characters]
MAX_EXTENT = 1000.0  #: largest |floor_z|, size, |coordinate| of a pose and speed accepted [m, m/s]
#: farthest a hand frame may be from the bar's surface [m]: farther, it does not hold the bar (the
#: shipped cells: 0.095 m, the PUMA's wrist centre above the bar; a gripper bridges that gap)
MAX_GRASP_GAP = 0.5
#: the most obstacles a cell may have: a World of 1,000 builds in about a second, one of 2,000 took
#: 22 s (Pinocchio's geometry model grows superlinearly), one of 10,000 (the former limit) did not
#: finish in 15 minutes
MAX_OBSTACLES = 1000
#: largest safety margin [m]: a PUMA reaches 0.86 m, so a margin of a metre leaves nothing to plan;
#: one beyond it was most likely written in millimetres
MAX_MARGIN = 1.0


def check_margin(value: object, name: str, error: type[Exception] = CellError) -> float:
    """A safety margin [m] in [0, :data:`MAX_MARGIN`] as a float; one above it (most likely written in
    millimetres) gets a message that says the margin is in metres.

    Raises:
        error: not a finite real number in that range.
    """
    try:
        v = float(value) if isinstance(value, numbers.Real) and not isinstance(value, bool) else math.nan
    except OverflowError:  # an int beyond the float range: real() says so
        v = math.inf
    if MAX_MARGIN < v < math.inf:
        raise error(f"{name}: {v:g} m is more than {MAX_MARGIN:g} m; the margin is in metres (20 mm is 0.02)")
    return real(value, name, lo=0.0, hi=MAX_MARGIN, unit="m", error=error)


def _is_inf(v: object) -> bool:
    return isinstance(v, (float, np.floating)) and v == math.inf


MOUNT_YAW = -math.pi / 2  #: base yaw of Cell.default()'s arms (J1 range centred on the work area) [rad]


def seed_units_to_world(p: npt.ArrayLike) -> FloatArray:
    """Seed screen units (x, y, z) -> world metres: 0.005 * (x, y, z - 5).

    Raises:
        ParameterError: not finite numbers of shape (..., 3).
    """
    a = points(p, "p", unit="seed units")
    return 0.005 * (a - np.array([0.0, 0.0, 5.0]))


def _ro(a: npt.ArrayLike, shape: tuple[int, ...], where: str) -> FloatArray:
    return frozen_array(a, shape, where, CellError)


def _pose(T: npt.ArrayLike, where: str) -> FloatArray:
    arr = validate_pose(T, name=where, error=CellError)
    if arr.shape != (4, 4):
        raise CellError(f"{where}: expected one pose of shape (4, 4), got {arr.shape}")
    if np.abs(arr[:3, 3]).max() > MAX_EXTENT:
        raise CellError(f"{where}: position {arr[:3, 3].tolist()} m is beyond {MAX_EXTENT:g} m"[:300])
    arr = arr.copy()
    arr.setflags(write=False)
    return arr


@value_class
@dataclass(frozen=True, slots=True)
class ArmMount:
    """An arm: the robot (a name from ``KNOWN_ROBOTS`` or a :class:`~dualpuma.kinematics.RobotSpec`:
    a URDF and its hand frame), its base pose in the world, its home (start) joints [rad]."""

    name: str
    robot: str | RobotSpec
    T_world_base: FloatArray
    q_home: FloatArray = field(default_factory=lambda: np.zeros(6))

    def __post_init__(self) -> None:
        text(self.name, "ArmMount.name", max_len=MAX_NAME, printable=True, error=CellError)
        if isinstance(self.robot, RobotSpec):
            try:
                Arm.load(self.robot)  # a 6-DOF arm with that hand frame (cached: loaded once)
            except RobotError as exc:
                raise CellError(f"{self.name}.robot: {exc}") from None
        elif not isinstance(self.robot, str) or self.robot not in KNOWN_ROBOTS:
            raise CellError(f"{self.name}.robot: unknown robot {self.robot!r}; known: {', '.join(KNOWN_ROBOTS)}, "
                            "or { urdf = \"path\", tip = \"frame\" }")
        object.__setattr__(self, "T_world_base", _pose(self.T_world_base, f"{self.name}.T_world_base"))
        object.__setattr__(self, "q_home", _ro(self.q_home, (6,), f"{self.name}.q_home"))


def _size(shape: str, size: npt.ArrayLike, where: str) -> FloatArray:
    choice(shape, SHAPES, f"{where}.shape", CellError)
    n = SIZE_COUNTS[shape]
    arr = _ro(size, (n,), f"{where}.size")
    if np.any(arr <= 0) or np.any(arr > MAX_EXTENT):
        raise CellError(f"{where}.size: sizes must be in (0, {MAX_EXTENT:g}] m, got {arr.tolist()}"[:300])
    return arr


def _bar_gap(bar: Bar, p: npt.ArrayLike) -> float:
    """Signed distance [m] of point p (3,) in the object frame from the bar's surface (negative inside)."""
    T = bar.T_object_bar
    q = T[:3, :3].T @ (np.asarray(p, float) - T[:3, 3])  # in the bar's frame
    if bar.shape == "box":
        h = 0.5 * bar.size
        out = np.maximum(np.abs(q) - h, 0.0)
        return float(np.linalg.norm(out)) if out.any() else -float(np.min(h - np.abs(q)))
    if bar.shape == "capsule":
        r, L = bar.size
        return float(np.hypot(np.hypot(q[0], q[1]), abs(q[2]) - min(abs(q[2]), 0.5 * L)) - r)
    return float(np.linalg.norm(q) - bar.size[0])


@value_class
@dataclass(frozen=True, slots=True)
class Bar:
    """The held bar: box size = full extents [m]; capsule size = (radius, length) along local z."""

    shape: str
    size: FloatArray
    T_object_bar: FloatArray

    def __post_init__(self) -> None:
        object.__setattr__(self, "size", _size(self.shape, self.size, "bar"))
        object.__setattr__(self, "T_object_bar", _pose(self.T_object_bar, "bar.T_object_bar"))


@value_class
@dataclass(frozen=True, slots=True)
class Grasp:
    """Rigid grasp: the hand (wrist-centre) frame in the object frame."""

    T_object_hand: FloatArray

    def __post_init__(self) -> None:
        object.__setattr__(self, "T_object_hand", _pose(self.T_object_hand, "grasp.T_object_hand"))


@value_class
@dataclass(frozen=True, slots=True)
class Obstacle:
    """Box (full extents), sphere (radius,) or capsule (radius, length); optional constant velocity
    [m/s] applied between ``t_start`` and ``t_end`` [s] (the seed's AGV scenario)."""

    name: str
    shape: str
    size: FloatArray
    T_world_obstacle: FloatArray
    velocity: FloatArray = field(default_factory=lambda: np.zeros(3))
    t_start: float = 0.0
    t_end: float = math.inf

    def __post_init__(self) -> None:
        text(self.name, "obstacle name", max_len=MAX_NAME, printable=True, error=CellError)
        w = f"obstacles[{self.name}]"
        object.__setattr__(self, "size", _size(self.shape, self.size, w))
        object.__setattr__(self, "T_world_obstacle", _pose(self.T_world_obstacle, f"{w}.T_world_obstacle"))
        object.__setattr__(self, "velocity", _ro(self.velocity, (3,), f"{w}.velocity"))
        if np.abs(self.velocity).max() > MAX_EXTENT:
            raise CellError(f"{w}.velocity: faster than {MAX_EXTENT:g} m/s along an axis")
        t0 = real(self.t_start, f"{w}.t_start", unit="s", error=CellError)
        t1 = math.inf if _is_inf(self.t_end) else real(self.t_end, f"{w}.t_end", unit="s", error=CellError)
        if t1 < t0:
            raise CellError(f"{w}: need finite t_start <= t_end (or t_end = inf), got {t0}, {t1}")
        object.__setattr__(self, "t_start", t0)
        object.__setattr__(self, "t_end", t1)

    def pose_at(self, t: float) -> FloatArray:
        """World pose at time ``t`` [s] (moves only inside [t_start, t_end]).

        Raises:
            ParameterError: ``t`` not a finite number.
        """
        dt = min(max(real(t, "t", unit="s"), self.t_start), self.t_end) - self.t_start
        T = self.T_world_obstacle.copy()
        T[:3, 3] += dt * self.velocity
        return T


@value_class
@dataclass(frozen=True, slots=True)
class Cell:
    """A two-arm work cell (see module docstring)."""

    left: ArmMount
    right: ArmMount
    bar: Bar
    grasp_left: Grasp
    grasp_right: Grasp
    T_world_object_start: FloatArray
    obstacles: tuple[Obstacle, ...] = ()
    floor_z: float = 0.0
    safety_margin: float = 0.02
    name: str = "cell"

    def __post_init__(self) -> None:
        for name, cls in (("left", ArmMount), ("right", ArmMount), ("bar", Bar), ("grasp_left", Grasp),
                          ("grasp_right", Grasp)):
            instance(getattr(self, name), cls, name, CellError)
        text(self.name, "name", max_len=MAX_NAME, printable=True, error=CellError)
        object.__setattr__(self, "T_world_object_start", _pose(self.T_world_object_start, "T_world_object_start"))
        for side in ("left", "right"):
            gap = _bar_gap(self.bar, getattr(self, f"grasp_{side}").T_object_hand[:3, 3])
            if gap > MAX_GRASP_GAP:
                raise CellError(
                    f"grasp_{side}: the {side} hand frame is {gap:.3f} m from the bar's surface, farther than "
                    f"{MAX_GRASP_GAP:g} m: it does not hold the bar (a cell file derives the grasp from {side}.q_home "
                    f"at object_start unless grasp_{side} is given: change those or bar.pose)")
        for side in ("left", "right"):
            mount, grasp = getattr(self, side), getattr(self, f"grasp_{side}")
            H = mount.T_world_base @ Arm.load(mount.robot).fk(mount.q_home)
            err = float(pose_error(H[None], (self.T_world_object_start @ grasp.T_object_hand)[None])[0])
            if not err <= GRASP_TOL:
                raise CellError(
                    f"{side}.q_home: at its home joints the {side} hand is {err:.6f} m off its grasp of the bar at the "
                    f"start pose (position error plus {CLOSURE_LEVER:g} m times the rotation error): the home joints "
                    f"must hold the bar there. A cell file derives grasp_{side} from {side}.q_home at object_start "
                    f"unless grasp_{side} is given: remove grasp_{side} to derive it again, or give joints that hold it")
        obs = self.obstacles
        if isinstance(obs, (str, bytes, dict)) or not isinstance(obs, (tuple, list)):
            raise CellError(f"obstacles: expected a tuple of Obstacle, got {type(obs).__name__}")
        if len(obs) > MAX_OBSTACLES:
            raise CellError(f"obstacles: {len(obs)} obstacles, more than {MAX_OBSTACLES} (a World of so many is too "
                            "slow to build: merge small ones into boxes)")
        for i, o in enumerate(obs):
            instance(o, Obstacle, f"obstacles[{i}]", CellError)
        object.__setattr__(self, "obstacles", tuple(obs))
        names = [o.name for o in self.obstacles]
        if len(set(names)) != len(names):
            raise CellError(f"obstacles: names must be unique, got {names}"[:300])
        object.__setattr__(self, "floor_z", real(self.floor_z, "floor_z", lo=-MAX_EXTENT, hi=MAX_EXTENT, unit="m",
                                                 error=CellError))
        object.__setattr__(self, "safety_margin", check_margin(self.safety_margin, "safety_margin"))

    @staticmethod
    def default() -> Cell:
        """The seed's two-PUMA layout in SI (shoulders 1 m apart, 0.6604 m up), no obstacles."""
        # Mounting: the seed has no joint limits, so its q1 = 0 direction is a free choice. We yaw
        # both bases by MOUNT_YAW (-90 deg: J1's zero faces the work area in front, -y) so that
        # J1's +-160 deg range is centred on it; q1 = seed q1 - MOUNT_YAW. Every link's world pose
        # is the seed's (fk(q) starts with Rz(q1) about the base z axis).
        c, s = math.cos(MOUNT_YAW), math.sin(MOUNT_YAW)
        T_wl, T_wr = np.eye(4), np.eye(4)
        T_wl[:2, :2] = T_wr[:2, :2] = [[c, -s], [s, c]]
        T_wl[:3, 3] = seed_units_to_world([200.0, 0.0, 137.08])
        T_wr[:3, 3] = seed_units_to_world([400.0, 0.0, 137.08])
        qL = np.array([-0.5123, 0.1847, -0.8479, 0.0, 0.6632, -0.5123])
        qR = np.array([-1.7703, 0.1833, 0.3838, 0.0, -0.5671, -1.7703])
        qL[0] -= MOUNT_YAW
        qR[0] -= MOUNT_YAW
        HL, HR = T_wl @ fk(qL), T_wr @ fk(qR)
        T_wo = np.eye(4)
        T_wo[:3, :3] = HL[:3, :3]  # the seed: Tro's rotation = robot 1's hand rotation
        T_wo[:3, 3] = 0.5 * (HL[:3, 3] + HR[:3, 3])  # the bar's frame midway between the wrists
        inv = np.linalg.inv(T_wo)
        # bar: box 0.75 m along object x, 5 cm square, its centre 0.12 m along the approach axis
        T_ob = np.eye(4)
        T_ob[2, 3] = 0.12
        return Cell(
            left=ArmMount("left", "puma560", T_wl, qL),
            right=ArmMount("right", "puma560", T_wr, qR),
            bar=Bar("box", np.array([0.75, 0.05, 0.05]), T_ob),
            grasp_left=Grasp(inv @ HL),
            grasp_right=Grasp(inv @ HR),
            T_world_object_start=T_wo,
            name="seed-default",
        )
