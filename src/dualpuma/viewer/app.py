"""`dualpuma serve`: the viser viewer — scene, teach pendant, routines and planning.

Threading (see ../shared/DESIGN.md): GUI callbacks (viser's threads) only record intent under a lock
(joint values, jog requests, object targets, button presses). One loop thread owns the World (FK,
IK, clearance) and moves every node inside ``server.atomic()`` at 30 Hz (:meth:`ViewerApp.step`;
tests call it directly). Planning and routines run in a worker thread with their own World; the loop
picks up the finished Plan and animates it. All browser tabs share this state; a tab closing
mid-animation changes nothing on the server.
"""

from __future__ import annotations

import math
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np
import viser

from ..errors import DualpumaError
from ..kinematics import puma
from ..kinematics.continuity import continue_branch
from ..kinematics.dual import SIDES, solve_path
from ..lie import angle, n_steps
from ..model.cell import Cell
from ..model.world import World
from ..planning.interpolation import interpolate_object
from ..planning.params import StrivingParams
from ..planning.plan import chain
from ..planning.striving import plan
from ..scenarios.routines import routine, run_routine
from .routines_panel import RoutinesPanel
from .scene import Scene, capsule_mesh
from .teach import TeachPanel, load_waypoints, save_waypoints

__all__ = ["ViewerApp", "capsule_mesh", "serve"]


class ViewerApp:
    """One viser server showing a cell (see the module docstring).

    Args:
        cell: the work cell.
        host, port: where to listen (loopback by default; port 0 = any free port).
    """

    def __init__(self, cell, host: str = "127.0.0.1", port: int = 8080) -> None:
        self.cell = cell
        self.world = World(cell)
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self._lock = threading.RLock()
        self.q = {s: np.array(getattr(cell, s).q_home, float) for s in SIDES}
        self.T_object = np.array(cell.T_world_object_start, float)
        self.mode = "joint"
        self.syncing = False
        self.message = ""
        self.waypoints: list[np.ndarray] = []
        self.plan = None
        self.plan_title = ""
        self.idx = 0.0
        self.playing = False
        self._jogs: list[tuple[str, np.ndarray, str]] = []
        self._object_target: np.ndarray | None = None
        self._future: Future | None = None
        self._pending_title = ""
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="dualpuma-plan")
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._last_t = time.perf_counter()
        self.scene = Scene(self.server, self.world)
        g = self.server.gui
        g.configure_theme(control_width="large")
        self.readout = g.add_markdown("")
        with g.add_folder("view", expand_by_default=False):
            self.show_grown = g.add_checkbox("grown obstacles (configuration mapping)", initial_value=False)
            self.show_grown.on_update(lambda _: self.scene.show_grown(self.show_grown.value))
            self.show_frames = g.add_checkbox("frames", initial_value=True)
            self.show_frames.on_update(lambda _: self.scene.show_frames(self.show_frames.value))
            self.show_env = g.add_checkbox("work-envelope arcs", initial_value=True)
            self.show_env.on_update(lambda _: self.scene.show_envelope(self.show_env.value))
            self.show_real_env = g.add_checkbox("real envelope, x-z section", False, disabled=self.scene.real_envelope is None)
            self.show_real_env.on_update(lambda _: self.scene.show_real_envelope(self.show_real_env.value))
        self.teach = TeachPanel(self)
        self.routines = RoutinesPanel(self)
        self.sliders = self.teach.sliders
        self.last_clearance = None
        self.step()

    # ------------------------------------------------------------------ intents (any thread)
    def set_joint_deg(self, side: str, j: int, deg: float) -> None:
        if self.syncing:
            return
        with self._lock:
            self._leave_playback()
            self.q[side][j] = math.radians(float(deg))
            if self.mode != "joint":
                self.mode = "joint"
                self.message = "joint mode: the object now follows the left hand"

    def set_mode(self, mode: str) -> None:
        if self.syncing:
            return
        with self._lock:
            self.mode = mode
            if mode == "coordinated":
                self._leave_playback()
                self.message = "coordinated mode: move the object; both arms follow (eq. 5.6)"

    def request_jog(self, side: str, delta: np.ndarray, frame: str) -> None:
        with self._lock:
            self._leave_playback()
            self._jogs.append((side, np.array(delta, float), frame))

    def request_object(self, T: np.ndarray) -> None:
        with self._lock:
            self._leave_playback()
            self.mode = "coordinated"
            self._object_target = np.array(T, float)

    def record_waypoint(self) -> None:
        with self._lock:
            self.waypoints.append(self.T_object.copy())
            self.message = f"recorded waypoint {len(self.waypoints)}"

    def clear_waypoints(self) -> None:
        with self._lock:
            self.waypoints.clear()
            self.message = "waypoints cleared"

    def save_waypoints(self, path: str, overwrite: bool = False) -> None:
        with self._lock:
            poses = list(self.waypoints)
        try:
            p = save_waypoints(path, poses, overwrite=overwrite)
            msg = f"saved {len(poses)} waypoints to {p}"
        except DualpumaError as e:
            msg = f"**not saved**: {e}"
        with self._lock:
            self.message = msg

    def load_waypoints(self, path: str) -> None:
        try:
            poses = load_waypoints(path)
            with self._lock:
                self.waypoints = poses
                self.message = f"loaded {len(poses)} waypoints from {path}"
        except DualpumaError as e:
            with self._lock:
                self.message = f"**not loaded**: {e}"

    def run_routine(self, n: int) -> None:
        self._submit(f"routine {n}", _routine_job, n)

    def plan_to_goal(self) -> None:
        with self._lock:
            T, q = self.T_object.copy(), (self.q["left"].copy(), self.q["right"].copy())
        goal = self.routines.goal_pose()
        params = StrivingParams(fallback=bool(self.routines.fallback.value))
        cell = self.cell
        self._submit("plan to goal", lambda: (plan(cell, T, goal, params, q_start=q), cell))

    def plan_waypoints(self) -> None:
        with self._lock:
            T, q, wps = self.T_object.copy(), (self.q["left"].copy(), self.q["right"].copy()), list(self.waypoints)
        if not wps:
            with self._lock:
                self.message = "no waypoints recorded"
            return
        cell = self.cell
        self._submit(f"{len(wps)} waypoints", lambda: (_plan_through(cell, T, q, wps), cell))

    def set_playing(self, on: bool) -> None:
        with self._lock:
            if self.plan is not None:
                if on and self.idx >= self.plan.T_world_object.shape[0] - 1:
                    self.idx = 0.0
                self.playing = bool(on)

    def step_playback(self, k: int) -> None:
        with self._lock:
            if self.plan is not None:
                self.playing = False
                self.idx = float(np.clip(int(self.idx) + k, 0, self.plan.T_world_object.shape[0] - 1))

    def seek(self, i: int) -> None:
        with self._lock:
            if self.plan is not None:
                self.playing = False
                self.idx = float(np.clip(i, 0, self.plan.T_world_object.shape[0] - 1))

    def _submit(self, title: str, fn, *args, **kw) -> None:
        with self._lock:
            if self._future is not None and not self._future.done():
                self.message = "busy: a plan is still being computed"
                return
            self._pending_title = title
            self.message = f"planning: {title} ..."
            self._future = self._executor.submit(fn, *args, **kw)

    def _leave_playback(self) -> None:
        if self.plan is not None:
            self.plan = None
            self.playing = False

    @property
    def busy(self) -> bool:
        """True while a plan/routine is being computed in the worker."""
        f = self._future
        return f is not None and not f.done()

    # ------------------------------------------------------------------ the loop (one thread)
    def step(self, dt: float | None = None) -> None:
        """One update: apply intents, advance playback, FK + clearance, move nodes atomically."""
        now = time.perf_counter()
        dt = now - self._last_t if dt is None else dt
        self._last_t = now
        new_plan = None
        with self._lock:
            if self._future is not None and self._future.done():
                fut, self._future = self._future, None
                try:
                    new_plan, cell = fut.result()
                    if cell is not self.cell:  # a routine brings its own obstacles
                        self.cell, self.world = cell, World(cell)
                        with self.server.atomic():
                            self.scene.set_world(self.world)
                    self.message = f"{self._pending_title}: {new_plan.status} {new_plan.reason}".strip()
                except Exception as e:  # noqa: BLE001 - show, never crash the loop
                    self.message = f"**{self._pending_title} failed**: {type(e).__name__}: {e}"
            if new_plan is not None and new_plan.T_world_object.shape[0]:
                self.plan, self.plan_title, self.idx, self.playing = new_plan, self._pending_title, 0.0, True
            jogs, self._jogs = self._jogs, []
            target, self._object_target = self._object_target, None
            self._apply_teach(jogs, target)
            t = 0.0
            if self.plan is not None:
                n = self.plan.T_world_object.shape[0]
                if self.playing:
                    self.idx = min(self.idx + float(self.routines.speed.value) * dt, n - 1)
                    self.playing = self.idx < n - 1
                i = int(self.idx)
                self.q = {"left": self.plan.q_left[i].copy(), "right": self.plan.q_right[i].copy()}
                self.T_object, t = self.plan.T_world_object[i].copy(), float(self.plan.t[i])
            elif self.mode == "joint":
                self.T_object = self.world.object_from_left(self.q["left"])
            qL, qR, T, mode, msg = self.q["left"].copy(), self.q["right"].copy(), self.T_object.copy(), self.mode, self.message
            plan, idx, nwp = self.plan, int(self.idx), len(self.waypoints)
        c = self.world.clearance(qL, qR, T, t)
        hands = self.world.hand_poses(qL, qR)
        self.last_clearance = c
        text = self._readout(qL, qR, T, hands, c, mode, msg, plan, idx)
        with self.server.atomic():
            self.scene.update(c, T, hands, self.cell.safety_margin)
            self.readout.content = text
            self.teach.count.content = f"{nwp} waypoints"
            self.syncing = True
            try:
                if new_plan is not None:
                    self.routines.show_plan(new_plan, self.plan_title)
                    self.scene.set_path(new_plan.T_world_object)
                if plan is not None:
                    self.routines.timeline.value = idx
                    self.routines.status.content = f"{self.plan_title}: step {idx}/{plan.n_steps} ({plan.status})"
                for side, q in (("left", qL), ("right", qR)):
                    for j in range(6):
                        s = self.sliders[(side, j)]
                        v = float(np.clip(math.degrees(q[j]), s.min, s.max))
                        if abs(s.value - v) > 1e-6:
                            s.value = v
                if self.teach.mode.value != mode:
                    self.teach.mode.value = mode
                if mode != "coordinated" or plan is not None:
                    self.teach.show_object(T)
            finally:
                self.syncing = False

    def _apply_teach(self, jogs, target) -> None:
        """Jogs and object targets through our IK (called by the loop with the lock held)."""
        for side, d, frame in jogs:
            if self.mode == "coordinated":  # jog the object frame: both arms follow
                base = self.T_object if target is None else target
                if frame == "world":
                    target = base.copy()
                    target[:3, 3] += d[:3, 3]
                else:
                    target = base @ d
                continue
            arm, Tb = self.world.arms[side], self.world.T_world_base[side]
            H = Tb @ arm.fk(self.q[side])
            if frame == "world":
                H[:3, 3] += d[:3, 3]
            else:
                H = H @ d
            res = continue_branch(arm, np.linalg.inv(Tb) @ H, self.q[side])
            if res.ok:
                self.q[side] = res.q
                self.message = f"jogged the {side} hand"
            else:
                self.message = f"**{side} hand: {res.status}** — {res.reason}; not moved"
        if target is not None:
            # a large slider/gizmo move is followed through 10 mm / 2 deg steps (branch continuity)
            n = max(1, _n_teach_steps(self.T_object, target))
            path = interpolate_object(self.T_object, target, n)
            sol = solve_path(self.world, path, (self.q["left"], self.q["right"]))
            if sol.n_ok < n:
                self.message = f"**object pose refused** — {sol.reason}"
            else:
                self.q = {"left": sol.q_left[-1].copy(), "right": sol.q_right[-1].copy()}
                self.T_object = target
                self.message = "coordinated move"

    def _readout(self, qL, qR, T, hands, c, mode, msg, plan, idx) -> str:
        lines = [f"**mode** {mode}" + (f" · playing *{self.plan_title}* step {idx}" if plan is not None else "")]
        for side, q, H in (("left", qL, hands[0]), ("right", qR, hands[1])):
            R = np.round(H[:3, :3], 3)
            lines.append(
                f"**{side}** branch `{puma.BRANCH_NAMES[int(puma.branch_of(q))]}` · q [deg] "
                f"{np.round(np.degrees(q), 1).tolist()}  \nwrist [mm] {np.round(H[:3, 3] * 1000, 1).tolist()}  \n"
                f"R = {R[0].tolist()} {R[1].tolist()} {R[2].tolist()}"
            )
        below = c.distance < self.cell.safety_margin
        lines.append(f"**min clearance {c.distance * 1000:.1f} mm** ({c.pair[0]} – {c.pair[1]})"
                     + (" — **BELOW THE MARGIN (collision)**" if below else ""))
        lines.append(f"object [mm] {np.round(T[:3, 3] * 1000, 1).tolist()}")
        if msg:
            lines.append(msg)
        return "\n\n".join(lines)

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
            except Exception as e:  # noqa: BLE001 - keep serving; report on the page
                with self._lock:
                    self.message = f"**update failed**: {type(e).__name__}: {e}"
            time.sleep(max(0.0, 1 / 30 - (time.perf_counter() - t0)))

    def close(self) -> None:
        """Stop the loop, the worker and the server."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
        self._executor.shutdown(wait=False, cancel_futures=True)
        self.server.stop()

    @property
    def url(self) -> str:
        return f"http://{self.server.get_host()}:{self.server.get_port()}"


def _routine_job(n: int):
    """Worker: run a routine; returns (plan, the routine's cell)."""
    return run_routine(n), routine(n).cell


def _n_teach_steps(A: np.ndarray, B: np.ndarray) -> int:
    """Teach moves are followed in steps of at most 10 mm and 2 deg (branch continuity)."""
    return n_steps(float(np.linalg.norm(B[:3, 3] - A[:3, 3])), angle(A[:3, :3], B[:3, :3]), 0.01, math.radians(2.0))


def _plan_through(cell, T, q, waypoints):
    """Plan through taught waypoints, leg by leg (worker thread)."""
    world = World(cell)
    out = None
    for W in waypoints:
        leg = plan(cell, T, W, q_start=q, world=world)
        out = leg if out is None else chain(out, leg)
        if not leg.reached:
            break
        T, q = W, (leg.q_left[-1], leg.q_right[-1])
    return out


def serve(cell=None, host: str = "127.0.0.1", port: int = 8080) -> None:
    """Start the viewer, print its URL and block until Ctrl-C."""
    app = None
    try:
        app = ViewerApp(cell if cell is not None else Cell.default(), host, port)
        print(f"dualpuma viewer: {app.url}  (Ctrl-C to stop)", flush=True)
        app.run()
    except KeyboardInterrupt:
        pass
    finally:
        if app is not None:
            app.close()
        print("dualpuma viewer: stopped", flush=True)
