"""The viewer's state of work: the teach pose (with Undo), the taught waypoints, and the playback
position of the current plan. Written only by the loop thread (panels' ``apply`` methods run
there); other threads read it (a :class:`TeachPose` is replaced whole, never modified).

What is shown is either the teach pose (``view == "teach"``) or the plan at ``play_time``
(``view == "plan"``). A teach move while a plan is shown starts from the plan's nearest step and
keeps the plan: "play" resumes it.
"""

from __future__ import annotations

import time

import numpy as np

from .datadir import MAX_WAYPOINTS
from .intents import Intent, Refused
from .playback import Playback
from .teach_moves import TeachPose

__all__ = ["UNDO_DEPTH", "State"]

UNDO_DEPTH = 100  #: teach poses kept for Undo
_COALESCE_S = 1.0  # consecutive changes of one control within this time are one Undo step [s]


class State:
    """See the module docstring; ``status`` receives the messages (:class:`~dualpuma.viewer.status.Status`)."""

    def __init__(self, status, pose: TeachPose) -> None:
        self.status = status
        self.pose = pose
        self.undo: list[TeachPose] = []
        self._undo_mark = ("", 0.0)
        self.waypoints: tuple[np.ndarray, ...] = ()
        self.playback: Playback | None = None
        self.play_time = 0.0
        self.playing = False
        self.view = "teach"
        self.dragging: dict = {}  # client id -> the gizmo it is dragging

    def shown(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """(q_left, q_right, T_object, t) of what is shown now."""
        if self.view == "plan" and self.playback is not None:
            s = self.playback.sample(self.play_time)
            return s.q_left, s.q_right, s.T_object, s.t
        return self.pose.q_left, self.pose.q_right, self.pose.T_object, 0.0

    def reset(self, pose: TeachPose, playback: Playback | None = None) -> None:
        """A new cell: this pose, no Undo, and ``playback`` shown playing (or none)."""
        self.pose, self.undo, self.playback = pose, [], playback
        self.play_time = float(playback.t[0]) if playback is not None else 0.0
        self.playing = playback is not None
        self.view = "plan" if playback is not None else "teach"

    # ------------------------------------------------------------------ teach pose
    def teach_start(self) -> TeachPose:
        """The pose a teach move starts from (see the module docstring)."""
        pb = self.playback
        if self.view == "plan" and pb is not None:
            i = pb.step_at(self.play_time)
            self._push_undo("plan")
            self.pose = TeachPose.of(pb.q_left[i], pb.q_right[i], pb.T_object[i])
            self.playing, self.view, self.play_time = False, "teach", pb.time_at_step(i)
            at = (f"t = {self.play_time - float(pb.t[0]):.2f} s (step {pb.row_at(self.play_time)})" if pb.timed
                  else f"step {i}")
            self.status.tell(f"teaching from {at} of {pb.title}; the plan is kept ('play' resumes it)", "info",
                             toast=False)
        return self.pose

    def _push_undo(self, key: str) -> None:
        now = time.monotonic()
        same = self._undo_mark[0] == key and now - self._undo_mark[1] < _COALESCE_S and self.undo
        self._undo_mark = (key, now)
        if not same:
            self.undo.append(self.pose)
            del self.undo[:-UNDO_DEPTH]

    def teach_move(self, move, it: Intent, note: str = "", done: str | None = None, quiet: bool = False) -> None:
        """Adopt a teach motion's pose, or tell its refusal; a clamp (``note``) and a move that stopped
        short (``move.short``) are always told."""
        if move.ok:
            # a drag or typing is one Undo step; every click is its own
            self._push_undo(it.key if it.kind in ("input", "gizmo") else f"{it.key}:{it.seq}")
            self.pose, self.view = move.pose, "teach"
            text = done or move.message
            if note or move.short:
                self.status.tell("; ".join(x for x in (note, move.short or text) if x), "warn", it.client,
                                 title="Clamped" if note else "Stopped short")
            else:
                self.status.tell(text, "ok", it.client, toast=False)
        else:
            self.status.tell(f"{note}; {move.message}" if note else move.message, "warn", it.client, toast=not quiet)

    def set_pose(self, pose: TeachPose, it: Intent, text: str) -> None:
        self._push_undo(f"set:{it.seq}")
        self.pose, self.view, self.playing = pose, "teach", False
        self.status.tell(text, "ok", it.client, toast=False)

    def undo_pose(self, it: Intent) -> None:
        if not self.undo:
            raise Refused("nothing to undo")
        self.pose, self.view, self.playing = self.undo.pop(), "teach", False
        self._undo_mark = ("", 0.0)
        # undo, record and clear are buttons: their result is a toast (the message line can be
        # scrolled out of view by the panel, and is not announced to a screen reader)
        self.status.tell(f"undone ({len(self.undo)} more step(s) to undo)", "ok", it.client)

    # ------------------------------------------------------------------ waypoints
    def edit_waypoints(self, what: str, it: Intent) -> None:
        """``record`` the shown object pose, or ``clear`` them all."""
        if what == "clear":
            self.waypoints = ()
            self.status.tell("waypoints cleared", "ok", it.client)
            return
        if len(self.waypoints) >= MAX_WAYPOINTS:
            raise Refused(f"at most {MAX_WAYPOINTS} waypoints")
        self.waypoints += (np.array(self.shown()[2]),)
        self.status.tell(f"recorded waypoint {len(self.waypoints)}", "ok", it.client)

    def set_waypoints(self, poses, it: Intent, text: str) -> None:
        self.waypoints = tuple(np.array(p, dtype=np.float64) for p in poses)
        self.status.tell(text, "ok", it.client, title="Loaded")

    # ------------------------------------------------------------------ playback
    def playback_command(self, cmd: str, it: Intent) -> None:
        """``play``, ``pause``, ``start``, ``-1`` or ``+1`` (step)."""
        pb = self.playback
        if pb is None:
            raise Refused("no plan yet: run a routine or plan to a goal first")
        if cmd == "play":
            if self.play_time >= pb.t_end - 1e-9:
                self.play_time = float(pb.t[0])
            self.playing, self.view = True, "plan"
        elif cmd == "pause":
            self.playing = False
        elif cmd == "start":
            self.play_time, self.playing, self.view = float(pb.t[0]), False, "plan"
        else:
            t = pb.next_row_time(self.play_time, 1 if cmd == "+1" else -1)
            self.play_time, self.playing, self.view = t, False, "plan"

    def seek_time(self, t: float) -> None:
        self.play_time, self.playing, self.view = float(t), False, "plan"

    def advance(self, dt: float, speed: float) -> None:
        """Let playback time run by ``dt`` [s] of wall time at ``speed`` (1 = real time)."""
        pb = self.playback
        if self.playing and pb is not None:
            self.play_time = min(self.play_time + max(dt, 0.0) * speed, pb.t_end)
            if self.play_time >= pb.t_end:
                self.playing = False
