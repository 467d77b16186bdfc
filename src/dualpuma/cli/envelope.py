"""``dualpuma envelope``: the coordinated work envelope, idealised (``--ideal``) or of a real cell."""

from __future__ import annotations

import argparse
import json
import math
import time
from typing import Any

import numpy as np

from ..envelope.ideal import ideal_envelope
from ..envelope.real import real_envelope
from ..errors import ParameterError
from ..lie import rot_to_rpy
from ..model.cell_file import cell_from_spec
from ..model.world import World
from ..planning.plan_io import json_safe
from .common import add_command

__all__ = ["register"]

_MAX_MM = 1_000_000.0  # largest ideal-model length [mm] (the model's own bound: 1000 m)


def _given(args: argparse.Namespace, dest: str) -> bool:
    return getattr(args, dest) is not None or getattr(args, f"{dest}_old") is not None


def _mm(args: argparse.Namespace, dest: str, default: float, lo: float, hi: float, lo_open: bool) -> float:
    """The flag's length in metres, checked in millimetres. The old spelling without ``-mm`` took
    metres in earlier versions: a value below 10 given with it is refused with a hint, never taken
    as mm."""
    new, old = getattr(args, dest), getattr(args, f"{dest}_old")
    name = f"--{dest.replace('_', '-')}"
    if new is not None and old is not None:
        raise ParameterError(f"{name}-mm and {name} are the same flag; give it once")
    if new is None and old is None:
        return default / 1000.0
    v, flag = (new, f"{name}-mm") if new is not None else (old, name)
    if flag == name and 0 < v < 10:
        raise ParameterError(f"{flag}: {v:g} mm? The envelope's lengths are in millimetres, no longer metres: "
                             f"e.g. {flag} {default:g} is {default / 1000:g} m; use {flag}-mm to say so explicitly")
    if not (math.isfinite(v) and (lo < v if lo_open else lo <= v) and v <= hi):
        span = f"{'(' if lo_open else '['}{lo:g}, {hi:g}]"
        raise ParameterError(f"{flag}: expected a length in {span} [mm], got {v:g}")
    return v / 1000.0


def _run(args: argparse.Namespace) -> int:
    """``dualpuma envelope``: the idealised (``--ideal``) or the real cell's work envelope.

    Prints the volumes (whole and above the shoulders' height) [m^3] and the x-z boundary polylines
    [m], as JSON with ``--json``. Options of the other model are refused (a DualpumaError, exit 2).
    """
    t0 = time.perf_counter()
    ideal_opts = any(_given(args, d) for d in ("reach", "base_distance", "bar_length"))
    real_opts = args.cell is not None or args.clearance or _given(args, "resolution")
    if args.ideal:
        if real_opts:
            raise ParameterError("--cell, --clearance and --resolution-mm apply to the real cell, not to --ideal")
        R = _mm(args, "reach", 1000.0, 0.0, _MAX_MM, True)
        D = _mm(args, "base_distance", 2500.0, 0.0, _MAX_MM, False)
        L = _mm(args, "bar_length", 1000.0, 0.0, _MAX_MM, False)
        env = ideal_envelope(R, D, L)
        seed = (R, D, L) == (1.0, 2.5, 1.0)
        out = {
            "model": "ideal",
            "reach_m": R,
            "base_distance_m": D,
            "bar_length_m": L,
            "volume_m3": env.volume_m3,
            "volume_upper_half_m3": env.volume_upper_half_m3,
            "volume_error_m3": env.volume_error_m3,
            "volume_closed_form_m3": env.volume_closed_form_m3,
            # the thesis's eq. (2.2) estimate for its example (docs/envelope.md explains the gap)
            "seed_estimate_upper_half_m3": 2.0 / 9.0 * np.pi if seed else None,
            "xz_boundary_m": [line.tolist() for line in env.boundary],
        }
    else:
        if ideal_opts:
            raise ParameterError("--reach-mm, --base-distance-mm and --bar-length-mm apply only with --ideal")
        h = _mm(args, "resolution", 25.0, 2.0, 500.0, True)
        cell = cell_from_spec(args.cell)
        world = World(cell) if args.clearance else None
        env = real_envelope(cell, h, world=world)
        out = {
            "model": "real",
            "cell": getattr(cell, "name", ""),
            "orientation": "start",
            "R_world_object": np.asarray(cell.T_world_object_start)[:3, :3].tolist(),
            "resolution_m": env.resolution,
            "volume_m3": env.volume_m3,
            "volume_upper_half_m3": env.volume_upper_half_m3,
            "z_split_m": env.z_split_m,
            "floor_excluded": env.floor,
            "clearance_checked": env.clearance_checked,
            "safety_margin_m": float(cell.safety_margin),
            "grid_points": env.grid_points,
            "points": len(env.points),
            "bounds_m": env.bounds.tolist(),
            "y_slice_m": env.y_slice_m,
            "xz_boundary_m": [line.tolist() for line in env.xz_polylines],  # (x, y_slice, z) [m]
        }
    out["time_s"] = time.perf_counter() - t0
    if args.json:
        print(json.dumps(json_safe(out), indent=2, allow_nan=False))
    else:
        print("\n".join(_text(out)))
    return 0


def _text(out: dict[str, Any]) -> list[str]:
    """The human summary of ``out`` (the --json record, SI): lengths in mm, angles in degrees,
    volumes in m^3."""

    def mm(v: float) -> str:
        return f"{v * 1e3:.0f}"

    lines = out["xz_boundary_m"]
    pts = f"{len(lines)} polylines, {sum(len(line) for line in lines)} points (--json for the points)"
    if out["model"] == "ideal":
        cf = out["volume_closed_form_m3"]
        closed = "" if cf is None else f"; closed form {cf:.6f} m³"
        text = [
            (f"ideal work envelope: reach {mm(out['reach_m'])} mm, base distance {mm(out['base_distance_m'])} mm, "
             f"bar length {mm(out['bar_length_m'])} mm"),
            (f"  volume {out['volume_m3']:.6f} m³ (numerical error {out['volume_error_m3']:.1e} m³{closed}), "
             f"upper half {out['volume_upper_half_m3']:.6f} m³"),
        ]
        if out["seed_estimate_upper_half_m3"] is not None:
            text.append(f"  the seed's estimate of the upper half (eq. 2.2): {out['seed_estimate_upper_half_m3']:.6f} m³")
        text.append(f"  x–z boundary: {pts}")
    else:
        roll, pitch, yaw = (round(float(v), 1) + 0.0 for v in np.degrees(rot_to_rpy(np.asarray(out["R_world_object"]))))
        (x0, x1), (y0, y1), (z0, z1) = out["bounds_m"]
        floor = "excluded" if out["floor_excluded"] else "ignored"
        clearance = (f"of at least the cell's margin, {out['safety_margin_m'] * 1e3:g} mm, required" if out["clearance_checked"]
                     else "not checked (--clearance)")
        text = [
            (f"real work envelope of the cell '{out['cell']}', the bar at its start orientation "
             f"(roll {roll:.1f}, pitch {pitch:.1f}, yaw {yaw:.1f} deg)"),
            f"  volume {out['volume_m3']:.4f} m³, above z = {mm(out['z_split_m'])} mm {out['volume_upper_half_m3']:.4f} m³",
            (f"  {out['points']:,} of {out['grid_points']:,} grid points on a {mm(out['resolution_m'])} mm grid; "
             f"floor {floor}; clearance {clearance}"),
            f"  bounds: x {mm(x0)}..{mm(x1)} mm, y {mm(y0)}..{mm(y1)} mm, z {mm(z0)}..{mm(z1)} mm",
            f"  x–z boundary at y = {mm(out['y_slice_m'])} mm: {pts}",
        ]
    text.append(f"  {out['time_s']:.2f} s")
    return text


def register(sub: Any) -> None:
    """Add the ``envelope`` command."""
    s = add_command(
        sub, "envelope", "coordinated work envelope volume (lengths in mm)",
        "The coordinated work envelope: where both arms can hold the bar together. --ideal: the\n"
        "seed's idealised model (spherical reach R, bases D apart, bar of length L; defaults: the\n"
        "thesis's example R = 1000, D = 2500, L = 1000 mm); otherwise a real cell (closed-form IK,\n"
        "joint limits, floor; --clearance also requires the safety margin), sampled on a grid.\n"
        "Lengths are given in millimetres (the old flags --reach, --base-distance, --bar-length and\n"
        "--resolution are the same flags: --reach 1000 is 1 m; a value below 10 with them is refused).\n"
        "Printed in millimetres and degrees (volumes in m^3); --json is SI: lengths [m], volumes [m^3].",
        ("dualpuma envelope --ideal", ("dualpuma envelope --ideal --reach-mm 1000 --base-distance-mm 2500 "
         "--bar-length-mm 1000 --json"), "dualpuma envelope --cell agv --resolution-mm 40 --clearance"),
    )
    s.add_argument("--ideal", action="store_true", help="the seed's idealised model (spherical reach)")
    for dest, what, default in (("reach", "reach radius R", 1000), ("base_distance", "base distance D", 2500),
                                ("bar_length", "bar length L", 1000)):
        flag = f"--{dest.replace('_', '-')}"
        s.add_argument(f"{flag}-mm", dest=dest, type=float, metavar="MM", help=f"{what} [mm] (ideal; default {default})")
        s.add_argument(flag, dest=f"{dest}_old", type=float, metavar="MM", help=f"the same as {flag}-mm")
    s.add_argument("--cell", default=None, help="cell TOML file or example name (real model; a file named like an example: ./NAME)")
    s.add_argument("--resolution-mm", dest="resolution", type=float, metavar="MM",
                   help="grid spacing [mm] in (2, 500] (real model; default 25)")
    s.add_argument("--resolution", dest="resolution_old", type=float, metavar="MM", help="the same as --resolution-mm")
    s.add_argument("--clearance", action="store_true", help="also require clearance (real model, slow)")
    s.add_argument("--json", action="store_true", help="print JSON")
    s.set_defaults(func=_run)
