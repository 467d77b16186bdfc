"""`dualpuma serve`: the viser viewer — scene, teach pendant, routines and planning, cells and files.

One source of truth, one writer (see ../shared/DESIGN.md, "Viewer habits"):

* GUI callbacks (viser's event loop) only record intents — the control, the value the event
  carried, the client that sent it (:mod:`.controls`, :mod:`.intents`).
* One loop thread (:meth:`ViewerApp.step`, 30 Hz) drains them in order, validates each (limits,
  finiteness, lengths), applies it, and is the only writer of the kinematic state (:attr:`pose`,
  the playback, the cell and its World) and of the scene. A bad intent is refused with a message
  to its sender; an unexpected error in one intent is reported and the loop goes on.
* After applying, the loop writes values back to the controls it changed, never over a control a
  user touched after the state it is writing (:meth:`Controls.show`); the writes themselves are
  made on viser's event loop, where a client's value is stored and read by its callback in one
  stretch (:meth:`Controls.flush`). It moves the nodes inside ``server.atomic()``.
* Planning and routines run in a worker thread; the loop picks up the finished playback. No lock is
  held through IK paths or planning: there is no state lock at all, the loop being the one writer.
  Cell swaps (a routine's own cell, a loaded cell) are applied by the loop too.

Files: only inside the data directory (:mod:`.datadir`). Network: :mod:`.security`.
"""

from __future__ import annotations

import logging
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np

from ..collision import self_contact
from ..errors import DualpumaError
from ..model import Cell, World
from ..planning import StrivingParams
from ..scenarios import routine_cell
from ..units import display_text
from .camera import fit_client, set_initial_camera
from .controls import Controls
from .datadir import DEFAULT_DATA_DIR, DataDir
from .files_panel import FilesPanel
from .intents import Intent, IntentQueue, Refused
from .jobs import goal_job, routine_job, same_cell, waypoints_job
from .routines_panel import RoutinesPanel
from .scene import Scene, capsule_mesh
from .security import AccessPolicy, check_listen, start_server
from .state import State
from .status import Status
from .teach import TeachPanel
from .teach_moves import grasp_error, home_pose
from .view_panel import ViewPanel

__all__ = ["MAX_STEP_DT", "PANEL_WIDTH", "SLIDER_TYPED_JUMP", "TYPED", "TYPED_HOLD", "TYPING_PAUSE", "ViewerApp", "capsule_mesh", "serve"]

log = logging.getLogger("dualpuma.viewer")
#: number boxes (not sliders) whose value is applied only once typing pauses for TYPING_PAUSE: viser
#: sends every keystroke (and nothing on Enter), and typing "1850" must not first move the object to
#: x = 1, 18, 185 mm. A second: 0.4 s let a hesitant typist's "-4" and "-40" of "-400" move the arms
#: (found by a helper typing at 0.4-0.5 s a key); a typed value now takes effect a second after its last key.
TYPED = ("object.", "goal.", "jog_mm", "jog_deg")
TYPING_PAUSE = 1.0  # [s]
#: ... and such a box keeps what the user typed for TYPED_HOLD after the last keystroke, even when the
#: value was refused (then it shows the state's value again): a slow typist's partial number, applied
#: and refused between two keys, must not reset the box under the cursor and garble what follows
TYPED_HOLD = 1.5  # [s]
#: a joint slider's value this far from the joint's shown value [deg] is taken as typed into the
#: slider's number box, and waits for the typing pause as TYPED do (typing 45 over 60.6 sent 4
#: first, which was applied, refused, and garbled the next key); a drag moves it by about a degree
#: per pixel and is applied at once (a click far along the track waits TYPING_PAUSE)
SLIDER_TYPED_JUMP = 3.0  # [deg]
#: the longest wall time one loop step lets playback run [s]: a step that rebuilt the scene for a
#: routine's own cell took 1.8 s, and playback jumped over the routine's first quarter
MAX_STEP_DT = 0.2
PANEL_WIDTH = 460  #: control panel width [px]: a 320 deg joint slider gets about 1 deg per pixel


class ViewerApp:
    """One viser server showing a cell (see the module docstring).

    Args:
        cell: the work cell (default: the seed's default cell).
        host, port: where to listen (loopback by default; port 0 = any free port, "auto" = the
            first free one from 8080).
        data_dir: the only directory files are read from and written to (created on first write).
        allow_hosts: extra host names the server answers to (see :class:`AccessPolicy`).
        cell_label: how the cell selector names ``cell`` (default ``"startup: <name>"``).

    Raises:
        ParameterError: the host or port cannot be used.
    """

    def __init__(self, cell: Cell | None = None, host: str = "127.0.0.1", port: int | str = 8080, *,
                 data_dir=DEFAULT_DATA_DIR, allow_hosts=(), cell_label: str | None = None) -> None:
        cell = Cell.default() if cell is None else cell
        self.startup_cell, self.startup_label = cell, cell_label or f"startup: {cell.name}"
        self.cell, self.cell_label, self.world = cell, self.startup_label, World(cell)
        self.data = DataDir(data_dir)
        self.queue = IntentQueue()
        self.pending_routine: tuple[int, str] | None = None
        self.user_cell: dict | None = None
        self.applied_seq = 0
        self.redraw = self._reframe = True
        self._typed: dict[str, tuple[Intent, float]] = {}
        self._keystroke: dict[str, float] = {}  # typed box -> time of its last keystroke (TYPED_HOLD)
        self.last_clearance = None
        self.last_contact: tuple[str, str, str] | None = None  # a close pair of the shown joints that may touch
        self._shown = None
        G = np.array(self.cell.T_world_object_start, dtype=np.float64)
        G[:3, 3] += (-0.2, 0.0, 0.1)
        self.settings = {"jog_frame": "object", "jog_mm": 10.0, "jog_deg": 5.0, "object_gizmo_on": True, "routine": 2,
                         "speed": 1.0, "goal": G, "goal_gizmo_on": False, "fallback": False, "timed": True,
                         "step_time": StrivingParams().step_time, "file_name": "waypoints", "overwrite": False, "cell_choice": self.cell_label}
        self._job: tuple[Future, str, object, Cell | None, World] | None = None
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="dualpuma-plan")
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._last_t = time.perf_counter()
        port = check_listen(host, port)
        self.server = start_server(host, port, AccessPolicy.for_host(host, allow_hosts))
        try:
            self._build()
        except BaseException:
            self.server.stop()
            raise
        err = grasp_error(self.world, self.state.pose)
        if max(e[0] for e in err.values()) > 1e-3:
            self.status.tell("the cell's home joints do not hold the bar with both hands; a first move brings both "
                             "hands to their grasps", "warn", toast=False)
        self.step(0.0)

    def _build(self) -> None:
        self.controls = Controls(self.queue, self.server.get_event_loop(),
                                 on_full=lambda c: self.status.tell("too many requests; slow down", "warn", c))
        g = self.server.gui
        g.configure_theme(control_width="large", show_share_button=False, dark_mode=False)
        g.main_panel.set_width(PANEL_WIDTH)
        self.status = Status(self.server, g.add_markdown("", order=0))
        self.state = State(self.status, home_pose(self.world))
        tabs = g.add_tab_group(order=1)
        self.scene = Scene(self.server, self.world)
        self.teach = TeachPanel(self, tabs.add_tab("teach"))
        self.routines = RoutinesPanel(self, tabs.add_tab("routines & planning"))
        self.files = FilesPanel(self, tabs.add_tab("cell & files"))
        self.view_panel = ViewPanel(self, tabs.add_tab("view"))
        self.panels = (self.teach, self.routines, self.files, self.view_panel)
        # a client that leaves mid-drag must not keep its gizmo from following the object
        self.server.on_client_disconnect(lambda client: self.queue.put("client_left", client.client_id, None, "button"))
        self.status.tell(f"{self.cell_label}: ready", "info", toast=False)

    # ------------------------------------------------------------------ state accessors
    @property
    def q(self) -> dict[str, np.ndarray]:
        """Both arms' joints as shown now [rad]."""
        qL, qR, _, _ = self.state.shown()
        return {"left": qL, "right": qR}

    @property
    def T_object(self) -> np.ndarray:
        """The object frame as shown now (4, 4) [m]."""
        return self.state.shown()[2]

    @property
    def playback(self):
        return self.state.playback

    @property
    def message(self) -> str:
        """The last message shown on the status line."""
        return self.status.message

    @property
    def plan(self):
        return None if self.state.playback is None else self.state.playback.plan

    @property
    def busy(self) -> bool:
        """True while a plan/routine is being computed in the worker."""
        return self._job is not None

    @property
    def url(self) -> str:
        host = self.server.get_host()
        return f"http://{f'[{host}]' if ':' in host else host}:{self.server.get_port()}"  # IPv6 in brackets

    def intent(self, key: str, value=None, kind: str = "input") -> None:
        """Record an intent as the server itself (no client): the Python API's way to act."""
        self.queue.put(key, value, None, kind)

    # ------------------------------------------------------------------ called by panels (loop thread)
    # -- planning (the work runs in the worker)
    def _submit(self, title: str, client, fn, *args, switch: Cell | None = None) -> None:
        if self._job is not None:
            raise Refused(f"busy: {self._job[1]} is still being computed")
        self._job = (self._executor.submit(fn, *args), title, client, switch, self.world)
        self.status.tell(f"{title}: planning …", "info", client, toast=False)

    def request_routine(self, n: int, it: Intent) -> None:
        cell = routine_cell(n)
        if same_cell(cell, self.cell):
            self._submit(f"routine {n}", it.client, routine_job, n, self.world, self.settings["timed"])
        elif self.user_cell is not None:  # already on a routine's cell: the user's own is kept
            self._submit(f"routine {n}", it.client, routine_job, n, None, self.settings["timed"], switch=cell)
        else:
            obst = ", ".join(o.name for o in cell.obstacles) or "no obstacles"
            msg = (f"Routine {n} runs in its own cell **{cell.name}** ({obst}; bar {cell.bar.shape}). Switch from "
                   f"**{self.cell_label}**? 'back to my cell' restores it with your pose and waypoints.")
            self.pending_routine = (n, msg)
            self.status.tell(f"routine {n} needs its own cell '{cell.name}': confirm the switch in the routines tab",
                             "info", it.client, title="Switch cell?")

    def confirm_switch(self, yes: bool, it: Intent) -> None:
        if self.pending_routine is None:
            raise Refused("nothing to confirm")
        n, _ = self.pending_routine
        self.pending_routine = None
        if yes:
            self._submit(f"routine {n}", it.client, routine_job, n, None, self.settings["timed"], switch=routine_cell(n))
        else:
            self.status.tell(f"routine {n} not run; still in {self.cell_label}", "info", it.client)

    def plan_to_goal(self, it: Intent) -> None:
        p = self.state.teach_start()
        self._submit("plan to goal", it.client, goal_job, self.world, p.T_object, (p.q_left, p.q_right),
                     self.settings["goal"].copy(), self.settings["fallback"], self.settings["timed"],
                     self.settings["step_time"])

    def plan_waypoints(self, it: Intent) -> None:
        st = self.state
        if not st.waypoints:
            raise Refused("no waypoints recorded")
        p = st.teach_start()
        self._submit(f"{len(st.waypoints)} waypoints", it.client, waypoints_job, self.world, p.T_object,
                     (p.q_left, p.q_right), list(st.waypoints), self.settings["timed"], self.settings["step_time"])

    def _collect_job(self) -> None:
        if self._job is None or not self._job[0].done():
            return
        fut, title, client, switch, world = self._job
        self._job = None
        try:
            res = fut.result()
        except Exception as exc:
            log.warning("%s failed", title, exc_info=True)
            self.status.tell(f"{title} failed: {type(exc).__name__}: {exc}", "error", client)
            return
        if switch is None and world is not self.world:
            self.status.tell(f"{title}: the cell changed while planning; result discarded", "warn", client)
            return
        p = res.plan
        if res.playback is None:
            self.status.tell(f"{title}: {p.status}: {display_text(p.reason)}", "warn", client, title="No plan")
            return
        st = self.state
        if switch is not None:
            if self.user_cell is None:
                self.user_cell = {"cell": self.cell, "label": self.cell_label, "world": self.world, "pose": st.pose,
                                  "waypoints": st.waypoints, "undo": list(st.undo)}
            self._set_cell(res.cell, res.world, f"routine {title.split()[-1]}: its own cell")
            st.reset(home_pose(res.world), res.playback)
        else:
            st.playback, st.play_time, st.playing, st.view = res.playback, float(res.playback.t[0]), True, "plan"
        self.routines.show_plan(res.playback)
        self.scene.set_path(res.playback.T_object)
        level = "ok" if p.reached and not res.note else "warn"
        retimed = p.trajectory.retimed if p.trajectory is not None else ""
        self.status.tell(f"{title}: {p.status} in {p.n_steps} steps, min clearance {p.min_clearance * 1000:.1f} mm"
                         + (f" — {display_text(p.reason)}" if p.reason else "") + (f" — {display_text(res.note)}" if res.note else "")
                         + (f" — timed: {retimed}" if retimed else ""),
                         level, client, title="Plan")

    # -- cells
    def _set_cell(self, cell: Cell, world: World, label: str) -> None:
        with self.server.atomic():
            self.scene.set_world(world)  # first: a RobotError here leaves everything as it was
            self.scene.set_path(None)
        self.cell, self.world, self.cell_label = cell, world, label
        self.state.reset(home_pose(world))
        self.pending_routine = None
        for side in ("left", "right"):
            lim = np.degrees(world.arms[side].limits)
            for j in range(6):
                h = self.controls.handles[f"joint.{side}.{j}"]
                h.min, h.max = round(float(lim[j, 0]), 1), round(float(lim[j, 1]), 1)
        self.routines.plot.set_curve([0.0, 1.0], [0.0, 0.0], "step", cell.safety_margin * 1000.0)
        self.settings["cell_choice"] = label
        self.files.refresh()
        self.redraw = self._reframe = True

    def switch_cell(self, cell: Cell, label: str, it: Intent) -> None:
        """Show another cell (the cell selector): home pose, no plan; it becomes the user's cell."""
        self._set_cell(cell, World(cell), label)
        self.user_cell = None
        self.status.tell(f"cell {label} loaded", "ok", it.client, title="Cell")

    def restore_user_cell(self, it: Intent) -> None:
        uc = self.user_cell
        if uc is None:
            raise Refused("you are in your own cell already")
        self._set_cell(uc["cell"], uc["world"], uc["label"])
        st = self.state
        st.pose, st.waypoints, st.undo, self.user_cell = uc["pose"], uc["waypoints"], uc["undo"], None
        self.status.tell(f"back in {uc['label']}", "ok", it.client, title="Cell")

    # ------------------------------------------------------------------ the loop (one thread)
    def _apply(self, it: Intent) -> None:
        if it.key == "client_left":
            self.state.dragging.pop(it.value, None)
            return
        try:
            if not any(panel.apply(it) for panel in self.panels):
                raise Refused(f"unknown control {it.key!r}")
        except Refused as exc:
            self.status.tell(str(exc), "warn", it.client)
        except DualpumaError as exc:
            self.status.tell(f"{it.key}: {exc}", "warn", it.client)
        except Exception as exc:
            log.exception("intent %s failed", it.key)
            self.status.tell(f"internal error on {it.key}: {type(exc).__name__}: {exc}", "error", it.client)

    def step(self, dt: float | None = None) -> None:
        """One update: finished jobs, intents in order, playback, FK + clearance, nodes and controls."""
        now = time.perf_counter()
        dt = min(now - self._last_t, MAX_STEP_DT) if dt is None else float(dt)
        self._last_t = now
        self._collect_job()
        for it in self.queue.drain():
            if self._being_typed(it):
                self._typed[it.key] = (it, now)  # a number being typed: applied once typing pauses
                self._keystroke[it.key] = now
                continue
            self._typed.pop(it.key, None)  # a later value of the same control (a drag) replaces a typed one
            self._apply(it)
            self.applied_seq = max(self.applied_seq, it.seq)
        for key, (it, t) in list(self._typed.items()):
            if now - t >= TYPING_PAUSE:
                del self._typed[key]
                self._apply(it)
                self.applied_seq = max(self.applied_seq, it.seq)
        self._keystroke = {k: t for k, t in self._keystroke.items() if now - t < TYPED_HOLD}
        self.controls.held = set(self._typed) | set(self._keystroke)
        self.state.advance(dt, self.settings["speed"])
        self._draw()

    def _being_typed(self, it: Intent) -> bool:
        """Is ``it`` a keystroke in a number box (TYPED, or a joint slider's box: SLIDER_TYPED_JUMP)?"""
        if it.client is None or it.kind != "input":
            return False
        if it.key.startswith(TYPED):
            return True
        if not it.key.startswith("joint."):
            return False
        _, side, j = it.key.split(".")
        try:
            deg = float(it.value)
        except (TypeError, ValueError, OverflowError):
            return True  # refused once typing pauses
        qL, qR, _, _ = self.state.shown()
        return not abs(deg - float(np.degrees((qL if side == "left" else qR)[int(j)]))) <= SLIDER_TYPED_JUMP

    def _draw(self) -> None:
        st = self.state
        qL, qR, T, t = st.shown()
        key = (qL.tobytes(), qR.tobytes(), T.tobytes(), t)
        pb = st.playback
        # the margin in force: the plan's own while a plan is shown (routines 2, 5, 8 keep 10 mm)
        margin = pb.margin(self.cell.safety_margin) if st.view == "plan" and pb is not None else self.cell.safety_margin
        if key != self._shown or self.redraw:
            c = self.world.clearance(qL, qR, T, t)
            hands = self.world.hand_poses(qL, qR)
            with self.server.atomic():
                self.scene.update(qL, qR, c, T, hands, margin, t)
            self._shown, self.redraw, self.last_clearance = key, False, c
            self.last_contact = self_contact(self.world, qL, qR)[0]
            if self._reframe:  # a new cell: new clients (and "Reset View") see all of it, and so do those here
                pts = self.scene.points()
                set_initial_camera(self.server, pts)
                for client in self.server.get_clients().values():
                    fit_client(client, pts)
                self._reframe = False
        c = self.last_clearance
        sample = pb.sample(st.play_time) if pb is not None else None
        seq = self.applied_seq
        with self.server.atomic():
            self.teach.show(seq, qL, qR, T, c)
            self.routines.show(seq, sample, st.playing)
            self.files.show(seq)
            self.view_panel.show(seq)
            self.controls.flush()
        mark = "⚠ " if c.distance < margin else ""
        if st.view == "plan" and pb is not None and sample is not None:
            head = f"{'▶ playing' if st.playing else 'paused'} {pb.title} · step {pb.row_at(sample.t)}/{len(pb.row_t) - 1}"
        else:
            head = "teach" + (" · planning …" if self._job is not None else "")
        touch = self.last_contact
        touch_text = f" · ⚠ {touch[0]} {touch[1]} – {touch[2]} may touch" if touch is not None else ""
        self.status.summary(f"{head} · {mark}{c.distance * 1000:.1f} mm{touch_text}")

    def start(self) -> None:
        """Run the loop in a background thread (30 Hz)."""
        if self._thread is None:
            self._thread = threading.Thread(target=self.run, name="dualpuma-viewer-loop", daemon=True)
            self._thread.start()

    def run(self) -> None:
        """Loop at 30 Hz until :meth:`close` (or Ctrl-C when run in the main thread)."""
        while not self._stop.is_set():
            t0 = time.perf_counter()
            try:
                self.step()
            except Exception:
                log.exception("viewer update failed")
            time.sleep(max(0.0, 1 / 30 - (time.perf_counter() - t0)))

    def close(self) -> None:
        """Stop the loop, the worker and the server."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
        self._executor.shutdown(wait=False, cancel_futures=True)
        self.server.stop()


def serve(cell: Cell | None = None, host: str = "127.0.0.1", port: int | str = 8080, *, data_dir=DEFAULT_DATA_DIR,
          allow_hosts=(), cell_label: str | None = None) -> None:
    """Start the viewer, print its URL and block until Ctrl-C.

    Raises:
        ParameterError: the host or port cannot be used (nothing started).
    """
    app = ViewerApp(cell, host, port, data_dir=data_dir, allow_hosts=allow_hosts, cell_label=cell_label)
    try:
        print(f"dualpuma viewer: {app.url}  (Ctrl-C to stop)", flush=True)
        app.run()
    except KeyboardInterrupt:
        pass
    finally:
        app.close()
        print("dualpuma viewer: stopped", flush=True)
