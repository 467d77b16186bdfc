"""The teach tab: joint sliders of both arms, Cartesian jog, the object frame by numbers or a gizmo,
Home and Undo, taught waypoints, and a compact read-out.

Grasp-keeping (see :mod:`.teach_moves`): moving the object moves both arms; moving a joint of one
arm moves the object with that hand and the partner arm follows to keep its grasp; a jog moves the
object or one hand (the other following). The object gizmo sits on the object frame, with its
orientation, and follows it.

The controls only record intents (:class:`~dualpuma.viewer.controls.Controls`); :meth:`TeachPanel.apply`
runs in the app's loop, validates the value and asks the app to change its pose; :meth:`TeachPanel.show`
writes the state back to the controls.
"""

from __future__ import annotations

import math

import numpy as np

from ..kinematics import BRANCH_NAMES
from ..lie import pose_from_wxyz, quaternion_wxyz, rot_to_rpy, rpy_to_rot
from .intents import Intent, Refused, choice, number
from .teach_moves import home_pose, jog_target, move_joint, move_object

__all__ = ["JOG_FRAMES", "MOVE_BUTTONS", "OBJECT_AXES", "TURN_BUTTONS", "TeachPanel", "gizmo_pose", "pose_numbers",
           "with_number"]

OBJECT_AXES = ("x", "y", "z", "roll", "pitch", "yaw")
MOVE_BUTTONS = ("-x", "+x", "-y", "+y", "-z", "+z")
TURN_BUTTONS = ("-rx", "+rx", "-ry", "+ry", "-rz", "+rz")
JOG_FRAMES = ("object", "left hand", "right hand")
_OBJECT_RANGE_MM = 5000.0  # object numbers beyond +-5 m are refused, not clamped


def pose_numbers(T: np.ndarray) -> list[float]:
    """x, y, z [mm] and roll, pitch, yaw [deg] of a pose (the number boxes)."""
    return [float(v) for v in T[:3, 3] * 1000.0] + [float(v) for v in np.degrees(rot_to_rpy(T[:3, :3]))]


def with_number(T: np.ndarray, axis: str, value: object, what: str) -> np.ndarray:
    """``T`` with one number box's value: x/y/z [mm] (within +-5 m) or roll/pitch/yaw [deg].

    Raises:
        Refused: not a finite number, or a position beyond +-5 m.
    """
    k = OBJECT_AXES.index(axis)
    lim = _OBJECT_RANGE_MM if k < 3 else 1e6
    v, _ = number(value, f"{what} {axis}", -lim, lim, "mm" if k < 3 else "deg", clamp=False)
    out = np.array(T, dtype=np.float64)
    if k < 3:
        out[k, 3] = v / 1000.0
    else:
        rpy = rot_to_rpy(out[:3, :3])
        rpy[k - 3] = math.radians(v)
        out[:3, :3] = rpy_to_rot(rpy)
    return out


def gizmo_pose(value: object) -> tuple[str, np.ndarray]:
    """(phase, pose 4x4) from a gizmo intent ``(phase, wxyz, position)``, validated.

    Raises:
        Refused: malformed, not finite, or more than 10 m from the origin.
    """
    try:
        phase, q, p = value  # type: ignore[misc]
        q = np.asarray(q, dtype=np.float64).reshape(4)
        p = np.asarray(p, dtype=np.float64).reshape(3)
    except (TypeError, ValueError):
        raise Refused("gizmo: malformed pose") from None
    if phase not in ("start", "update", "end") or not (np.all(np.isfinite(q)) and np.all(np.isfinite(p))):
        raise Refused("gizmo: pose is not finite")
    if not 0.5 < float(np.linalg.norm(q)) < 2.0 or float(np.linalg.norm(p)) > 10.0:
        raise Refused("gizmo: pose out of range")
    return str(phase), pose_from_wxyz(q, p)


class TeachPanel:
    """The teach tab of ``app`` (a :class:`~dualpuma.viewer.app.ViewerApp`)."""

    def __init__(self, app, tab) -> None:
        self.app = app
        g, c = app.server.gui, app.controls
        with tab:
            self.readout = g.add_markdown("")
            with g.add_folder("jog"):
                c.input("jog_frame", g.add_dropdown("jog", JOG_FRAMES, initial_value=app.settings["jog_frame"],
                                                    hint="what a jog moves; the other hand follows"))
                c.input("jog_mm", g.add_number("step [mm]", app.settings["jog_mm"], min=0.1, max=200.0, step=0.1))
                c.input("jog_deg", g.add_number("step [deg]", app.settings["jog_deg"], min=0.1, max=90.0, step=0.1))
                c.group("jog", g.add_button_group("move", MOVE_BUTTONS, hint="along the world axes"))
                c.group("jog", g.add_button_group("turn", TURN_BUTTONS, hint="about the jogged frame's own axes"))
                c.group("pose", g.add_button_group("pose", ("Home", "Undo")))
            with g.add_folder("object frame [mm, deg]"):
                for k in OBJECT_AXES:
                    c.input(f"object.{k}", g.add_number(f"object {k}", 0.0, step=0.1))
                self.gizmo_on = c.input("object_gizmo_on", g.add_checkbox("object gizmo", app.settings["object_gizmo_on"]))
            for side in ("left", "right"):
                lim = np.degrees(app.world.arms[side].limits)
                with g.add_folder(f"{side} arm joints [deg]", expand_by_default=True):
                    for j in range(6):
                        c.input(f"joint.{side}.{j}", g.add_slider(f"{side} q{j + 1}", min=round(float(lim[j, 0]), 1),
                                                                   max=round(float(lim[j, 1]), 1), step=0.1,
                                                                   initial_value=0.0))
            with g.add_folder("taught waypoints"):
                c.group("waypoints", g.add_button_group("waypoints", ("record", "clear")))
                self.count = g.add_markdown("0 waypoints")
        T0 = app.state.pose.T_object
        self.gizmo = c.gizmo("object_gizmo", app.server.scene.add_transform_controls(
            "/object_gizmo", scale=0.25, position=tuple(T0[:3, 3]), wxyz=quaternion_wxyz(T0[:3, :3]),
            visible=app.settings["object_gizmo_on"], disable_sliders=True))
        self._drag_refused = False

    # ------------------------------------------------------------------ intents (loop thread)
    def apply(self, it: Intent) -> bool:
        """Apply a teach intent; False if ``it`` is not one of this panel's."""
        app, key = self.app, it.key
        if key.startswith("joint."):
            _, side, j = key.split(".")
            j = int(j)
            lim = np.degrees(app.world.arms[side].limits[j])
            deg, note = number(it.value, f"{side} q{j + 1}", float(lim[0]), float(lim[1]), "deg")
            app.state.teach_move(move_joint(app.world, app.state.teach_start(), side, j, math.radians(deg)), it, note=note)
        elif key.startswith("object."):
            pose = app.state.teach_start()
            T = with_number(pose.T_object, key.split(".")[1], it.value, "object")
            app.state.teach_move(move_object(app.world, pose, T), it)
        elif key == "object_gizmo":
            self._gizmo(it)
        elif key == "jog":
            b = choice(it.value, MOVE_BUTTONS + TURN_BUTTONS, "jog")
            sign, axis = (-1.0 if b[0] == "-" else 1.0), b[1:]
            frame = {"object": "object", "left hand": "left", "right hand": "right"}[app.settings["jog_frame"]]
            amount = sign * (app.settings["jog_mm"] / 1000.0 if axis in "xyz" else math.radians(app.settings["jog_deg"]))
            pose = app.state.teach_start()
            move = move_object(app.world, pose, jog_target(app.world, pose, frame, axis, amount))
            app.state.teach_move(move, it, done=f"jogged the {app.settings['jog_frame']} {b}")
        elif key in ("jog_mm", "jog_deg"):
            hi = 200.0 if key == "jog_mm" else 90.0
            app.settings[key], note = number(it.value, "jog step", 0.1, hi, "mm" if key == "jog_mm" else "deg")
            if note:
                app.status.tell(note, "warn", it.client)
        elif key == "jog_frame":
            app.settings[key] = choice(it.value, JOG_FRAMES, "jog")
        elif key == "pose":
            b = choice(it.value, ("Home", "Undo"), "pose")
            if b == "Home":
                app.state.set_pose(home_pose(app.world), it, "home: the cell's home joints and start pose")
            else:
                app.state.undo_pose(it)
        elif key == "object_gizmo_on":
            app.settings[key] = bool(it.value is True)
            self.gizmo.visible = app.settings[key]
        elif key == "waypoints":
            b = choice(it.value, ("record", "clear"), "waypoints")
            app.state.edit_waypoints(b, it)
        else:
            return False
        return True

    def _gizmo(self, it: Intent) -> None:
        app = self.app
        phase, T = gizmo_pose(it.value)
        if not app.settings["object_gizmo_on"]:  # switched off: hidden, so no drag of it is the user's
            app.state.dragging.pop(it.client_id, None)
            raise Refused("object gizmo: switched off ('object gizmo' in the teach tab shows it)")
        cid = it.client_id
        if phase == "start":
            app.state.dragging[cid] = "object_gizmo"
            self._drag_refused = False
            return
        if phase == "end":
            app.state.dragging.pop(cid, None)
        pose = app.state.teach_start()
        if np.allclose(T, pose.T_object, rtol=0.0, atol=1e-9):
            return
        move = move_object(app.world, pose, T)
        if move.ok or phase == "end" or not self._drag_refused:
            app.state.teach_move(move, it, quiet=move.ok and phase == "update")
        self._drag_refused = self._drag_refused or not move.ok

    # ------------------------------------------------------------------ write-back (loop thread)
    def show(self, seq: int, qL, qR, T, clearance) -> None:
        """Write the shown state to the controls (only what changed and nobody touched since)."""
        app, c = self.app, self.app.controls
        for side, q in (("left", qL), ("right", qR)):
            for j in range(6):
                c.show(f"joint.{side}.{j}", round(math.degrees(float(q[j])), 1), seq, tol=0.05)
        for k, v in zip(OBJECT_AXES, pose_numbers(T)):
            c.show(f"object.{k}", round(float(v), 1) + 0.0, seq, tol=0.05)
        for key in ("jog_mm", "jog_deg", "jog_frame", "object_gizmo_on"):
            c.show(key, app.settings[key], seq)
        if not any(v == "object_gizmo" for v in app.state.dragging.values()):
            pos, q = tuple(float(v) for v in T[:3, 3]), quaternion_wxyz(T[:3, :3])
            if not (np.allclose(self.gizmo.position, pos, rtol=0.0, atol=1e-9) and np.allclose(self.gizmo.wxyz, q, rtol=0.0, atol=1e-9)):
                self.gizmo.position, self.gizmo.wxyz = pos, q
        self.count.content = f"{len(app.state.waypoints)} waypoint(s) recorded"
        self.readout.content = self._readout(qL, qR, T, clearance)

    def _readout(self, qL, qR, T, c) -> str:
        app = self.app
        hands = app.world.hand_poses(qL, qR)
        rpy = np.degrees(rot_to_rpy(T[:3, :3]))
        lines = [f"**object** {_mm(T[:3, 3])} · rpy {_deg(rpy)}"]
        for side, q, H in (("left", qL, hands[0]), ("right", qR, hands[1])):
            arm = app.world.arms[side]
            branch = f" `{BRANCH_NAMES[arm.branch_of(q)]}`" if arm.analytic else " (numeric IK)"
            lines.append(f"**{side}** {arm.robot} hand {_mm(H[:3, 3])}{branch}")
        below = c.distance < app.cell.safety_margin
        lines.append(f"**clearance {c.distance * 1000:.1f} mm** ({c.pair[0]} – {c.pair[1]})"
                     + (f" — **below the {app.cell.safety_margin * 1000:.0f} mm margin**" if below else ""))
        return "  \n".join(lines)


def _mm(p) -> str:
    return "(" + ", ".join(f"{v + 0.0:.1f}" for v in np.round(np.asarray(p) * 1000.0, 1)) + ") mm"


def _deg(a) -> str:
    return "(" + ", ".join(f"{v + 0.0:.1f}" for v in np.round(a, 1)) + ") deg"
