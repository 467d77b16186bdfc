"""``dualpuma plan``: plan the bar from a cell's start pose to a goal given at the CLI edge (mm, deg)."""

from __future__ import annotations

import argparse
import json
import os
from typing import Any

import numpy as np

from ..errors import FileError, ParameterError
from ..files import atomic_write, check_writable
from ..lie import rot_to_rpy, rpy_to_rot
from ..model.cell_file import cell_from_spec
from ..planning.params import StrivingParams
from ..planning.striving import plan

__all__ = ["register"]


def _run(args: argparse.Namespace) -> int:
    cell = cell_from_spec(args.cell)
    A = cell.T_world_object_start
    B = A.copy()
    if args.to is not None:
        B[:3, 3] = np.asarray(args.to, float) / 1000.0
    if args.by is not None:
        B[:3, 3] = A[:3, 3] + np.asarray(args.by, float) / 1000.0
    if args.rpy is not None:
        B[:3, :3] = rpy_to_rot(rot_to_rpy(A[:3, :3]) + np.radians(args.rpy))
    if not np.all(np.isfinite(B)):
        raise ParameterError("goal: the coordinates must be finite numbers")
    if args.step_mm <= 0 or not np.isfinite(args.step_mm):
        raise ParameterError(f"--step-mm: expected a positive length, got {args.step_mm}")
    params = StrivingParams(step=args.step_mm / 1000.0, fallback=args.fallback)
    if args.out:  # before the work: an existing or unwritable output is refused now, not after planning
        if os.path.lexists(args.out) and not args.force:
            raise FileError(f"{args.out}: exists; pass --force to overwrite it")
        check_writable(args.out, overwrite=args.force)
    p = plan(cell, A, B, params)
    if args.out:
        if args.out.endswith(".npz"):
            p.save_npz(args.out, overwrite=args.force)
        else:
            atomic_write(args.out, p.to_json().encode("utf-8"), overwrite=args.force)
    if args.json:
        print(json.dumps({"status": p.status, "reason": p.reason, "steps": p.n_steps, "events": list(p.events),
                          "path_length_m": p.path_length, "min_clearance_m": p.min_clearance,
                          "planning_time_s": p.planning_time, "planner": p.planner}))
    else:
        print(f"{p.status}{' — ' + p.reason if p.reason else ''}")
        print(f"  {p.n_steps} steps, {p.path_length * 1e3:.0f} mm, min clearance {p.min_clearance * 1e3:.1f} mm, "
              f"{p.planning_time * 1e3:.1f} ms ({p.planner})")
        for e in p.events:
            print(f"  - {e}")
    return 0 if p.reached else 1


def register(sub: Any) -> None:
    """Add the ``plan`` command."""
    s = sub.add_parser("plan", help="plan the bar from the cell's start pose to a goal (Striving)")
    s.add_argument("--cell", default=None, help="cell TOML file or example name (default: the seed's cell)")
    g = s.add_mutually_exclusive_group(required=True)
    g.add_argument("--to", nargs=3, type=float, metavar=("X", "Y", "Z"), help="goal origin in the world [mm]")
    g.add_argument("--by", nargs=3, type=float, metavar=("DX", "DY", "DZ"), help="goal = start + offset [mm]")
    s.add_argument("--rpy", nargs=3, type=float, metavar=("R", "P", "Y"), help="rotation from the start [deg]")
    s.add_argument("--step-mm", type=float, default=50.0, help="translation step [mm] (default 50)")
    s.add_argument("--fallback", action="store_true", help="search SE(3) (RRT-Connect) if Striving freezes")
    s.add_argument("--out", default=None, help="write the plan (.json or .npz)")
    s.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    s.add_argument("--json", action="store_true")
    s.set_defaults(func=_run)
