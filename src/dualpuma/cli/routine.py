"""``dualpuma routine N``: run one of the seed's routines 1–8 and print its outcome."""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np

from ..kinematics.dual import SIDES
from ..planning.plan_io import json_safe
from ..scenarios.routines import routine, run_routine
from ..units import display_text
from .common import add_command

__all__ = ["register", "report"]


def report(n: int, as_json: bool = False) -> str:
    """Run routine ``n``; its outcome as text, or JSON with the plan's steps (SI units)."""
    r = routine(n)
    p = run_routine(n)
    if as_json:
        d = {
            "routine": r.number, "title": r.title, "expected": r.expected, "status": p.status, "reason": p.reason,
            "deviation": r.deviation, "events": list(p.events), "path_length": p.path_length,
            "planning_time": p.planning_time, "planner": p.planner,
            "cell": {s: {"T_world_base": np.asarray(getattr(r.cell, s).T_world_base).tolist(),
                         "T_object_hand": np.asarray(getattr(r.cell, f"grasp_{s}").T_object_hand).tolist()}
                     for s in SIDES},
            "steps": [{k: st[k] for k in ("T_world_object", "q_left", "q_right", "clearance", "pair", "t")}
                      for st in p.steps()],
        }
        return json.dumps(json_safe(d), allow_nan=False)
    lines = [f"routine {r.number}: {r.title}",
             f"  status: {p.status}{' — ' + display_text(p.reason) if p.reason else ''} (seed: {r.expected})",
             (f"  {p.n_steps} step{'' if p.n_steps == 1 else 's'}, object path {p.path_length * 1e3:.0f} mm, min clearance "
              f"{p.min_clearance * 1e3:.1f} mm, planned in {p.planning_time * 1e3:.1f} ms")]
    lines += [f"  - {display_text(e)}" for e in p.events]
    if r.deviation:
        lines.append(f"  note: {r.deviation}")
    return "\n".join(lines)


def _run(args: argparse.Namespace) -> int:
    print(report(args.n, args.json))
    return 0


def register(sub: Any) -> None:
    """Add the ``routine`` command."""
    s = add_command(
        sub, "routine", "run one of the seed's routines 1-8",
        "Run one of the seed's routines 1-8 (the thesis's test programs: taught joints, translations,\n"
        "orientation changes, obstacles) and print its outcome: status, steps, object path [mm],\n"
        "minimum clearance [mm], events and the documented deviations from the seed. --json prints\n"
        "the whole plan in SI units (metres, radians; strict JSON, non-finite numbers as null).\n"
        "Exit code 0 when the routine ran, whatever its status (routine 1 ends limit_exceeded and\n"
        "routine 6 frozen, as their notes explain; unlike plan, whose 1 means the goal was missed),\n"
        "2 for bad input.",
        ("dualpuma routine 8", "dualpuma routine 2 --json"),
    )
    s.add_argument("n", type=int, choices=range(1, 9), metavar="N", help="the routine's number, 1-8")
    s.add_argument("--json", action="store_true", help="print JSON with every step")
    s.set_defaults(func=_run)
