"""``dualpuma fk``: forward kinematics of one arm (joint angles in degrees, positions in mm)."""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np

from ..kinematics import BRANCH_NAMES, KNOWN_ROBOTS, Arm
from ..kinematics.limits import LIMIT_TOL
from ..lie import rot_to_rpy
from .common import add_command, add_vector, angles

__all__ = ["register"]


def _num(v: float) -> str:
    """A number in fixed point with 10 decimals, trailing zeros cut: read back to 1e-10 (mm or deg)
    and never in exponent form (argparse would take ``-1e-13`` for an option)."""
    s = f"{v:.10f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def _run(args: argparse.Namespace) -> int:
    arm = Arm.load(args.robot)
    q_deg = angles(args.q, 6, "--q")
    q = np.deg2rad(q_deg)
    T = arm.fk(q, args.frame)
    frame = args.frame or arm.hand_frame
    pos_mm = T[:3, 3] * 1000.0
    rpy_deg = np.rad2deg(rot_to_rpy(T[:3, :3]))
    out: dict[str, Any] = {
        "robot": arm.robot,
        "frame": frame,
        "q_deg": np.rad2deg(q).tolist(),
        "position_mm": pos_mm.tolist(),
        "rpy_deg": rpy_deg.tolist(),  # R = Rz(yaw) Ry(pitch) Rx(roll), as ik --rpy takes it
        "T_base_frame": T.tolist(),  # [m]
    }
    lim = arm.limits
    outside = [j for j in range(6) if not lim[j, 0] - LIMIT_TOL <= q[j] <= lim[j, 1] + LIMIT_TOL]
    # the pose is computed all the same (fk is geometry), but the arm cannot take these joints
    out["outside_limits"] = [{"joint": j + 1, "q_deg": float(q_deg[j]), "limits_deg": np.rad2deg(lim[j]).tolist()}
                             for j in outside]
    if arm.analytic:
        out["branch"] = BRANCH_NAMES[arm.branch_of(q)]
    if frame == arm.hand_frame:  # the hand (the PUMA's wrist centre): what ik solves for
        robot = "" if arm.robot == "puma560" else f"--robot {arm.robot} "
        out["ik_command"] = (f"dualpuma ik {robot}--xyz " + " ".join(map(_num, pos_mm)) + " --rpy "
                             + " ".join(map(_num, rpy_deg)))
    print(json.dumps(out, indent=2) if args.json else _text(out))
    return 0


def _text(out: dict) -> str:
    lines = [(f"{out['robot']}: frame {out['frame']!r} in the base frame at q = "
             f"{' '.join(_num(round(v, 9)) for v in out['q_deg'])} deg"),
             "  position [mm]:  " + "  ".join(f"{a} = {_num(v)}" for a, v in zip("xyz", out["position_mm"])),
             "  rpy [deg]:      " + "  ".join(f"{a} = {_num(v)}" for a, v in
                                              zip(("roll", "pitch", "yaw"), out["rpy_deg"]))
             + "   (R = Rz(yaw) Ry(pitch) Rx(roll))",
             "  T_base_frame [m]:"]
    for row in np.asarray(out["T_base_frame"]):
        lines.append("    " + " ".join(f"{v:10.6f}" for v in row))
    for o in out["outside_limits"]:
        lo, hi = o["limits_deg"]
        lines.append(f"  note: q{o['joint']} = {_num(round(o['q_deg'], 9))} deg is outside its limits "
                     f"[{_num(round(lo, 3))}, {_num(round(hi, 3))}] deg (the pose is computed all the same)")
    if "branch" in out:
        lines.append(f"  branch: {out['branch']}")
    if "ik_command" in out:
        lines.append(f"  back to joints: {out['ik_command']}")
    return "\n".join(lines)


def register(sub: Any) -> None:
    """Add the ``fk`` command."""
    s = add_command(
        sub, "fk", "forward kinematics of one arm (degrees in; mm, degrees and metres out)",
        "Forward kinematics of one arm: the pose of a frame (default the hand; the PUMA 560's wrist\n"
        "centre) in the arm's base frame, as a position [mm], roll-pitch-yaw angles [deg] (the form\n"
        "'dualpuma ik' takes: its command line is printed) and the 4x4 transform [m].",
        ("dualpuma fk --q 10 20 30 0 45 0", "dualpuma fk --q '10,20,30,0,45,0' --json",
         "dualpuma fk --robot ur5 --q 0 -90 90 0 90 0 --frame tool0"),
    )
    s.add_argument("--robot", default="puma560", help=f"the arm: {', '.join(KNOWN_ROBOTS)} (default puma560)")
    add_vector(s, "--q", 6, "deg", "joint angles", default=(0, 0, 0, 0, 0, 0))
    s.add_argument("--frame", default=None, help="frame name (default: the hand)")
    s.add_argument("--json", action="store_true", help="print JSON")
    s.set_defaults(func=_run)
