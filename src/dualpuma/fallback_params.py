"""Parameters and result of the SE(3) RRT-Connect fallback (:mod:`dualpuma.fallback`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from .errors import ParameterError

__all__ = ["FallbackParams", "FallbackResult"]

FloatArray = npt.NDArray[np.float64]

def _positive(name: str, v: object, *, integer: bool = False, zero_ok: bool = False) -> None:
    ok_type = (
        isinstance(v, (int, np.integer))
        if integer
        else isinstance(v, (int, float, np.floating, np.integer))
    )
    if (
        isinstance(v, bool)
        or not ok_type
        or not math.isfinite(float(v))
        or (v < 0 if zero_ok else v <= 0)
    ):  # type: ignore[operator]
        kind = "an integer" if integer else "a finite value"
        raise ParameterError(
            f"FallbackParams.{name}: expected {kind} {'>= 0' if zero_ok else '> 0'}, got {v!r}"
        )


@dataclass(frozen=True, slots=True)
class FallbackParams:
    """Parameters of :func:`rrt_connect` (frozen; validated on construction, SI units).

    Attributes:
        max_iterations: RRT-Connect iterations (one extend + one connect each) before giving up.
        step: longest translation of the bar's frame per output step [m].
        rot_step: largest rotation per output step [rad].
        substeps: validity is checked at ``substeps`` evenly spaced sub-poses per output step.
        max_joint_step: largest joint change per output step and per sub-pose [rad].
        max_extend: longest extension of a tree per iteration, in the SE(3) metric [m].
        goal_bias: probability of extending towards the other tree's root instead of a sample.
        local_bias: probability of sampling near a random node of the growing tree (Gaussian,
            standard deviation ``max_extend / 2`` in translation and ``max_extend / (2 rot_weight)``
            in rotation) instead of in the whole box: explores narrow passages such as slots.
        bounds: ``((x, y, z) lower, (x, y, z) upper)`` box sampled for the object origin [m];
            None: the box around start and goal grown by ``bounds_padding``, clipped at the floor.
        bounds_padding: growth of the default sampling box [m].
        max_rotation: sampled orientations are the start's or the goal's turned by at most this
            angle about a random axis [rad] (90 deg: the bar may pitch, roll and yaw to snake).
        rot_weight: SE(3) metric ``|dp| + rot_weight * angle`` [m/rad].
        connect_attempts: the other tree tries to reach each new node from this many of its nodes:
            the nearest in the metric (which also grows by its permitted prefix) and the nearest by
            position alone (a full edge or nothing) — trees meeting in a narrow region from opposite
            orientations are nearest by position, not by the metric.
        shortcut_iterations: random shortcut attempts on a found path (0 = no smoothing).
        margin: required clearance [m]; None = the cell's ``safety_margin``.
    """

    max_iterations: int = 5000
    step: float = 0.05
    rot_step: float = math.radians(10.0)
    substeps: int = 5
    max_joint_step: float = math.radians(20.0)
    max_extend: float = 0.25
    goal_bias: float = 0.1
    local_bias: float = 0.5
    bounds: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    bounds_padding: float = 0.5
    max_rotation: float = math.radians(90.0)
    rot_weight: float = 0.15
    connect_attempts: int = 3
    shortcut_iterations: int = 100
    margin: float | None = None

    def __post_init__(self) -> None:
        for name in ("max_iterations", "substeps", "connect_attempts"):
            _positive(name, getattr(self, name), integer=True)
        _positive("shortcut_iterations", self.shortcut_iterations, integer=True, zero_ok=True)
        for name in (
            "step",
            "rot_step",
            "max_joint_step",
            "max_extend",
            "max_rotation",
            "rot_weight",
        ):
            _positive(name, getattr(self, name))
        _positive("bounds_padding", self.bounds_padding, zero_ok=True)
        if self.rot_step > math.pi or self.max_rotation > math.pi:
            raise ParameterError(
                f"FallbackParams.rot_step/max_rotation: expected angles <= pi [rad], got {self.rot_step}, {self.max_rotation}"
            )
        for name in ("goal_bias", "local_bias"):
            g = getattr(self, name)
            if isinstance(g, bool) or not isinstance(g, (int, float)) or not 0.0 <= g <= 1.0:
                raise ParameterError(
                    f"FallbackParams.{name}: expected a probability in [0, 1], got {g!r}"
                )
        if self.goal_bias + self.local_bias > 1.0:
            raise ParameterError(
                f"FallbackParams.goal_bias + local_bias: expected <= 1, got {self.goal_bias + self.local_bias}"
            )
        if self.margin is not None:
            _positive("margin", self.margin, zero_ok=True)
        if self.bounds is not None:
            try:
                b = np.array(self.bounds, dtype=float)
            except (TypeError, ValueError):
                b = np.zeros(0)
            if b.shape != (2, 3) or not np.all(np.isfinite(b)) or not np.all(b[0] < b[1]):
                raise ParameterError(
                    f"FallbackParams.bounds: expected ((x, y, z) lower, (x, y, z) upper) [m] with lower < upper, got {self.bounds!r}"
                )
            object.__setattr__(self, "bounds", (tuple(map(float, b[0])), tuple(map(float, b[1]))))


@dataclass(frozen=True, slots=True)
class FallbackResult:
    """Result of :func:`rrt_connect` (arrays read-only; empty when ``ok`` is False).

    Attributes:
        ok: a permitted path from start to goal was found.
        T_world_object: object poses (N, 4, 4) [m]; row 0 = start, row N-1 = goal.
        q_left, q_right: joints (N, 6) [rad].
        clearance: minimum signed distance per pose (N,) [m].
        reason: why it failed ("" when ok).
        iterations: RRT-Connect iterations run.
        n_nodes: nodes in both trees.
        time_s: wall time [s].
        t: time of each pose (N,) [s]: ``t0 + i * step_time``.
    """

    ok: bool
    T_world_object: FloatArray
    q_left: FloatArray
    q_right: FloatArray
    clearance: FloatArray
    reason: str
    iterations: int
    n_nodes: int
    time_s: float
    t: FloatArray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        for name in ("T_world_object", "q_left", "q_right", "clearance", "t"):
            arr = np.array(getattr(self, name), dtype=np.float64)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
