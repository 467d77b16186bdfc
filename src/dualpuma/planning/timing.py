"""Timing a plan for execution: a time-optimal joint trajectory of both arms under the PUMA 560's
joint velocity and acceleration limits, on the closed chain (:func:`time_plan`).

1. **Dense path on the closed chain.** Between consecutive rows of the plan the bar moves along the
   SE(3) geodesic (translation linear, rotation along the shortest arc); both arms follow it by IK on
   their branches (:func:`~dualpuma.kinematics.bar_path.follow_geodesic`), so every dense sample
   holds the bar exactly.
2. **Corners.** Where the bar's direction of motion changes at a row (a recovery, a fallback
   waypoint) the joint path has a corner, which a time-optimal parameteriser would pass at speed
   (infinite acceleration): the path is split there and each piece is timed rest to rest.
3. **One time law for both arms.** Each piece is a cubic spline through its 12-joint samples (both
   arms) in a path parameter s, and toppra (TOPP-RA, ``JointVelocityConstraint`` +
   ``JointAccelerationConstraint``) computes the time-optimal s(t) for it; joints follow
   ``q(t) = path(s(t))`` with constant path acceleration between toppra's gridpoints (its
   ``ParametrizeConstAccel`` law, evaluated here in numpy), so the output stays exactly on the path
   and both arms share the same s(t). toppra enforces the limits at its gridpoints only: they are
   scaled by ``limit_scale`` (0.98) first and the measured ratios are reported.
4. **Closed-chain tolerance.** The closed-chain error of a configuration is how far the right hand
   is from where the bar held by the left hand wants it (FK of both arms): the position error plus
   0.1 m times the rotation error (a point 100 mm from the wrist centre moves by at most that). The
   spline is checked halfway and at the quarters between its samples and the dense sampling is
   doubled where the error exceeds half of ``closure_tol``; the output samples and the joint-linear
   midpoints between consecutive output samples are checked against ``closure_tol`` (the sampling
   period halves until they pass). The samples (:mod:`.schedule`) are each piece's, at most ``dt``
   apart, or, with ``period``, a controller's clock: exactly ``period`` apart from the start, which
   is never halved (a period too long for the closed chain is refused, naming one that is not).
5. **Certified clearance.** The samples' clearances are computed and the joint-linear motion between
   consecutive samples is certified at their real times (:func:`~.certify.certify_chords`); a
   trajectory that cannot be certified says so: ``certified`` False with the reason.
6. **Giving way to moving obstacles.** A plan's rows carry the planner's clock (``step_time`` a
   step), which the arms rarely keep: the fastest timing meets a moving obstacle at other times
   than the plan did. When it is not certified for that reason (not when a sample is below the
   margin against geometry that never moves: every timing passes there), the same path is timed
   again with a wait at the first row and/or a uniform slowdown (the time law run ``scale`` times
   slower: velocities / scale, accelerations / scale², so the limits still hold), candidates in
   the order they arrive (waits 0, 0.1 s doubling up to ``max_wait`` and the times a moving obstacle
   starts or stops; slowdowns 1.25, 1.5, 2, 3, 4 up to ``max_slowdown``), each certified as in step
   5, and refused if its samples leave the closed chain by more than ``closure_tol`` (they are not
   the fastest timing's); the first one certified is returned (``start_delay``, ``time_scale``). On a
   controller's clock a wait is a whole number of periods. The wait itself is
   certified once for its longest possible length, and no longer wait is tried. None certified: the
   fastest timing, ``certified`` False, the reason saying so. This is the velocity-tuning half of a
   path-velocity decomposition (Kant & Zucker 1986) restricted to two parameters: waits between
   rows are not searched.

Why toppra: :mod:`.time_law`.

Joint velocity and acceleration limits: :mod:`.rate_limits` (the PUMA 560's nominal table and
its source, the URDF's velocity limits, what is missing for other arms).
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..checks import instance, real
from ..collision.contact import first_contact_chord
from ..errors import ParameterError
from ..kinematics.bar_path import follow_geodesic_why
from ..kinematics.dual import CLOSURE_LEVER, check_rows_hold_the_bar, closure_error
from ..model.cell import check_margin
from ..model.world import World
from .certify import certify_chords
from .params import start_time
from .plan import Plan
from .rate_limits import rate_limits
from .reach import motion_bounds
from .schedule import sample, total_duration, wait_times
from .time_law import spline, time_optimal
from .trajectory import Trajectory

__all__ = ["CLOSURE_LEVER", "CLOSURE_TOL", "DT", "MAX_SAMPLES", "MAX_SLOWDOWN", "MAX_WAIT", "PERIOD_RANGE",
           "SLOWDOWN_RANGE", "WAIT_RANGE", "closure_error", "time_plan", "with_trajectory"]

FloatArray = npt.NDArray[np.float64]

CLOSURE_TOL = 0.5e-3  #: default closed-chain tolerance [m]
MAX_SAMPLES = 200_000  #: most samples a timed trajectory may have (over half an hour at 10 ms)
MAX_WAIT = 10.0  #: default longest wait at the first row against moving obstacles [s]
MAX_SLOWDOWN = 4.0  #: default largest uniform slowdown against moving obstacles
DT = 0.01  #: default largest sampling period [s]
PERIOD_RANGE = (1e-4, 1.0)  #: the controller cycles a trajectory may be sampled on [s] (10 kHz .. 1 Hz)
_HALVINGS = 6  # the sampling period is halved at most this often for the closed chain
WAIT_RANGE = (0.0, 3600.0)  #: the values max_wait may take [s]
SLOWDOWN_RANGE = (1.0, 100.0)  #: the values max_slowdown may take
_SLOWDOWNS = (1.0, 1.25, 1.5, 2.0, 3.0, 4.0)  # slowdowns tried (up to max_slowdown)
_CORNER = math.radians(3.0)  # a change of the bar's direction above this at a row is a corner
_FIRST_STEP = math.radians(2.0)  # initial dense sampling: joints move at most this per sample [rad]
_ROUNDS = 14
_SAME_POSE = 1e-12  # consecutive rows within this of each other [m, rotation entries] and ...
_SAME_JOINTS = 1e-9  # ... this [rad] are one configuration, passed at one time
_NOT_A_MOTION = ("invalid_start", "invalid_goal", "invalid_input", "error")  # statuses of plans that never moved
_METHOD = "toppra TOPP-RA (JointVelocity + JointAcceleration constraints), constant path acceleration between gridpoints"


# ----------------------------------------------------------------------------- dense path
def _twist(A: FloatArray, B: FloatArray) -> FloatArray:
    """Direction of the bar's motion A -> B: translation and 0.15 m/rad times the rotation vector
    (world frame), normalised."""
    w = A[:3, :3] @ np.asarray(pin.log3(A[:3, :3].T @ B[:3, :3]), dtype=float)
    v = np.concatenate([B[:3, 3] - A[:3, 3], 0.15 * w])
    n = float(np.linalg.norm(v))
    return v / n if n > 0 else v


def _corners(P: FloatArray) -> list[int]:
    """Rows (1..N-2) where the bar's direction of motion changes by more than :data:`_CORNER`."""
    out = []
    for i in range(1, P.shape[0] - 1):
        a, b = _twist(P[i - 1], P[i]), _twist(P[i], P[i + 1])
        if not (np.any(a) and np.any(b)) or math.acos(max(-1.0, min(1.0, float(a @ b)))) > _CORNER:
            out.append(i)
    return out


# ----------------------------------------------------------------------------- public
def time_plan(plan, world, *, v_max: npt.ArrayLike | None = None, a_max: npt.ArrayLike | None = None,
              closure_tol: float = CLOSURE_TOL, dt: float | None = None, period: float | None = None,
              limit_scale: float = 0.98, margin: float | None = None, max_wait: float = MAX_WAIT,
              max_slowdown: float = MAX_SLOWDOWN, t_start: float | None = None) -> Trajectory:
    """Time a plan for execution (module docstring): the trajectory of both arms through every
    row of ``plan``, sampled at most ``dt`` apart or on a controller's clock (``period``), under the
    joint limits, on the closed chain.

    Args:
        plan: a :class:`~dualpuma.planning.plan.Plan` with at least one row.
        world: the :class:`~dualpuma.model.world.World` of the plan's cell.
        v_max, a_max: joint velocity [rad/s] and acceleration [rad/s^2] limits, (6,) for both arms
            or (12,) (left then right); default the nominal PUMA 560 values (:data:`~.rate_limits.PUMA_QD_MAX`).
        closure_tol: closed-chain tolerance between samples [m].
        dt: largest sampling period [s] (default :data:`DT`; halved where the closed chain needs it):
            each piece between corners is sampled evenly.
        period: instead of ``dt``, a controller's fixed cycle [s] (in :data:`PERIOD_RANGE`): every
            sample exactly ``period`` after the previous one from the plan's start time
            (:mod:`.schedule`), a wait a whole number of periods long. Never halved: a period too
            long for ``closure_tol`` is refused, naming one that keeps it.
        limit_scale: the limits are scaled by this before toppra (which enforces them at its
            gridpoints only).
        margin: clearance to certify [m] (default: the margin the plan was made with,
            ``plan.meta["margin"]``, else the cell's).
        max_wait, max_slowdown: when a moving obstacle makes the fastest timing unsafe, the longest
            wait at the first row [s] and the largest uniform slowdown (>= 1) tried to let it pass
            (module docstring, step 6); ``max_wait=0, max_slowdown=1`` keeps the fastest timing.
        t_start: when the motion starts [s] (default the plan's first time, ``plan.t[0]``), in
            :data:`~.params.T_START_RANGE`; moving obstacles are met at the trajectory's times. A leg
            executed after another timed leg starts when that one ends (``previous.t[-1]``): a
            plan's own clock ends sooner than its timed motion. (Or chain the legs' plans first and
            time the chained plan: one trajectory.)

    Returns:
        :class:`~dualpuma.planning.trajectory.Trajectory` (``certified`` says whether its motion
        keeps the margin; a plan the arms cannot follow on the closed chain gives ParameterError).

    Raises:
        ParameterError: bad arguments (``dt`` and ``period`` together), an empty plan, a plan that
            failed before it moved (``invalid_start``, ``invalid_goal``, ``invalid_input``, ``error``
            with one configuration in all its rows), rows that
            do not hold the bar in ``world``'s cell, limits missing for a non-PUMA arm, rows the arms
            cannot follow on their IK branches, or a ``period`` too long for the closed chain.
    """
    instance(plan, Plan, "plan")
    instance(world, World, "world")
    Q = np.hstack([plan.q_left, plan.q_right]).astype(float)
    # a plan that never moved: all its rows one configuration (a chain's failed last leg after others moved is timed)
    if plan.status in _NOT_A_MOTION and not np.any(np.abs(Q[1:] - Q[:1]) > _SAME_JOINTS):
        raise ParameterError(f"time_plan: a plan with status {plan.status} is no motion to execute ({plan.reason})")
    if not np.all(np.isfinite(Q)):
        raise ParameterError("time_plan: the plan has rows without joints (NaN)")
    n_rows = plan.T_world_object.shape[0]
    if n_rows == 0:
        raise ParameterError("time_plan: the plan has no rows")
    P = np.asarray(plan.T_world_object, float)
    check_rows_hold_the_bar(world, P, Q, "time_plan")
    closure_tol = real(closure_tol, "closure_tol", lo=1e-7, hi=1.0, unit="m")
    if dt is not None and period is not None:
        raise ParameterError("time_plan: give dt (the largest sampling period) or period (a controller's fixed "
                             "cycle), not both")
    on_clock = period is not None
    dt = real(period, "period", lo=PERIOD_RANGE[0], hi=PERIOD_RANGE[1], unit="s") if on_clock else (
        real(DT if dt is None else dt, "dt", lo=1e-4, hi=10.0, unit="s"))
    cycle = dt if on_clock else 0.0  # the controller's cycle the samples are on (never halved), 0: per piece
    limit_scale = real(limit_scale, "limit_scale", lo=0.5, hi=1.0, unit="")
    max_wait = real(max_wait, "max_wait", lo=WAIT_RANGE[0], hi=WAIT_RANGE[1], unit="s")
    max_slowdown = real(max_slowdown, "max_slowdown", lo=SLOWDOWN_RANGE[0], hi=SLOWDOWN_RANGE[1], unit="")
    v, v_source = rate_limits(world, v_max, "v_max")
    a, a_source = rate_limits(world, a_max, "a_max")
    source = v_source if v_source == a_source else f"velocity: {v_source}; acceleration: {a_source}"
    if margin is None:  # the planner's margin (recorded in the plan), else the cell's
        margin = plan.meta.get("margin", world.cell.safety_margin) if isinstance(plan.meta, dict) else None
    m = world.covered(check_margin(world.cell.safety_margin if margin is None else margin, "margin", ParameterError))
    t0 = float(plan.t[0]) if t_start is None else start_time(t_start)
    # a row that repeats the previous one (same pose and joints) is passed at the same time
    keep = np.ones(n_rows, dtype=bool)
    keep[1:] = ((np.abs(np.diff(P, axis=0)).max(axis=(1, 2)) > _SAME_POSE)
                | (np.abs(np.diff(Q, axis=0)).max(axis=1) > _SAME_JOINTS))
    of_row = np.cumsum(keep) - 1  # each row's index among the kept ones
    P, Q, n_rows = P[keep], Q[keep], int(keep.sum())
    if n_rows == 1:
        T = np.array([t0])
        d, _ = _clearance(world, Q[:1], T)
        return _assemble(world, T, Q[:1], np.zeros((1, 12)), np.zeros((1, 12)), d, _certificate(world, Q[:1], d, T, m)[1],
                         np.full(of_row.size, t0), v, a, closure_tol, _closure_worst(world, Q[:1]), source, cycle)
    bounds = [0, *_corners(P), n_rows - 1]
    max_step = 2.0 * math.pi
    counts = [max(2, math.ceil(float(np.abs(Q[i + 1] - Q[i]).max()) / _FIRST_STEP)) for i in range(n_rows - 1)]
    pieces = []
    for a_row, b_row in itertools.pairwise(bounds):
        pieces.append(_fit_piece(world, P, Q, a_row, b_row, counts, closure_tol, max_step, v * limit_scale,
                                 a * limit_scale, v, a))
    step = dt
    for _ in range(_HALVINGS):
        T, QS, QD, QDD, row_t = sample(pieces, step, t0, on_clock=on_clock, max_samples=MAX_SAMPLES)
        worst = _closure_worst(world, QS)
        if worst <= closure_tol:
            break
        if on_clock:  # a controller's cycle is not ours to halve: say which one would keep the chain
            _refuse_period(world, pieces, dt, t0, worst, closure_tol)
        step *= 0.5
    else:
        raise ParameterError(f"time_plan: closed-chain error {worst:.7f} m above {closure_tol:.7f} m at "
                             f"sampling period {step:.2e} s")
    d, pair = _clearance(world, QS, T)
    fastest = _assemble(world, T, QS, QD, QDD, d, _certificate(world, QS, d, T, m)[1], row_t[of_row], v, a,
                        closure_tol, worst, source, cycle)
    if fastest.certified or not _moving_may_pass(world, d, pair, m) or first_contact_chord(world, QS)[1]:
        return fastest  # (no timing moves the arms off a path that may bring a close pair into contact)
    max_wait = min(max_wait, max(0.0, MAX_SAMPLES * step - fastest.duration))  # longer ones exceed MAX_SAMPLES
    tunings = _tunings(world, t0, fastest.duration, max_wait, max_slowdown, cycle)
    if not tunings:  # max_wait 0 and max_slowdown 1: the fastest timing was asked for
        return fastest
    # a moving obstacle meets the fastest timing: wait at the first row and/or run slower (step 6)
    can_wait = _wait_limit(world, QS[0], t0, step, max_wait, m)
    for delay, scale in tunings:
        if delay > can_wait or total_duration(pieces, delay, scale) / step > MAX_SAMPLES:
            continue
        T, QS, QD, QDD, row_t = sample(pieces, step, t0, delay, scale, on_clock=on_clock)
        worst = _closure_worst(world, QS)
        if worst > closure_tol:  # other samples than the fastest timing's
            continue
        d, _ = _clearance(world, QS, T)
        if np.any(d < m) or _certificate(world, QS, d, T, m)[1]:
            continue
        return _assemble(world, T, QS, QD, QDD, d, "", row_t[of_row], v, a, closure_tol, worst, source, cycle, delay,
                         scale)
    why = (f"{fastest.reason} (a moving obstacle: no wait at the first row up to {max_wait:g} s and no slowdown up "
           f"to x{max_slowdown:g} keeps the margin")
    late = _clock_ratio(plan.t, fastest.row_times)
    if late > 1.0:
        why += (f"; the plan's clock passes its rows up to {late:.1f}x sooner than the arms can reach them: plan with "
                f"a step_time {late:.1f}x as long")
    return dataclasses.replace(fastest, reason=why + ")")


def _fit_piece(world, P, Q, a_row: int, b_row: int, counts: list[int], tol: float, max_step: float, v, a,
               v_true, a_true):
    """Dense samples of rows a_row..b_row, refined until the spline keeps the closed chain, then timed."""
    dense: dict[int, FloatArray] = {}
    for _ in range(_ROUNDS):
        parts = [Q[a_row][None]]
        for i in range(a_row, b_row):
            if i not in dense:
                D, why = follow_geodesic_why(world, P[i], P[i + 1], Q[i], counts[i], max_step, Q[i + 1])
                if D is None:
                    raise ParameterError(f"time_plan: the arms cannot follow the bar from row {i} to row {i + 1} on "
                                         f"their IK branches: {why}")
                dense[i] = D
            parts.append(dense[i])
        W = np.concatenate(parts)
        owner = np.concatenate([[a_row]] + [np.full(counts[i], i) for i in range(a_row, b_row)])
        path, s = spline(W)
        fr = np.array([0.25, 0.5, 0.75])
        probe = (s[:-1, None] + fr[None] * np.diff(s)[:, None]).ravel()
        err = closure_error(world, path(probe)).reshape(-1, 3).max(axis=1)
        bad = np.flatnonzero(err > 0.5 * tol)
        if bad.size == 0:
            break
        for i in set(owner[1:][bad].tolist()):
            counts[i] *= 2
            dense.pop(i, None)
    else:
        raise ParameterError(f"time_plan: rows {a_row}..{b_row}: the spline does not keep the closed chain")
    law = time_optimal(path, v, a, v_true, a_true)
    if law is None:
        raise ParameterError(f"time_plan: toppra found no time law for rows {a_row}..{b_row}")
    knots = np.concatenate([[0], np.cumsum([counts[i] for i in range(a_row, b_row)])])
    d = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(W, axis=0), axis=1))])
    return path, law, d[knots] / max(d[-1], 1e-300)


def _wait_limit(world, q0: FloatArray, t0: float, step: float, max_wait: float, margin: float) -> float:
    """How long [s] (at most ``max_wait``) the arms can stay at rest at joints q0 (12,) from t0 with
    their clearance certified against the moving obstacles (the wait sampled as
    :func:`~.schedule.wait_times`)."""
    if max_wait <= 0.0:
        return 0.0
    T = t0 + wait_times(step, max_wait)
    Q = np.repeat(q0[None], T.shape[0], axis=0)
    n_ok, why = _certificate(world, Q, _clearance(world, Q, T)[0], T, margin)
    return max_wait if not why else float(T[n_ok] - t0)


def _clearance(world, QS: FloatArray, T: FloatArray):
    from ..collision.batch import min_clearance

    return min_clearance(world, np.ascontiguousarray(QS), T)


def _moving_may_pass(world, d: FloatArray, pair, margin: float) -> bool:
    """Can another timing help a trajectory that is not certified (its samples' clearances d [m] and
    pairs)? Not without moving obstacles, nor when a sample is below the margin against geometry
    that never moves (every timing passes that configuration)."""
    if not world.moving or d.shape[0] < 2:
        return False
    below = np.flatnonzero(d < margin)
    if below.size == 0 or pair[below[0]] < 0:
        return True  # refused between samples (a midpoint, or too close to prove), or no pair named
    moving = {gid for gid, _ in world.moving}
    return bool(set(world.pair_ids[int(pair[below[0]])]) & moving)


def _clock_ratio(plan_t: FloatArray, row_times: FloatArray) -> float:
    """How many times later than the plan's clock (times plan_t [s] of its rows) the fastest timing
    reaches its rows (row_times [s]) at most (1 when no row is later)."""
    dp, dr = plan_t[1:] - plan_t[0], row_times[1:] - row_times[0]
    return float(np.max(dr[dp > 0] / dp[dp > 0], initial=1.0))


def _tunings(world, t0: float, duration: float, max_wait: float, max_slowdown: float, cycle: float = 0.0):
    """Candidate ``(delay [s], scale)`` other than (0, 1), earliest arrival first (ties: the smaller
    slowdown): delays 0, 0.1 s doubling up to ``max_wait`` and ``max_wait`` itself, and the times
    after ``t0`` at which a moving obstacle starts or stops (with a controller's ``cycle`` [s]: each
    rounded up to a whole number of cycles, so that the motion after the wait is sampled as the
    fastest timing; none beyond ``max_wait``); slowdowns :data:`_SLOWDOWNS` up to ``max_slowdown`` and
    ``max_slowdown`` itself."""
    delays = {0.0, max_wait}
    x = 0.1
    while x < max_wait:
        delays.add(x)
        x *= 2.0
    for _, ob in world.moving:
        for edge in (ob.t_start, ob.t_end):
            if 0.0 < edge - t0 <= max_wait:
                delays.add(float(edge - t0))
    if cycle > 0.0:
        delays = {w for w in (math.ceil(x / cycle - 1e-9) * cycle for x in delays) if w <= max_wait}
    scales = {c for c in _SLOWDOWNS if c <= max_slowdown} | {max_slowdown}
    out = sorted((d + c * duration, c, d) for d in delays for c in scales if (d, c) != (0.0, 1.0))
    return [(d, c) for _, c, d in out]


def _certificate(world, QS: FloatArray, d: FloatArray, T: FloatArray, margin: float) -> tuple[int, str]:
    """Samples QS (K, 12) with clearances d [m] at times T [s]: ``(n_ok, reason)``, the leading chords
    certified (:func:`~.certify.certify_chords`), and why not all are or not every sample keeps the margin."""
    reach, v_obs = motion_bounds(world)
    cert = certify_chords(world, QS, d, T, margin, reach, v_obs)
    if cert.n_ok == QS.shape[0] - 1 and bool(np.all(d >= margin)):
        return cert.n_ok, ""
    least = f" (the least clearance of the checked pairs at the samples: {float(d.min()):.4f} m)"  # the first refusal is not the worst
    return cert.n_ok, (f"sample {cert.n_ok}: {cert.reason}" if cert.reason else "a sample is below the margin") + least


def _closure_worst(world, QS: FloatArray) -> float:
    """The largest closed-chain error [m] at samples QS (K, 12) and halfway between consecutive ones
    (joint-linear)."""
    err = float(closure_error(world, QS).max())
    return max(err, float(closure_error(world, 0.5 * (QS[1:] + QS[:-1])).max())) if QS.shape[0] > 1 else err


def _refuse_period(world, pieces, period: float, t0: float, worst: float, tol: float) -> None:
    """Raise the ParameterError of a controller ``period`` [s] whose samples leave the closed chain
    by ``worst`` > ``tol`` [m], naming the longest period period / 2^k that keeps it (if any)."""
    shorter, hint = period, ""
    for _ in range(_HALVINGS):
        if shorter * 0.5 < PERIOD_RANGE[0]:
            break
        try:
            QS = sample(pieces, 0.5 * shorter, t0, on_clock=True, max_samples=MAX_SAMPLES)[1]
        except ParameterError:  # more samples than MAX_SAMPLES: no shorter period is offered
            break
        shorter *= 0.5
        if _closure_worst(world, QS) <= tol:
            hint = f"a period of {shorter:.4g} s keeps it"
            break
    hint = hint or (f"no period down to {shorter:.4g} s keeps it" if shorter < period
                    else "no shorter period fits the sample bound")
    raise ParameterError(f"time_plan: at a period of {period:.4g} s the closed-chain error between samples is "
                         f"{worst:.7f} m, above closure_tol {tol:.7f} m: {hint} (or slower joint limits, or a larger "
                         "closure_tol)")


def _assemble(world, T, QS, QD, QDD, d, reason: str, row_t, v, a, tol: float, closure: float, source: str,
              period: float = 0.0, delay: float = 0.0, scale: float = 1.0) -> Trajectory:
    """The Trajectory of samples T, QS, QD, QDD with clearances d [m] (:func:`_clearance`) and the
    reason it is not certified ("" when it is: :func:`_certificate`); ``closure``: their closed-chain
    error (:func:`_closure_worst`) [m]; ``period``: the controller's cycle the samples are on [s] (0:
    sampled per piece)."""
    return Trajectory(
        t=T, q_left=QS[:, :6], q_right=QS[:, 6:], qd_left=QD[:, :6], qd_right=QD[:, 6:], qdd_left=QDD[:, :6],
        qdd_right=QDD[:, 6:], row_times=row_t, v_max=v, a_max=a, duration=float(T[-1] - T[0]), closure_tol=tol,
        closure_error=closure, velocity_ratio=float(np.max(np.abs(QD) / v)),
        acceleration_ratio=float(np.max(np.abs(QDD) / a)), min_clearance=float(d.min()), certified=not reason,
        reason=reason, limits_source=source, method=_METHOD, start_delay=delay, time_scale=scale,
        period=period)


def with_trajectory(plan, world, **kwargs):
    """``plan`` with its :attr:`~dualpuma.planning.plan.Plan.trajectory` set by :func:`time_plan`
    (same keyword arguments); exported by ``to_json`` / ``save_npz``.

    Raises:
        ParameterError: as :func:`time_plan`; a ``t_start`` other than the plan's first time (a
            plan's trajectory starts with it: :func:`time_plan` times it from another).
    """
    instance(plan, Plan, "plan")
    if kwargs.get("t_start") is not None and plan.t.shape[0] and start_time(kwargs["t_start"]) != plan.t[0]:
        raise ParameterError(f"with_trajectory: a plan's trajectory starts at its first time ({float(plan.t[0]):g} s); "
                             "time_plan(plan, world, t_start=...) times it from another")
    return dataclasses.replace(plan, trajectory=time_plan(plan, world, **kwargs))
