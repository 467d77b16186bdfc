"""The ``dualpuma`` command: serve / fk / ik / envelope / routine / plan."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

import numpy as np

from .errors import DualpumaError

__all__ = ["main"]


def _floats(text: str, n: int, what: str) -> np.ndarray:
    try:
        vals = [float(v) for v in text.replace(",", " ").split()]
    except ValueError as exc:
        raise DualpumaError(f"{what}: expected {n} numbers, got {text!r}") from exc
    if len(vals) != n:
        raise DualpumaError(f"{what}: expected {n} numbers, got {len(vals)}")
    return np.array(vals)


def _cmd_fk(args: argparse.Namespace) -> int:
    from . import puma
    from .arm import Arm

    arm = Arm.load(args.robot)
    q = np.deg2rad(_floats(args.q, 6, "--q [deg]"))
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
    print(json.dumps(out, indent=2) if args.json else _fmt_pose(out))
    return 0


def _fmt_pose(out: dict) -> str:
    lines = [f"{out['robot']} frame {out['frame']!r} at q = {np.round(out['q_deg'], 3).tolist()} deg"]
    for row in np.asarray(out["T_base_frame"]):
        lines.append("  " + " ".join(f"{v:10.6f}" for v in row))
    if "branch" in out:
        lines.append(f"  branch: {out['branch']}")
    return "\n".join(lines)


def _cmd_ik(args: argparse.Namespace) -> int:
    from . import puma

    p = _floats(args.xyz, 3, "--xyz [mm]") / 1000.0
    rpy = np.deg2rad(_floats(args.rpy, 3, "--rpy [deg]"))
    import pinocchio as pin

    T = np.eye(4)
    T[:3, :3] = pin.rpy.rpyToMatrix(*rpy)
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


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="dualpuma", description="Two PUMA 560 arms carrying one bar.")
    sub = p.add_subparsers(dest="cmd", required=True)

    s = sub.add_parser("fk", help="forward kinematics of one arm (angles in degrees)")
    s.add_argument("--robot", default="puma560")
    s.add_argument("--q", default="0 0 0 0 0 0", help="six joint angles [deg]")
    s.add_argument("--frame", default=None, help="frame name (default: the hand)")
    s.add_argument("--json", action="store_true")
    s.set_defaults(func=_cmd_fk)

    s = sub.add_parser("ik", help="all eight PUMA IK branches for a wrist pose")
    s.add_argument("--xyz", required=True, help="wrist centre in the shoulder frame [mm]")
    s.add_argument("--rpy", default="0 0 0", help="roll pitch yaw [deg]")
    s.add_argument("--json", action="store_true")
    s.set_defaults(func=_cmd_ik)
    _add_more_commands(sub)
    return p


def _add_more_commands(sub: argparse._SubParsersAction) -> None:
    """Commands of the other modules (serve, envelope, routine, plan), registered when present."""
    from importlib import import_module

    for mod in ("cli_more", "cli_plan"):
        try:
            m = import_module(f"dualpuma.{mod}")
        except ImportError:  # pragma: no cover - module not built yet
            continue
        m.register(sub)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except DualpumaError as exc:
        print(f"dualpuma {args.cmd}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
