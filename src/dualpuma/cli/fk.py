"""``dualpuma fk``: forward kinematics of one arm (joint angles in degrees, positions in mm)."""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np

from ..kinematics import puma
from ..kinematics.arm import Arm
from .common import floats

__all__ = ["register"]


def _run(args: argparse.Namespace) -> int:
    arm = Arm.load(args.robot)
    q = np.deg2rad(floats(args.q, 6, "--q [deg]"))
    T = arm.fk(q, args.frame)
    out = {
        "robot": arm.robot,
        "frame": args.frame or arm.hand_frame,
        "q_deg": np.rad2deg(q).tolist(),
        "T_base_frame": T.tolist(),
        "position_mm": (T[:3, 3] * 1000).tolist(),
    }
    if arm.analytic:
        out["branch"] = puma.BRANCH_NAMES[int(puma.branch_of(q))]
    print(json.dumps(out, indent=2) if args.json else _text(out))
    return 0


def _text(out: dict) -> str:
    lines = [f"{out['robot']} frame {out['frame']!r} at q = {np.round(out['q_deg'], 3).tolist()} deg"]
    for row in np.asarray(out["T_base_frame"]):
        lines.append("  " + " ".join(f"{v:10.6f}" for v in row))
    if "branch" in out:
        lines.append(f"  branch: {out['branch']}")
    return "\n".join(lines)


def register(sub: Any) -> None:
    """Add the ``fk`` command."""
    s = sub.add_parser("fk", help="forward kinematics of one arm (angles in degrees)")
    s.add_argument("--robot", default="puma560")
    s.add_argument("--q", default="0 0 0 0 0 0", help="six joint angles [deg]")
    s.add_argument("--frame", default=None, help="frame name (default: the hand)")
    s.add_argument("--json", action="store_true")
    s.set_defaults(func=_run)
