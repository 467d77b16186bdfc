"""Teach pendant in the browser (the seed's Appendix 2, in 3-D): joint sliders, Cartesian jog of the
selected hand, coordinated object-frame control (sliders or a gizmo), read-outs, and taught
waypoints (record, play through the planner, save/load). Callbacks only record intent in
:class:`~dualpuma.viewer.app.ViewerApp`'s state; the app's loop does the kinematics."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..checks import validate_pose
from ..errors import ParameterError
from ..lie import pose_from_wxyz, rot_to_rpy, rpy_to_rot

__all__ = ["TeachPanel", "load_waypoints", "save_waypoints"]

_AXES = ("x", "y", "z", "roll", "pitch", "yaw")


def save_waypoints(path: str | Path, poses: list[np.ndarray], overwrite: bool = False) -> Path:
    """Write taught object poses (4x4, metres) as JSON; refuses to overwrite unless asked."""
    p = Path(path)
    if p.exists() and not overwrite:
        raise ParameterError(f"{p}: exists; tick 'overwrite' (or pass overwrite=True) to replace it")
    data = {"format": "dualpuma.waypoints/1", "units": "m", "T_world_object": [np.asarray(T).tolist() for T in poses]}
    tmp = p.with_name(p.name + ".tmp")
    tmp.write_text(json.dumps(data))
    tmp.replace(p)
    return p


def load_waypoints(path: str | Path) -> list[np.ndarray]:
    """Read a waypoint file written by :func:`save_waypoints` (poses validated)."""
    p = Path(path)
    try:
        data = json.loads(p.read_text())
        if data.get("format") != "dualpuma.waypoints/1":
            raise ParameterError(f"{p}: not a dualpuma waypoint file")
        return [validate_pose(T, name=f"{p}: waypoint {i}") for i, T in enumerate(data["T_world_object"])]
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as e:
        raise ParameterError(f"{p}: cannot read waypoints: {e}") from e


class TeachPanel:
    """GUI of the teach pendant; ``app`` is the ViewerApp whose state it edits."""

    def __init__(self, app) -> None:
        self.app = app
        g = app.server.gui
        self.mode = g.add_dropdown("mode", ("joint", "coordinated"), initial_value="joint")
        self.mode.on_update(lambda _: app.set_mode(self.mode.value))
        self.robot = g.add_dropdown("robot", ("left", "right"), initial_value="left")
        self.sliders: dict[tuple[str, int], object] = {}
        for side in ("left", "right"):
            lim = np.rad2deg(app.world.arms[side].limits)
            with g.add_folder(f"{side} arm joints [deg]", expand_by_default=(side == "left")):
                for j in range(6):
                    sl = g.add_slider(f"{side} q{j + 1}", min=float(lim[j, 0]), max=float(lim[j, 1]), step=0.1,
                                      initial_value=float(np.rad2deg(app.q[side][j])))
                    sl.on_update(lambda ev, side=side, j=j: app.set_joint_deg(side, j, ev.target.value))
                    self.sliders[(side, j)] = sl
        with g.add_folder("Cartesian jog (selected robot)"):
            self.jog_mm = g.add_number("step [mm]", initial_value=10.0, min=0.1, max=200.0, step=0.1)
            self.jog_deg = g.add_number("step [deg]", initial_value=5.0, min=0.1, max=90.0, step=0.1)
            self.jog_buttons = {}
            for axis in _AXES:
                for sign in (-1, 1):
                    b = g.add_button(f"{'+' if sign > 0 else '-'}{axis}")
                    b.on_click(lambda _, axis=axis, sign=sign: self.jog(axis, sign))
                    self.jog_buttons[(axis, sign)] = b
        with g.add_folder("object frame (coordinated)"):
            T0 = app.cell.T_world_object_start
            r0 = np.rad2deg(rot_to_rpy(T0[:3, :3]))
            init = dict(zip(_AXES, list(T0[:3, 3] * 1000.0) + list(r0)))
            self.obj = {}
            for k in _AXES:
                lo, hi = (init[k] - 600, init[k] + 600) if k in "xyz" else (init[k] - 180, init[k] + 180)
                s = g.add_slider(f"object {k} [{'mm' if k in 'xyz' else 'deg'}]", min=lo, max=hi, step=1.0 if k in "xyz" else 0.5,
                                 initial_value=float(init[k]))
                s.on_update(lambda _: self._object_from_sliders())
                self.obj[k] = s
            self.gizmo_on = g.add_checkbox("object gizmo", initial_value=False)
        self.gizmo = app.server.scene.add_transform_controls("/object_gizmo", scale=0.25, position=tuple(T0[:3, 3]),
                                                             visible=False)
        self.gizmo_on.on_update(self._show_gizmo)
        self.gizmo.on_update(lambda _: self._object_from_gizmo())
        with g.add_folder("taught waypoints"):
            self.record = g.add_button("record waypoint")
            self.record.on_click(lambda _: app.record_waypoint())
            self.clear = g.add_button("clear waypoints")
            self.clear.on_click(lambda _: app.clear_waypoints())
            self.play = g.add_button("play waypoints (planner)")
            self.play.on_click(lambda _: app.plan_waypoints())
            self.path = g.add_text("file", initial_value="waypoints.json")
            self.overwrite = g.add_checkbox("overwrite", initial_value=False)
            self.save = g.add_button("save")
            self.save.on_click(lambda _: app.save_waypoints(self.path.value, self.overwrite.value))
            self.load = g.add_button("load")
            self.load.on_click(lambda _: app.load_waypoints(self.path.value))
            self.count = g.add_markdown("0 waypoints")

    # ---------------------------------------------------------------- intents
    def jog(self, axis: str, sign: int) -> None:
        """Request a Cartesian jog of the selected hand (world axes; rotations about the hand)."""
        d = np.eye(4)
        if axis in "xyz":
            d[:3, 3] = np.eye(3)["xyz".index(axis)] * sign * float(self.jog_mm.value) / 1000.0
            frame = "world"
        else:
            rpy = np.zeros(3)
            rpy[_AXES.index(axis) - 3] = sign * np.radians(float(self.jog_deg.value))
            d[:3, :3] = rpy_to_rot(rpy)
            frame = "hand"
        self.app.request_jog(self.robot.value, d, frame)

    def object_target(self) -> np.ndarray:
        """The object pose the sliders describe (4x4, metres)."""
        T = np.eye(4)
        T[:3, 3] = [self.obj[k].value / 1000.0 for k in "xyz"]
        T[:3, :3] = rpy_to_rot(np.radians([self.obj[k].value for k in ("roll", "pitch", "yaw")]))
        return T

    def _object_from_sliders(self) -> None:
        if not self.app.syncing:
            self.app.request_object(self.object_target())

    def _show_gizmo(self, _event=None) -> None:
        self.gizmo.visible = bool(self.gizmo_on.value)

    def _object_from_gizmo(self) -> None:
        self.app.request_object(pose_from_wxyz(self.gizmo.wxyz, self.gizmo.position))

    def show_object(self, T: np.ndarray) -> None:
        """Reflect the current object pose on the sliders (called by the loop; no new intent)."""
        vals = list(T[:3, 3] * 1000.0) + list(np.rad2deg(rot_to_rpy(T[:3, :3])))
        for k, v in zip(_AXES, vals):
            s = self.obj[k]
            if k not in "xyz":  # angles: the equivalent value inside the slider's 360 deg window
                v = s.min + (v - s.min) % 360.0
            s.value = float(np.clip(v, s.min, s.max))
