"""The routines & planning tab: the seed's routines 1–8, playback (play / pause / step, timeline,
speed), the clearance plot with a marker at the current step, the plan's events, and planning to
a goal (numbers or a gizmo) or through the taught waypoints.

A routine that needs a cell other than the one shown says so and offers to switch; "back to my
cell" restores the user's cell, pose and waypoints.
"""

from __future__ import annotations

import math

import numpy as np

from ..lie import quaternion_wxyz
from ..planning.rate_limits import missing_rate_limits
from ..scenarios import ROUTINES
from ..units import display_text
from .intents import Intent, Refused, choice, flag, number
from .plot import ClearancePlot
from .status import markdown_text
from .teach import OBJECT_AXES, gizmo_pose, pose_numbers, with_number

__all__ = ["PLAY_BUTTONS", "ROUTINE_LABELS", "SPEEDS", "STEP_TIMES", "TIMED_HINT", "RoutinesPanel"]

ROUTINE_LABELS = tuple(f"{n}: {r.title}" for n, r in sorted(ROUTINES.items()))
PLAY_BUTTONS = ("play", "pause", "start", "-1", "+1")
SPEEDS = (0.1, 4.0)  #: playback speed factor range (1 = real time)
STEP_TIMES = (0.01, 10.0)  #: range of the plan's clock, time per step [s]
#: the "timed trajectory" box's hint where the cell's arms have the limits timing needs
TIMED_HINT = "plans are timed under the arms' joint limits and played at that speed; off: step by step"


class RoutinesPanel:
    """The routines & planning tab of ``app``."""

    def __init__(self, app, tab) -> None:
        self.untimed: tuple[object, str] | None = None  # (the World, why its plans cannot be timed: "" if they can)
        self.app = app
        g, c = app.server.gui, app.controls
        with tab:
            c.input("routine", g.add_dropdown("routine", ROUTINE_LABELS, initial_value=ROUTINE_LABELS[app.settings["routine"] - 1]))
            c.button("run", g.add_button("run routine"))
            self.confirm = g.add_markdown("", visible=False)
            self.switch = c.group("switch", g.add_button_group("switch cell?", ("switch and run", "cancel"), visible=False))
            self.back = c.button("back", g.add_button("back to my cell", visible=False))
            self.status = g.add_markdown("no plan")
            c.group("play", g.add_button_group("playback", PLAY_BUTTONS))
            self.timeline = c.input("timeline", g.add_slider("timeline [step]", min=0.0, max=1.0, step=0.1, initial_value=0.0))
            c.input("speed", g.add_slider("speed [x real time]", min=SPEEDS[0], max=SPEEDS[1], step=0.1,
                                          initial_value=app.settings["speed"]))
            c.input("timed", g.add_checkbox("timed trajectory (joint limits)", app.settings["timed"], hint=TIMED_HINT))
            self.plot = ClearancePlot(g, app.cell.safety_margin * 1000.0)
            self.plot.handle.visible = False
            self.events = g.add_markdown("")
            # open: viser's folder header opens by mouse only, and closed it kept these from the keyboard
            with g.add_folder("plan to a goal [mm, deg]", expand_by_default=True):
                for k in OBJECT_AXES:
                    c.input(f"goal.{k}", g.add_number(f"goal {k}", 0.0, step=0.1))
                c.input("goal_gizmo_on", g.add_checkbox("goal gizmo", app.settings["goal_gizmo_on"]))
                c.input("fallback", g.add_checkbox("fallback (RRT-Connect) if stuck", app.settings["fallback"]))
                c.input("step_time", g.add_number("step time [s]", app.settings["step_time"], min=STEP_TIMES[0],
                                                  max=STEP_TIMES[1], step=0.01,
                                                  hint="the plan's clock: moving obstacles are checked at this time "
                                                       "per step; longer when the timed motion says the arms cannot "
                                                       "keep it"))
                c.group("plan", g.add_button_group("plan", ("goal = current", "plan to goal", "through waypoints")))
        G = app.settings["goal"]
        self.goal = c.gizmo("goal_gizmo", app.server.scene.add_transform_controls(
            "/goal", scale=0.2, position=tuple(G[:3, 3]), wxyz=quaternion_wxyz(G[:3, :3]),
            visible=app.settings["goal_gizmo_on"], disable_sliders=True))

    def selected(self) -> int:
        return int(self.app.settings["routine"])

    # ------------------------------------------------------------------ intents (loop thread)
    def apply(self, it: Intent) -> bool:
        app, key, s = self.app, it.key, self.app.settings
        if key == "routine":
            s["routine"] = int(choice(it.value, ROUTINE_LABELS, "routine").split(":")[0])
        elif key == "run":
            app.request_routine(s["routine"], it)
        elif key == "switch":
            app.confirm_switch(choice(it.value, ("switch and run", "cancel"), "switch") == "switch and run", it)
        elif key == "back":
            app.restore_user_cell(it)
        elif key == "play":
            app.state.playback_command(choice(it.value, PLAY_BUTTONS, "playback"), it)
        elif key == "timeline":
            pb = app.state.playback
            if pb is None:
                raise Refused("timeline: no plan to scrub")
            # the slider's last mark may lie past the plan's end (a round number): that is the end
            x, note = number(it.value, "timeline", float(pb.x[0]), max(pb.x_end, float(self.timeline.max)))
            app.state.seek_time(pb.time_at_x(min(x, pb.x_end)))
            if note:
                app.status.tell(note, "warn", it.client)
        elif key == "speed":
            s["speed"], note = number(it.value, "speed", *SPEEDS, "x")
            if note:
                app.status.tell(note, "warn", it.client)
        elif key.startswith("goal."):
            s["goal"] = with_number(s["goal"], key.split(".")[1], it.value, "goal")
        elif key == "goal_gizmo":
            phase, G = gizmo_pose(it.value)
            if phase == "start":
                app.state.dragging[it.client_id] = "goal_gizmo"
            else:
                s["goal"] = G
                if phase == "end":
                    app.state.dragging.pop(it.client_id, None)
        elif key == "step_time":
            s["step_time"], note = number(it.value, "step time", *STEP_TIMES, "s")
            if note:
                app.status.tell(note, "warn", it.client)
        elif key in ("goal_gizmo_on", "fallback", "timed"):
            s[key] = flag(it.value, key)
            if key == "goal_gizmo_on":
                self.goal.visible = s[key]
        elif key == "plan":
            b = choice(it.value, ("goal = current", "plan to goal", "through waypoints"), "plan")
            if b == "goal = current":
                s["goal"] = np.array(app.state.shown()[2])
            elif b == "plan to goal":
                app.plan_to_goal(it)
            else:
                app.plan_waypoints(it)
        else:
            return False
        return True

    # ------------------------------------------------------------------ write-back (loop thread)
    def show_plan(self, pb) -> None:
        """A new plan: timeline range, plot curve, events."""
        app = self.app
        tl = self.timeline
        tl.step = 0.1 if not pb.timed else 0.01
        tl.precision = 1 if not pb.timed else 2  # its box's decimals (viser fixes them from the first step: 1.23 s was 1.2)
        tl.max = max(math.ceil(float(pb.x_end) / tl.step - 1e-9) * tl.step, 0.1)  # a round number on the slider
        tl.label = "timeline [s]" if pb.timed else "timeline [step]"
        self.plot.set_curve(pb.x, pb.clearance, pb.x_label, pb.margin(app.cell.safety_margin) * 1000.0)
        plan = pb.plan
        ev = "\n".join(f"- {markdown_text(display_text(e))}" for e in plan.events[-12:]) or "- (no events)"
        warn = ""
        if pb.mismatch > 1e-3:
            warn = (f"\n\n**note**: the plan's clearance differs by up to {pb.mismatch * 1000:.1f} mm from this cell's "
                    "(it was checked against other geometry); the plot and read-out show the plan's values at its steps")
        self.events.content = f"**{markdown_text(pb.title)}**: `{plan.status}` {markdown_text(display_text(plan.reason))}{warn}\n\n{ev}"

    def show(self, seq: int, sample, playing: bool) -> None:
        app, c, s = self.app, self.app.controls, self.app.settings
        for key in ("speed", "goal_gizmo_on", "fallback", "timed", "step_time"):
            c.show(key, s[key], seq)
        if self.untimed is None or self.untimed[0] is not app.world:  # a new cell: can its plans be timed?
            self.untimed = (app.world, missing_rate_limits(app.world))
            timed = c.handles["timed"]
            timed.disabled = bool(self.untimed[1])  # the viewer has no box for the limits a cell lacks
            timed.hint = f"not in this cell: {self.untimed[1]}" if self.untimed[1] else TIMED_HINT
        c.show("routine", ROUTINE_LABELS[s["routine"] - 1], seq)
        G = s["goal"]
        for k, v in zip(OBJECT_AXES, pose_numbers(G)):
            c.show(f"goal.{k}", round(float(v), 1), seq, tol=0.05)
        if not any(v == "goal_gizmo" for v in app.state.dragging.values()):
            pos, q = tuple(float(v) for v in G[:3, 3]), quaternion_wxyz(G[:3, :3])
            if not (np.allclose(self.goal.position, pos, rtol=0.0, atol=1e-9) and np.allclose(self.goal.wxyz, q, rtol=0.0, atol=1e-9)):
                self.goal.position, self.goal.wxyz = pos, q
        pb = app.state.playback
        pending = app.pending_routine
        self.confirm.visible = self.switch.visible = pending is not None
        if pending is not None:
            self.confirm.content = pending[1]
        self.back.visible = app.user_cell is not None
        if app.user_cell is not None:
            self.back.label = f"back to my cell ({app.user_cell['label']})"
        self.plot.handle.visible = pb is not None
        if pb is None:
            self.status.content = "no plan"
            c.show("timeline", 0.0, seq)  # a slider moved with no plan goes back
            return
        if sample is not None:
            c.show("timeline", round(sample.x, 2), seq, tol=0.005)
            self.plot.set_marker(round(sample.x, 2))
        state = "▶ playing" if playing else ("paused" if app.state.view == "plan" else "teaching (plan kept: play resumes)")
        at = f"step {pb.row_at(sample.t)}/{len(pb.row_t) - 1}" if sample is not None else ""
        self.status.content = f"**{markdown_text(pb.title)}** · {state} · {at} · t = {sample.t if sample else 0.0:.2f} s"

