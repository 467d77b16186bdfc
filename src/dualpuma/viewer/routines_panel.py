"""Routines and planning panel: the seed's routines 1–8 (run, play / pause / step, timeline), the
plan's events, a goal gizmo with "plan to goal", and the clearance-along-path plot (uPlot)."""

from __future__ import annotations

import numpy as np
from viser import uplot

from ..lie import pose_from_wxyz, quaternion_wxyz
from ..scenarios.routines import ROUTINES

__all__ = ["ROUTINE_LABELS", "RoutinesPanel"]

ROUTINE_LABELS = tuple(f"{n}: {r.title}" for n, r in sorted(ROUTINES.items()))


class RoutinesPanel:
    """GUI for routines and planning; ``app`` is the ViewerApp whose state it edits."""

    def __init__(self, app) -> None:
        self.app = app
        g = app.server.gui
        with g.add_folder("routines and planning"):
            self.choice = g.add_dropdown("routine", ROUTINE_LABELS, initial_value=ROUTINE_LABELS[1])
            self.run = g.add_button("run routine")
            self.run.on_click(lambda _: app.run_routine(self.selected()))
            self.play = g.add_button("play")
            self.play.on_click(lambda _: app.set_playing(True))
            self.pause = g.add_button("pause")
            self.pause.on_click(lambda _: app.set_playing(False))
            self.step = g.add_button("step")
            self.step.on_click(lambda _: app.step_playback(1))
            self.timeline = g.add_slider("timeline [step]", min=0, max=1, step=1, initial_value=0)
            self.timeline.on_update(lambda _: None if app.syncing else app.seek(int(self.timeline.value)))
            self.speed = g.add_slider("speed [steps/s]", min=1.0, max=60.0, step=1.0, initial_value=10.0)
            self.goal_on = g.add_checkbox("goal gizmo", initial_value=False)
            self.plan_goal = g.add_button("plan to goal")
            self.plan_goal.on_click(lambda _: app.plan_to_goal())
            self.fallback = g.add_checkbox("fallback (RRT-Connect) if frozen", initial_value=False)
            self.status = g.add_markdown("no plan")
            self.events = g.add_markdown("")
            x = np.array([0.0, 1.0])
            self.plot = g.add_uplot(
                data=(x, np.zeros(2), np.full(2, app.cell.safety_margin * 1000.0)),
                series=(uplot.Series(label="step"), uplot.Series(label="clearance [mm]", stroke="blue", width=2),
                        uplot.Series(label="margin [mm]", stroke="red", width=1)),
                title="clearance along the path", aspect=1.6,
            )
        T0 = app.cell.T_world_object_start.copy()
        T0[:3, 3] += (-0.2, 0.0, 0.1)
        self.goal = app.server.scene.add_transform_controls("/goal", scale=0.2, position=tuple(T0[:3, 3]),
                                                            wxyz=quaternion_wxyz(T0[:3, :3]), visible=False)
        self.goal_on.on_update(self._show_goal)

    def _show_goal(self, _event=None) -> None:
        self.goal.visible = bool(self.goal_on.value)

    def selected(self) -> int:
        """The routine number chosen in the dropdown."""
        return int(str(self.choice.value).split(":")[0])

    def goal_pose(self) -> np.ndarray:
        """The goal gizmo's pose (4x4, metres)."""
        return pose_from_wxyz(self.goal.wxyz, self.goal.position)

    def show_plan(self, plan, title: str) -> None:
        """Reset the timeline, events and plot for a new plan (called by the loop)."""
        n = plan.T_world_object.shape[0]
        self.timeline.max = max(1, n - 1)
        self.timeline.value = 0
        ev = "\n".join(f"- {e}" for e in plan.events[-12:]) or "- (no events)"
        self.events.content = f"**{title}**: `{plan.status}` {plan.reason}\n\n{ev}"
        if n >= 2:
            x = np.arange(n, dtype=float)
            self.plot.data = (x, plan.clearance * 1000.0, np.full(n, self.app.cell.safety_margin * 1000.0))
