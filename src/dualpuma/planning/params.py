"""Parameters of the planners (frozen dataclasses validated on construction, SI units).

* :class:`StrivingParams` — the seed's Striving planner (:func:`dualpuma.planning.plan`).
* :class:`FallbackParams` — the SE(3) RRT-Connect fallback (:mod:`dualpuma.planning.rrt`).

Every field is checked for type, finiteness and a sane range (a value that would make the planner
run out of memory or time is refused, not accepted); the error names the field and the range.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..checks import choice, flag, integer, probability, real
from ..errors import ParameterError
from ..lie import n_steps
from ..model.cell import check_margin

__all__ = ["MAX_RUN_POSES", "MAX_STEP", "MAX_TIME_LIMIT", "MIN_ROT_STEP", "MIN_STEP", "ORIENTATIONS", "PATH_CHECK_ROT", "PATH_CHECK_STEP", "PATH_SUBSTEPS_MIN", "SEED_ALTERNATES", "T_START_RANGE", "UP_AND_OVER",
           "FallbackParams", "StrivingParams", "checked_substeps", "for_striving", "start_time"]

#: the seed's routine-8 alternates, cumulative from the refused point [m]: AP1 = +x 50 mm, +z 25 mm;
#: AP2 = AP1 - 75 mm z; AP3 = AP2 + 50 mm y (listing: px + 10, pz + 5; pz - 15; py + 10 units)
SEED_ALTERNATES = ((0.05, 0.0, 0.025), (0.05, 0.0, -0.05), (0.05, 0.05, -0.05))
#: routine 7's recovery: 50 mm straight up from the current point, repeated (listing: z + 10 units)
UP_AND_OVER = ((0.0, 0.0, 0.05),)
#: orientation interpolation modes of Striving
ORIENTATIONS = ("slerp", "rpy", "puma")
_MAX_SUBSTEPS = 1000
#: the planners check at least this many poses per step, the ones between steps on the bar's path
#: (the path the timed trajectory follows): introduced when the planners certified the joint chord
#: instead of that path (a Hypothesis example's trajectory came 0.39 mm inside a 20 mm margin); the
#: certificate now covers the path, and these poses still screen it for joint limits and wrist
#: crossings (kinematics.bar_path.first_unfollowed); ``substeps`` 1 acts as 2
PATH_SUBSTEPS_MIN = 2
#: ... and poses on the bar's path at most this far apart (the trajectory's clearance between two
#: checked poses of the path can dip below theirs; with 0.1 m between them a random problem's
#: trajectory came 2.3 mm inside the margin): 25 mm [m], 2.5 deg [rad]
PATH_CHECK_STEP = 0.025
PATH_CHECK_ROT = math.radians(2.5)
_MAX_LENGTH = 100.0  # [m] no step or extension beyond this (a cell is a few metres)
#: the longest output step [m]: a step is checked every PATH_CHECK_STEP, at most _MAX_SUBSTEPS times
MAX_STEP = _MAX_SUBSTEPS * PATH_CHECK_STEP
#: the shortest step [m] and smallest rotation step [rad] accepted (0.1 mm, 0.01 deg): a step of
#: 1e-9 m made a run of 5e8 poses (MemoryError)
MIN_STEP = 1e-4
MIN_ROT_STEP = math.radians(0.01)
#: the most poses one straight run may check (steps x checked sub-poses): a run beyond it is
#: refused with a ParameterError naming step, rot_step and substeps (not built: 128 bytes a pose)
MAX_RUN_POSES = 1_000_000
#: the longest time limit a search accepts: a day [s]
MAX_TIME_LIMIT = 86_400.0
#: the start times a plan or a trajectory accepts [s]: from 0 to about 31 years (at 1e17 s, 0.1 s
#: steps were the same float: every row at one time, moving obstacles checked at one instant)
T_START_RANGE = (0.0, 1e9)


def start_time(value: object, name: str = "t_start") -> float:
    """A start time [s] in :data:`T_START_RANGE`.

    Raises:
        ParameterError: not a finite real number in that range.
    """
    return real(value, name, lo=T_START_RANGE[0], hi=T_START_RANGE[1], unit="s")


@dataclass(frozen=True, slots=True)
class FallbackParams:
    """Parameters of :func:`~dualpuma.planning.rrt.rrt_connect`.

    Attributes:
        max_iterations: RRT-Connect iterations (one extend + one connect each) before giving up.
        step: longest translation of the bar's frame per output step [m].
        rot_step: largest rotation per output step [rad].
        substeps: validity is checked at ``substeps`` evenly spaced sub-poses per output step (at
            least :data:`PATH_SUBSTEPS_MIN`, at most :data:`PATH_CHECK_STEP` / :data:`PATH_CHECK_ROT`
            apart: :func:`checked_substeps`).
        max_joint_step: largest joint change per output step and per sub-pose [rad].
        max_extend: longest extension of a tree per iteration, in the SE(3) metric [m].
        goal_bias: probability of extending towards the other tree's root instead of a sample.
        local_bias: probability of sampling near a random node of the growing tree (Gaussian,
            standard deviation ``max_extend / 5`` in translation and ``max_extend / (5 rot_weight)``
            in rotation) instead of in the whole box: explores narrow passages such as slots (0.7
            and a fifth of ``max_extend`` since 2026-11-27, 0.5 and a half before; paired on the
            hard set over six rng seeds: planning time x0.73 in total, p90 1.54 -> 0.76 s, paths 5 %
            shorter; on a held-out set x0.49, the slowest 26 -> 5.6 s; the box family alone x1.08;
            the snaking slot field solved at all of seeds 0-19 instead of 18: docs/performance.md).
        bounds: ``((x, y, z) lower, (x, y, z) upper)`` box sampled for the object origin [m];
            None: the box around start and goal grown by ``bounds_padding``, clipped at the floor.
        bounds_padding: growth of the default sampling box [m].
        max_rotation: sampled orientations are the start's or the goal's turned by at most this
            angle about a random axis [rad], small turns more often (half of them within a quarter
            of it) (90 deg: the bar may pitch, roll and yaw to snake).
        rot_weight: SE(3) metric ``|dp| + rot_weight * angle`` [m/rad].
        connect_attempts: the other tree tries to reach each new node from this many of its nodes:
            the nearest in the metric and the nearest by position alone.
        restart_iterations: the search starts again from new trees (the random stream continuing)
            after this many iterations without a path, then after twice as many, four times as
            many, ... (0 = never): the iterations a search needs are heavy-tailed, a few searches
            growing their trees into a dead end of a slot for thousands of iterations (since
            2026-11-27; paired on 360 searches of the hard and held-out sets the slowest took 5.9 s
            instead of 10.6 s, the total time x0.98: docs/performance.md, sixteenth session).
        shortcut_iterations: random shortcut attempts on a found path (0 = no smoothing).
        min_shortcut_gain: a shortcut is tried only if it shortens the path by more than this in
            the metric [m] (1 mm by default: on the hard set the shortcuts below it were a fifth
            of those that passed, cost 7 % of the planning time and shortened the paths by 26 mm
            in all, 0.15 %; 0 tries every shorter one).
        margin: required clearance [m]; None = the cell's ``safety_margin``.
        time_limit: give up after this much wall-clock time of the search [s] (None = no limit:
            only ``max_iterations`` ends it). Checked before each iteration, so the search ends
            within one iteration of it (milliseconds), and smoothing a found path is not cut.
            A limit that fires depends on the host's speed: the same problem may be reached on
            a faster machine (a plan that meets the goal is the same bit for bit either way).
    """

    max_iterations: int = 5000
    step: float = 0.05
    rot_step: float = math.radians(10.0)
    substeps: int = 5
    max_joint_step: float = math.radians(20.0)
    max_extend: float = 0.25
    goal_bias: float = 0.1
    local_bias: float = 0.7
    bounds: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    bounds_padding: float = 0.5
    max_rotation: float = math.radians(90.0)
    rot_weight: float = 0.15
    connect_attempts: int = 3
    restart_iterations: int = 1000
    shortcut_iterations: int = 100
    min_shortcut_gain: float = 0.001
    margin: float | None = None
    time_limit: float | None = None

    def __post_init__(self) -> None:
        f = "FallbackParams."
        integer(self.max_iterations, f + "max_iterations", lo=1, hi=10_000_000)
        integer(self.substeps, f + "substeps", lo=1, hi=_MAX_SUBSTEPS)
        integer(self.connect_attempts, f + "connect_attempts", lo=1, hi=1000)
        integer(self.restart_iterations, f + "restart_iterations", lo=0, hi=10_000_000)
        integer(self.shortcut_iterations, f + "shortcut_iterations", lo=0, hi=1_000_000)
        real(self.step, f + "step", lo=MIN_STEP, hi=MAX_STEP, unit="m")
        real(self.max_extend, f + "max_extend", lo=0.0, hi=_MAX_LENGTH, lo_open=True, unit="m")
        real(self.rot_step, f + "rot_step", lo=MIN_ROT_STEP, hi=math.pi, unit="rad")
        real(self.max_rotation, f + "max_rotation", lo=0.0, hi=math.pi, lo_open=True, unit="rad")
        real(self.max_joint_step, f + "max_joint_step", lo=0.0, hi=2 * math.pi, lo_open=True, unit="rad")
        real(self.rot_weight, f + "rot_weight", lo=0.0, hi=_MAX_LENGTH, lo_open=True, unit="m/rad")
        real(self.bounds_padding, f + "bounds_padding", lo=0.0, hi=_MAX_LENGTH, unit="m")
        real(self.min_shortcut_gain, f + "min_shortcut_gain", lo=0.0, hi=_MAX_LENGTH, unit="m")
        probability(self.goal_bias, f + "goal_bias")
        probability(self.local_bias, f + "local_bias")
        if self.goal_bias + self.local_bias > 1.0:
            raise ParameterError(f"{f}goal_bias + local_bias: expected <= 1, got {self.goal_bias + self.local_bias}")
        if self.margin is not None:
            check_margin(self.margin, f + "margin", ParameterError)
        if self.time_limit is not None:
            real(self.time_limit, f + "time_limit", lo=0.0, hi=MAX_TIME_LIMIT, lo_open=True, unit="s")
        if self.bounds is not None:
            try:
                b = np.array(self.bounds, dtype=float)
            except (TypeError, ValueError):
                b = np.zeros(0)
            if b.shape != (2, 3) or not np.all(np.isfinite(b)) or not np.all(b[0] < b[1]):
                raise ParameterError(
                    f"{f}bounds: expected ((x, y, z) lower, (x, y, z) upper) [m] with lower < upper, "
                    f"got {self.bounds!r}"
                )
            object.__setattr__(self, "bounds", (tuple(map(float, b[0])), tuple(map(float, b[1]))))


@dataclass(frozen=True, slots=True)
class StrivingParams:
    """Parameters of :func:`~dualpuma.planning.striving.plan`.

    Attributes:
        step: translation per step [m] (the seed: 10 screen units = 50 mm).
        rot_step: largest rotation per step [rad].
        min_step: the smallest step used when a step is refined because a joint would move more
            than ``max_joint_step`` [m].
        substeps: permission is checked at ``substeps`` evenly spaced poses per step (>= 1; the
            planner checks at least :data:`PATH_SUBSTEPS_MIN`, and poses at most
            :data:`PATH_CHECK_STEP` / :data:`PATH_CHECK_ROT` apart: :func:`checked_substeps`).
        max_joint_step: largest joint change per step [rad] (the seed's RobMov: 20 deg).
        margin: required clearance [m]; None = the cell's ``safety_margin``.
        orientation: ``slerp`` (geodesic), ``rpy`` (roll-pitch-yaw increments, eq. 5.7) or ``puma``
            (the seed's imaginary-PUMA joint angles, routine 3).
        alternates: recovery offsets (x, y, z) [m] tried in order when a pose is refused.
        alternates_from: ``refused`` (offsets from the refused pose, routine 8) or ``current``
            (from the last permitted pose, routine 7's up-and-over).
        mapping: also require the object origin outside every obstacle grown by the bar's major
            dimension (the seed's configuration mapping).
        max_steps: give up (frozen) after this many steps.
        max_recoveries: give up (frozen: wandering) after this many alternate positions taken.
        handover_after: with ``fallback``, hand over to it as soon as this many alternate
            positions in a row have left the bar no nearer the goal than it came before (nearness:
            the larger of distance / ``step`` and rotation angle / ``rot_step``, measured at each
            refused pose); 0 = only when Striving freezes, wanders or gives up. Without
            ``fallback`` Striving recovers as the seed did, up to ``max_recoveries``.
        step_time: time per step [s] (moving obstacles are checked at each step's time).
        twist_buffer: twisting-collision detector (routine 6) [m]: while the bar rotates, refuse a
            step whose arm–arm clearance is below this buffer *and* closing — the arms spiralling
            into each other are stopped before contact, as the seed's node search did with its
            175 mm threshold (0 = off).
        fallback: when Striving freezes, search SE(3) with RRT-Connect (:mod:`.rrt`).
        fallback_params: parameters for that search (None = its defaults).
    """

    step: float = 0.05
    rot_step: float = math.radians(5.0)
    min_step: float = 0.005
    substeps: int = 5
    max_joint_step: float = math.radians(20.0)
    margin: float | None = None
    orientation: str = "slerp"
    alternates: tuple[tuple[float, float, float], ...] = SEED_ALTERNATES
    alternates_from: str = "refused"
    mapping: bool = False
    max_steps: int = 2000
    max_recoveries: int = 100
    handover_after: int = 3
    step_time: float = 0.1
    twist_buffer: float = 0.0
    fallback: bool = False
    fallback_params: FallbackParams | None = None

    def __post_init__(self) -> None:
        f = "StrivingParams."
        real(self.step, f + "step", lo=MIN_STEP, hi=MAX_STEP, unit="m")
        real(self.min_step, f + "min_step", lo=MIN_STEP, hi=MAX_STEP, unit="m")
        real(self.rot_step, f + "rot_step", lo=MIN_ROT_STEP, hi=math.pi, unit="rad")
        real(self.max_joint_step, f + "max_joint_step", lo=0.0, hi=2 * math.pi, lo_open=True, unit="rad")
        real(self.step_time, f + "step_time", lo=0.0, hi=3600.0, lo_open=True, unit="s")
        real(self.twist_buffer, f + "twist_buffer", lo=0.0, hi=_MAX_LENGTH, unit="m")
        if self.min_step > self.step:
            raise ParameterError(f"{f}min_step ({self.min_step} m) must be <= step ({self.step} m): give a "
                                 f"smaller min_step with a step that short")
        integer(self.substeps, f + "substeps", lo=1, hi=_MAX_SUBSTEPS)
        integer(self.max_steps, f + "max_steps", lo=1, hi=1_000_000)
        integer(self.max_recoveries, f + "max_recoveries", lo=1, hi=1_000_000)
        integer(self.handover_after, f + "handover_after", lo=0, hi=1_000_000)
        if self.margin is not None:
            check_margin(self.margin, f + "margin", ParameterError)
        choice(self.orientation, ORIENTATIONS, f + "orientation")
        choice(self.alternates_from, ("refused", "current"), f + "alternates_from")
        flag(self.mapping, f + "mapping")
        flag(self.fallback, f + "fallback")
        if self.fallback_params is not None and not isinstance(self.fallback_params, FallbackParams):
            raise ParameterError(f"{f}fallback_params: expected FallbackParams or None, "
                                 f"got {type(self.fallback_params).__name__}")
        try:
            alts = np.asarray(self.alternates, dtype=float) if len(self.alternates) else np.zeros((0, 3))
            if isinstance(self.alternates, (str, bytes, dict)):
                raise TypeError
        except (TypeError, ValueError):
            alts = np.zeros((0, 0))
        if alts.ndim != 2 or alts.shape[1] != 3 or alts.shape[0] > 100 or not np.all(np.isfinite(alts)) \
                or np.abs(alts).max(initial=0.0) > _MAX_LENGTH:
            raise ParameterError(f"{f}alternates: expected at most 100 finite (x, y, z) offsets [m], "
                                 f"got {self.alternates!r}"[:300])
        object.__setattr__(self, "alternates", tuple(tuple(float(v) for v in a) for a in alts))


def checked_substeps(substeps: int, step: float = 0.0, rot_step: float = 0.0) -> int:
    """The poses per step a planner checks for a ``substeps`` parameter: at least
    :data:`PATH_SUBSTEPS_MIN` (one pose between steps on the bar's path, which the timed trajectory
    follows), and enough that poses on the bar's path are at most :data:`PATH_CHECK_STEP` [m] and
    :data:`PATH_CHECK_ROT` [rad] apart for steps of ``step`` [m] and ``rot_step`` [rad]."""
    return max(int(substeps), PATH_SUBSTEPS_MIN, n_steps(step, rot_step, PATH_CHECK_STEP, PATH_CHECK_ROT))


def for_striving(params: FallbackParams, striving) -> FallbackParams:
    """``params`` for a fallback that continues a Striving run (``striving``: StrivingParams or any
    object with ``margin``, ``substeps`` and ``max_joint_step``): Striving's margin applies when
    ``params.margin`` is None, validity is checked at least at its ``substeps``, and no joint moves
    more than the smaller of the two ``max_joint_step`` per output step (the whole returned path
    keeps the bound the caller asked Striving for)."""
    m = getattr(striving, "margin", None)
    sub = max(params.substeps, int(getattr(striving, "substeps", 1)))
    step = min(params.max_joint_step, float(getattr(striving, "max_joint_step", params.max_joint_step)))
    return dataclasses.replace(params, substeps=sub, margin=params.margin if params.margin is not None else m,
                               max_joint_step=step)
