"""``dualpuma plan``: plan the bar from a cell's start pose to a goal given at the CLI edge (mm, deg)."""

from __future__ import annotations

import argparse
import json
import math
from typing import Any

import numpy as np

from ..collision.contact import unmapped_sides
from ..errors import ParameterError
from ..files import atomic_write
from ..lie import rot_to_rpy, rpy_to_rot
from ..model.cell_file import EXAMPLE_CELLS, cell_from_spec
from ..model.world import World
from ..planning.params import MAX_STEP, MAX_TIME_LIMIT, MIN_STEP, FallbackParams, StrivingParams
from ..planning.plan_io import json_safe
from ..planning.rate_limits import JOINT_LIMIT_RANGE
from ..planning.striving import plan
from ..planning.timing import (
    DT,
    MAX_SLOWDOWN,
    MAX_WAIT,
    PERIOD_RANGE,
    SLOWDOWN_RANGE,
    WAIT_RANGE,
    with_trajectory,
)
from ..units import display_text
from .common import add_command, add_vector, angles, check_output, vector

__all__ = ["register"]


def _limits(values: list[str], what: str, unit: str) -> np.ndarray:
    """6 values (both arms) or 12 (left then right) in degrees (per s or s^2: ``unit``) within
    :data:`~dualpuma.planning.rate_limits.JOINT_LIMIT_RANGE` (given in radians): the limits [rad/...]."""
    n = len(" ".join(values).replace(",", " ").split())
    if n not in (6, 12):
        raise ParameterError(f"{what}: expected 6 numbers (both arms) or 12 (left then right), got {n}")
    v = vector(values, n, what)
    lo, hi = np.degrees(JOINT_LIMIT_RANGE)
    lo, hi = math.ceil(lo * 1e4) / 1e4, math.floor(hi * 10.0) / 10.0  # as shown, rounded inwards: what it says, it takes
    if np.any(v < lo) or np.any(v > hi):
        raise ParameterError(f"{what}: limits must be in [{lo:g}, {hi:.1f}] {unit}, got {v.tolist()}"[:300])
    return np.radians(v)


def _run(args: argparse.Namespace) -> int:
    check_output(args.out, args.force)  # before the work: an unwritable output is refused now, not after planning
    if not (math.isfinite(args.step_mm) and MIN_STEP * 1000.0 <= args.step_mm <= MAX_STEP * 1000.0):
        raise ParameterError(f"--step-mm: expected a length in [{MIN_STEP * 1000.0:g}, {MAX_STEP * 1000.0:g}] [mm], "
                             f"got {args.step_mm}")
    if not (math.isfinite(args.step_time) and 0 < args.step_time <= 3600):
        raise ParameterError(f"--step-time: expected a time in (0, 3600] [s], got {args.step_time}")
    if args.time_limit is not None:
        if not args.fallback:
            raise ParameterError("--time-limit: it limits the SE(3) fallback search: give --fallback too")
        if not (math.isfinite(args.time_limit) and 0 < args.time_limit <= MAX_TIME_LIMIT):
            raise ParameterError(f"--time-limit: expected a time in (0, {MAX_TIME_LIMIT:g}] [s], got {args.time_limit}")
    cell = cell_from_spec(args.cell)
    A = cell.T_world_object_start
    B = A.copy()
    if args.to is not None:
        B[:3, 3] = vector(args.to, 3, "--to [mm]") / 1000.0
    if args.by is not None:
        B[:3, 3] = A[:3, 3] + vector(args.by, 3, "--by [mm]") / 1000.0
    if args.rpy is not None:
        B[:3, :3] = rpy_to_rot(rot_to_rpy(A[:3, :3]) + np.radians(angles(args.rpy, 3, "--rpy")))
    timing = {"--v-max": args.v_max, "--a-max": args.a_max, "--max-wait": args.max_wait,
              "--max-slowdown": args.max_slowdown, "--period": args.period}
    if not args.trajectory and any(v is not None for v in timing.values()):
        raise ParameterError(f"{', '.join(k for k, v in timing.items() if v is not None)}: these time the plan: "
                             "give --trajectory too")
    for flag, value, (lo, hi), what in (("--max-wait", args.max_wait, WAIT_RANGE, "a time [s]"),
                                        ("--max-slowdown", args.max_slowdown, SLOWDOWN_RANGE, "a factor"),
                                        ("--period", args.period, PERIOD_RANGE, "a controller cycle [s]")):
        if value is not None and not (math.isfinite(value) and lo <= value <= hi):
            raise ParameterError(f"{flag}: expected {what} in [{lo:g}, {hi:g}], got {value}")
    v_max = None if args.v_max is None else _limits(args.v_max, "--v-max", "deg/s")
    a_max = None if args.a_max is None else _limits(args.a_max, "--a-max", "deg/s^2")
    step = args.step_mm / 1000.0  # and Striving's shortest step no longer than it
    params = StrivingParams(step=step, min_step=min(StrivingParams().min_step, step), step_time=args.step_time,
                            fallback=args.fallback,
                            fallback_params=None if args.time_limit is None else FallbackParams(time_limit=args.time_limit))
    world = World(cell)
    p = plan(cell, A, B, params, world=world)
    if args.trajectory and p.reached:
        extra = {k: v for k, v in (("max_wait", args.max_wait), ("max_slowdown", args.max_slowdown),
                                   ("period", args.period)) if v is not None}
        p = with_trajectory(p, world, v_max=v_max, a_max=a_max, **extra)
    if args.out is not None:
        if args.out.lower().endswith(".npz"):
            p.save_npz(args.out, overwrite=args.force)
        else:
            atomic_write(args.out, p.to_json().encode("utf-8"), overwrite=args.force)
    tr = p.trajectory
    # moving obstacles were met on the plan's clock, which the arms need not keep: only the timed
    # motion checks them at real times (a box at 0.5 m/s: 46.5 mm on the clock, 17.7 mm timed)
    untimed = (f"the cell's moving obstacles were checked on the plan's clock ({args.step_time:g} s per step), "
               "which the arms may not keep: --trajectory checks them at the timed motion's real times"
               if world.moving and tr is None and p.reached else "")
    unmapped = unmapped_sides(world)  # an arm whose always-close link pairs have no contact map
    whose = "arms'" if len(unmapped) > 1 else "arm's"
    unchecked = (f"the {' and '.join(unmapped)} {whose} always-close link pairs "
                 "two joints apart are not checked on their meshes (no contact map: docs/robots.md)" if unmapped else "")
    warnings = [w for w in (untimed, unchecked) if w]
    if args.json:
        out = {"status": p.status, "reason": p.reason, "steps": p.n_steps, "events": list(p.events),
               "path_length_m": p.path_length, "min_clearance_m": p.min_clearance,
               "planning_time_s": p.planning_time, "planner": p.planner, "step_time_s": args.step_time,
               "warnings": warnings}
        if args.trajectory:
            out["trajectory"] = None if tr is None else tr.to_dict()
        print(json.dumps(json_safe(out), allow_nan=False))
    else:
        print(f"{p.status}{' — ' + display_text(p.reason) if p.reason else ''}")
        print(f"  {p.n_steps} step{'' if p.n_steps == 1 else 's'}, {p.path_length * 1e3:.0f} mm, min clearance {p.min_clearance * 1e3:.1f} mm, "
              f"{p.planning_time * 1e3:.1f} ms ({p.planner})")
        if tr is not None:
            every = f" every {tr.period:g} s" if tr.period else ""
            print(f"  timed: {tr.duration:.2f} s{' (' + tr.retimed + ')' if tr.retimed else ''}, {tr.n_samples} samples{every}, "
                  f"closed-chain error "
                  f"{tr.closure_error * 1e3:.3f} mm (tolerance {tr.closure_tol * 1e3:.1f} mm), peak "
                  f"{tr.velocity_ratio * 100:.0f} % of the velocity and {tr.acceleration_ratio * 100:.0f} % of the "
                  f"acceleration limits, " + ("certified" if tr.certified else f"NOT certified: {display_text(tr.reason)}"))
        for e in p.events:
            print(f"  - {display_text(e)}")
        if p.status == "frozen" and not args.fallback:
            print("  (Striving froze: --fallback searches SE(3) with RRT-Connect from where it stopped)")
        for w in warnings:
            print(f"  ({w})")
        if tr is not None and not tr.certified and "step_time" in tr.reason:
            print(f"  (--step-time sets step_time: {args.step_time:g} s now)")
    if tr is not None and not tr.certified:
        return 1  # planned, but its timed motion does not keep the margin (moving obstacles met at real speed)
    return 0 if p.reached else 1


def register(sub: Any) -> None:
    """Add the ``plan`` command."""
    s = add_command(
        sub, "plan", "plan the bar from the cell's start pose to a goal (Striving; mm, degrees)",
        "Plan the held bar from the cell's start pose to a goal with the Striving planner (and the\n"
        "SE(3) RRT-Connect fallback with --fallback). The goal is an absolute origin (--to) or an\n"
        "offset from the start (--by) [mm], optionally turned by roll-pitch-yaw angles from the\n"
        "start's (--rpy) [deg]. --trajectory times the plan for execution (both arms, one time law,\n"
        "closed-chain error below 0.5 mm; the PUMA 560's nominal joint limits, a URDF's velocity\n"
        "limits, or --v-max/--a-max [deg/s, deg/s^2]) and puts it in --json and --out.\n"
        "Exit code 0 if the goal is reached (and its trajectory certified), 1 if not (the status says\n"
        "why), 2 for bad input; an --out file that exists or cannot be written is refused before planning.",
        ("dualpuma plan --by -200 0 100 --rpy 0 0 -10", ("dualpuma plan --cell routine7_box --to 1500 -200 475 "
         "--fallback --out plan.npz"), "dualpuma plan --by '-200,0,100' --fallback --json --out plan.json --force",
         "dualpuma plan --by -100 -50 50 --trajectory --out timed.npz",
         "dualpuma plan --by -100 -50 50 --trajectory --period 0.004 --json",
         "dualpuma plan --cell mixed_puma_ur5 --by -100 0 50 --trajectory --a-max 45 40 75 70 90 80"),
    )
    s.add_argument("--cell", default=None,
                   help=f"cell TOML file or example name ({', '.join(EXAMPLE_CELLS)}; default: the seed's cell; a file "
                        "named like an example: ./NAME)")
    g = s.add_mutually_exclusive_group(required=True)
    add_vector(s, "--to", 3, "mm", "goal origin in the world", group=g)
    add_vector(s, "--by", 3, "mm", "goal = start + offset", group=g)
    add_vector(s, "--rpy", 3, "deg", "rotation from the start's roll-pitch-yaw")
    s.add_argument("--step-mm", type=float, default=50.0, help="translation step [mm] (default 50)")
    step_time = StrivingParams().step_time
    s.add_argument("--step-time", type=float, default=step_time, metavar="S",
                   help=f"the plan's clock: time per step [s] at which moving obstacles are checked (default "
                        f"{step_time:g}; longer when the timed motion says the arms cannot keep it)")
    s.add_argument("--fallback", action="store_true",
                   help="search SE(3) (RRT-Connect) if Striving freezes or stops making progress")
    s.add_argument("--time-limit", type=float, default=None, metavar="S",
                   help="give the fallback search up after this many seconds [s] (default: no limit, "
                        f"{FallbackParams().max_iterations} iterations)")
    s.add_argument("--out", default=None, help="write the plan: .npz (any case), else strict JSON (refused if it exists)")
    s.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    s.add_argument("--trajectory", action="store_true",
                   help="time the plan for execution; include it in --json and --out")
    s.add_argument("--v-max", nargs="+", default=None, metavar="DEG_S",
                   help="joint velocity limits [deg/s]: 6 values for both arms or 12 (left then right)")
    s.add_argument("--a-max", nargs="+", default=None, metavar="DEG_S2",
                   help="joint acceleration limits [deg/s^2]: 6 or 12 values (needed for arms other than the PUMA)")
    s.add_argument("--max-wait", type=float, default=None, metavar="S",
                   help=f"longest wait at the start the timing may add to let a moving obstacle pass [s] "
                        f"(default {MAX_WAIT:g}; 0 = never wait)")
    s.add_argument("--max-slowdown", type=float, default=None, metavar="X",
                   help=f"largest uniform slowdown the timing may use for the same [>= 1] (default {MAX_SLOWDOWN:g})")
    s.add_argument("--period", type=float, default=None, metavar="S",
                   help=f"sample the trajectory on a joint controller's fixed cycle [s]: every sample exactly this "
                        f"long after the previous one (e.g. 0.004 for 250 Hz; default: at most {DT:g} s apart)")
    s.add_argument("--json", action="store_true", help="print a JSON summary")
    s.set_defaults(func=_run)
