"""``dualpuma ik``: all eight PUMA IK branches for a wrist pose (mm and degrees)."""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np

from ..kinematics import puma
from ..lie import rpy_to_rot
from .common import floats

__all__ = ["register"]


def _run(args: argparse.Namespace) -> int:
    p = floats(args.xyz, 3, "--xyz [mm]") / 1000.0
    rpy = np.deg2rad(floats(args.rpy, 3, "--rpy [deg]"))
    T = np.eye(4)
    T[:3, :3] = rpy_to_rot(rpy)
    T[:3, 3] = p
    sols, valid = puma.ik_all(T)
    rows = [
        {"branch": name, "valid": bool(v), "q_deg": None if np.isnan(s).any() else np.rad2deg(s).round(6).tolist()}
        for name, s, v in zip(puma.BRANCH_NAMES, sols, valid)
    ]
    if args.json:
        print(json.dumps({"T_base_wrist": T.tolist(), "solutions": rows}, indent=2))
    else:
        print(f"PUMA 560 wrist at {np.round(p * 1000, 3).tolist()} mm, rpy {np.round(np.rad2deg(rpy), 3).tolist()} deg:")
        for r in rows:
            q = "unreachable" if r["q_deg"] is None else " ".join(f"{a:9.3f}" for a in r["q_deg"])
            print(f"  {r['branch']:<18} {'ok ' if r['valid'] else 'no '} {q}")
    return 0


def register(sub: Any) -> None:
    """Add the ``ik`` command."""
    s = sub.add_parser("ik", help="all eight PUMA IK branches for a wrist pose")
    s.add_argument("--xyz", required=True, help="wrist centre in the shoulder frame [mm]")
    s.add_argument("--rpy", default="0 0 0", help="roll pitch yaw [deg]")
    s.add_argument("--json", action="store_true")
    s.set_defaults(func=_run)
