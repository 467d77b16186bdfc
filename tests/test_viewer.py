"""Viewer (Python level): intents drive the state through the loop, the scene shows Pinocchio's
poses, and each defect of issue 15 stays fixed. Tests that must act as a browser tab would (the
client of an event, the callback wiring) use ``viser_client.Client`` over viser's own protocol."""

from __future__ import annotations

import math
import re
import time
import types

import numpy as np
import pinocchio as pin
import pytest
from viewer_checks import hand, serve_process, wait
from viser_client import Client

from dualpuma.kinematics import BRANCH_NAMES, Arm
from dualpuma.model import Cell, World, example_cell
from dualpuma.scenarios import run_routine
from dualpuma.viewer.app import TYPING_PAUSE, ViewerApp, capsule_mesh
from dualpuma.viewer.arm_visual import ArmVisual
from dualpuma.viewer.playback import Playback
from dualpuma.viewer.teach_moves import grasp_error


@pytest.fixture()
def app(tmp_path):
    a = ViewerApp(Cell.default(), port=0, data_dir=tmp_path / "data")
    yield a
    a.close()


def ws_url(app) -> str:
    return f"ws://127.0.0.1:{app.server.get_port()}"


def run(app, *intents) -> None:
    """Record intents as the server itself and let the loop apply them."""
    for it in intents:
        app.intent(*it) if isinstance(it, tuple) else app.intent(it)
    app.step()


def on_grasp(app, atol=1e-9):
    """Both hands exactly on their grasps of the shown object (independent FK)."""
    for side in ("left", "right"):
        G = app.T_object @ getattr(app.cell, f"grasp_{side}").T_object_hand
        np.testing.assert_allclose(hand(app.cell, side, app.q[side]), G, atol=atol)


def test_capsule_mesh_surface():
    v, f = capsule_mesh(0.05, 0.3)
    core = np.maximum(np.abs(v[:, 2]) - 0.15, 0)
    np.testing.assert_allclose(np.hypot(np.hypot(v[:, 0], v[:, 1]), core), 0.05, atol=1e-6)
    assert f.max() < len(v) and (np.abs(v[:, 2]) > 0.15).any()


# ---------------------------------------------------------------- arms drawn from the URDF
@pytest.mark.parametrize("robot", ["puma560", "ur5", "z1", "kinova"])
def test_urdf_visual_link_poses_equal_pinocchio(robot, rng):
    """ViserUrdf's link frames (yourdfpy, joints mapped by name; a Z1's gripper joint at its locked
    value, a Kinova's continuous joints) equal Pinocchio's FK to 1e-9."""
    import viser

    arm = Arm.load(robot)
    T_base = np.eye(4)
    T_base[:3, 3] = (1.0, -0.5, 0.7)
    T_base[:3, :3] = pin.rpy.rpyToMatrix(0.1, -0.2, 0.3)
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        av = ArmVisual(server, arm, T_base, "/arm", (200, 100, 50))
        links = [f.name for f in arm.model.frames if f.type == pin.FrameType.BODY]
        assert len(links) >= 7
        lo, hi = arm.limits[:, 0], arm.limits[:, 1]
        for q in rng.uniform(np.maximum(lo, -3), np.minimum(hi, 3), size=(5, 6)):
            av.update(q)
            for link in links:
                np.testing.assert_allclose(av.link_pose(link), T_base @ arm.fk(q, link), atol=1e-9, err_msg=link)
    finally:
        server.stop()


def test_arms_are_posed_by_the_loop_and_have_their_own_colours(app):
    run(app, ("joint.left.0", 62.0))
    q = app.state.pose.q_left
    assert math.degrees(q[0]) == pytest.approx(62.0, abs=1e-9)
    for side in ("left", "right"):
        T = app.scene.arms[side].link_pose("link3")
        np.testing.assert_allclose(T, getattr(app.cell, side).T_world_base @ Arm.puma560().fk(app.q[side], "link3"),
                                   atol=1e-9)
    colours = {side: {tuple(c[:3]) for g in a.urdf.scene.geometry.values() for c in g.visual.face_colors}
               for side, a in app.scene.arms.items()}
    from dualpuma.viewer.scene import ARM_COLORS

    assert ARM_COLORS["left"] in colours["left"] and ARM_COLORS["right"] in colours["right"]
    assert ARM_COLORS["left"] not in colours["right"]


# ---------------------------------------------------------------- state that lies (issue 15)
def test_non_finite_and_malformed_values_are_refused(app):
    q0 = app.q["left"].copy()
    run(app, ("joint.left.0", float("nan")))
    assert "not a finite number" in app.message
    run(app, ("joint.left.0", "12"))
    assert "expected a number" in app.message
    run(app, ("speed", float("inf")))
    assert app.settings["speed"] == 1.0
    np.testing.assert_array_equal(app.q["left"], q0)
    assert app.controls.handles["joint.left.0"].value == pytest.approx(round(math.degrees(q0[0]), 1))


def test_jog_then_a_slider_of_the_same_arm_both_apply(app):
    """The jog stored IK's read-only array; the next slider of that arm raised ValueError."""
    c = Client(ws_url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 1, what="client")
        H0 = hand(app.cell, "left", app.q["left"])
        app.intent("jog_frame", "left hand")
        run(app, ("jog", "+z", "button"))
        H1 = hand(app.cell, "left", app.q["left"])
        np.testing.assert_allclose(H1[:3, 3] - H0[:3, 3], [0, 0, 0.01], atol=1e-9)
        target = round(math.degrees(app.q["left"][0]) + 1.5, 1)
        c.set(app.controls.handles["joint.left.0"], target)
        wait(lambda: abs(math.degrees(app.q["left"][0]) - target) < 1e-9, step=app.step, what="the slider after the jog")
        on_grasp(app)
    finally:
        c.close()


def test_joint_move_keeps_the_grasp_partner_follows(app):
    """Joint mode let the right gripper let go; now the partner arm follows by IK."""
    for key, v in (("joint.left.0", 63.0), ("joint.left.5", -20.0), ("joint.right.2", 30.0)):
        run(app, (key, v))
        on_grasp(app)
    assert math.degrees(app.q["right"][2]) == pytest.approx(30.0, abs=1e-9)
    # a move the partner cannot follow stops where it still can, and says so (a held arrow key, whose
    # values viser throttles into jumps, or a value typed past that point moved nothing at all)
    start = math.degrees(app.q["left"][0])
    before_swing, before_left = app.q["right"].copy(), app.q["left"].copy()
    run(app, ("joint.left.0", -150.0))
    stop = math.degrees(app.q["left"][0])
    assert "stopped at" in app.message and "cannot follow beyond" in app.message, app.message
    assert -150.0 < stop < start - 1.0
    on_grasp(app)
    # on the way the right wrist swung fast near its singularity (q4 about 130 deg for 25 deg of the
    # left q1): followed in finer steps; the old step check called it a branch flip and refused at
    # 58.7 deg. Independent of _follow's halving: the same move in 0.05 deg steps of q1, each solved
    # from the last by the public IK, nowhere jumps a joint by more than 10 deg (a flip turns the wrist
    # 180 deg at once) and ends at the same joints
    assert stop < 50.0 and abs(math.degrees(app.q["right"][3] - before_swing[3])) > 90.0
    qR, qL = before_swing.copy(), before_left.copy()
    for x in np.linspace(math.radians(start), math.radians(stop), int((start - stop) / 0.05) + 1)[1:]:
        qL[0] = x
        T_obj = hand(app.cell, "left", qL) @ np.linalg.inv(app.cell.grasp_left.T_object_hand)
        q_new = _right_ik_near(app, T_obj, qR)
        assert np.max(np.abs(q_new - qR)) < math.radians(10.0)
        qR = q_new
    np.testing.assert_allclose(qR, app.q["right"], atol=1e-6)
    # ... which is where it stops: a step further (0.05 deg) is refused whole, nothing moves
    before = {s: app.q[s].copy() for s in ("left", "right")}
    run(app, ("joint.left.0", stop - 0.05))
    assert "cannot follow" in app.message and "this move was not made" in app.message
    for side, q in before.items():
        np.testing.assert_array_equal(app.q[side], q)


def _right_ik_near(app, T_world_object, q_near):
    """The right arm's IK solution nearest ``q_near`` holding its grasp of the object at
    ``T_world_object`` (the public all-branch IK, the nearest of the valid ones)."""
    arm = app.world.arms["right"]
    T = np.linalg.inv(app.cell.right.T_world_base) @ T_world_object @ app.cell.grasp_right.T_object_hand
    S, V = arm.ik_all(T)
    S = S[V]
    d = S - q_near
    d = (d + np.pi) % (2 * np.pi) - np.pi  # whole turns apart are the same place
    k = int(np.argmin(np.max(np.abs(d), axis=1)))
    return q_near + d[k]


# ---------------------------------------------------------------- controls that fight (issue 15)
def test_object_numbers_resync_after_a_refusal_and_after_a_jog(app):
    T0 = app.T_object.copy()
    run(app, ("object.x", 4000.0))
    assert "refused" in app.message
    np.testing.assert_array_equal(app.T_object, T0)
    assert app.controls.handles["object.x"].value == pytest.approx(round(T0[0, 3] * 1000, 1))
    run(app, ("object.y", T0[1, 3] * 1000 - 30.0))  # the next reachable move is accepted
    assert app.T_object[1, 3] == pytest.approx(T0[1, 3] - 0.03, abs=1e-12)
    assert app.T_object[0, 3] == pytest.approx(T0[0, 3], abs=1e-12)
    run(app, ("jog", "+z", "button"))
    z = app.T_object[2, 3]
    assert z == pytest.approx(T0[2, 3] + 0.01, abs=1e-12)
    assert app.controls.handles["object.z"].value == pytest.approx(round(z * 1000, 1))
    run(app, ("object.x", T0[0, 3] * 1000 - 20.0))  # does not undo the jog
    assert app.T_object[2, 3] == pytest.approx(z, abs=1e-12)
    on_grasp(app)


def test_gizmo_sits_on_the_object_follows_it_and_a_5mm_drag_is_accepted(app):
    from dualpuma.lie import quaternion_wxyz

    g = app.teach.gizmo
    T = app.T_object
    np.testing.assert_allclose(g.position, T[:3, 3], atol=1e-12)
    assert abs(abs(np.dot(g.wxyz, quaternion_wxyz(T[:3, :3]))) - 1.0) < 1e-9
    run(app, ("jog", "-y", "button"))
    np.testing.assert_allclose(g.position, app.T_object[:3, 3], atol=1e-12)
    c = Client(ws_url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 1, what="client")
        p = tuple(np.asarray(g.position) + (0.005, 0.0, 0.0))
        c.drag("/object_gizmo", "start")
        c.drag("/object_gizmo", "update", tuple(g.wxyz), p)
        c.drag("/object_gizmo", "end")
        wait(lambda: np.allclose(app.T_object[:3, 3], p, atol=1e-9), step=app.step, what="the gizmo drag")
        on_grasp(app)
    finally:
        c.close()


def test_a_switched_off_gizmo_moves_nothing(app):
    """'object gizmo' unticked hides it; a drag of it (only a program can send one) still moved the
    bar (found by a reviewer). Refused now, and the drag is not left open."""
    run(app, ("object_gizmo_on", False))
    assert app.teach.gizmo.visible is False
    T0 = app.T_object.copy()
    c = Client(ws_url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 1, what="client")
        p = tuple(T0[:3, 3] + (0.005, 0.0, 0.0))
        c.drag("/object_gizmo", "start")
        c.drag("/object_gizmo", "update", tuple(app.teach.gizmo.wxyz), p)
        c.drag("/object_gizmo", "end")
        wait(lambda: "switched off" in app.message, step=app.step, what="the refusal")
        for _ in range(5):
            app.step()
        np.testing.assert_array_equal(app.T_object, T0)
        assert not app.state.dragging
    finally:
        c.close()


def test_a_new_cells_arm_is_drawn_on_its_own_base_in_a_browser_open_across_the_switch(app):
    """Default cell (PUMA bases turned -90 deg about z) -> ur5_pair (the left UR5's base not turned):
    the browser drew the UR5 turned like the PUMA before it until the page was reloaded (found in
    Chromium by a helper). A browser keeps a node's last pose for a new node of the same name, and
    viser sends no pose equal to its default, so the client is replayed here that way: the pose a
    node shows is the last one sent under its name, identity if none."""
    from dualpuma.lie import quaternion_wxyz

    c = Client(ws_url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 1, what="client")
        run(app, ("cell_choice", "example: ur5_pair"), ("cell_action", "load cell", "button"))
        assert app.cell.name == "ur5_pair", app.message
        time.sleep(0.5)  # the messages of the switch reach the client
        for side in ("left", "right"):
            root = app.scene.arms[side].root
            shown = c.poses.get(root.name, {})
            T = app.world.T_world_base[side]
            q = np.asarray(shown.get("wxyz", (1.0, 0.0, 0.0, 0.0)))
            assert abs(abs(float(q @ quaternion_wxyz(T[:3, :3]))) - 1.0) < 1e-9, (side, root.name, shown)
            np.testing.assert_allclose(shown.get("position", (0.0, 0.0, 0.0)), T[:3, 3], atol=1e-6)
    finally:
        c.close()


def test_timing_is_offered_only_where_the_arms_have_the_limits_it_needs(app):
    """A UR5 has no acceleration limits (a URDF gives none) and the viewer has no box for them: the
    'timed trajectory' box was ticked in the UR cells and every plan said 'not timed' (found by a
    helper). It is disabled there, and says why; the PUMA cells keep it."""
    from dualpuma.planning.rate_limits import missing_rate_limits

    h = app.controls.handles["timed"]
    app.step()
    assert h.disabled is False and missing_rate_limits(app.world) == ""
    for name in ("mixed_puma_ur5", "ur5_pair"):
        run(app, ("cell_choice", f"example: {name}"), ("cell_action", "load cell", "button"))
        app.step()
        assert app.cell.name == name and h.disabled is True, app.message
        assert "a_max is needed" in h.hint and "ur5" in h.hint and "--a-max" in h.hint, h.hint
    run(app, ("cell_choice", "example: default"), ("cell_action", "load cell", "button"))
    app.step()
    assert h.disabled is False


def test_collision_highlight_turns_red(app):
    run(app, ("object.z", app.T_object[2, 3] * 1000 - 100.0))  # the gripper goes into the floor
    assert app.last_clearance.distance < app.cell.safety_margin
    from dualpuma.viewer.scene import COLORS

    assert tuple(np.asarray(app.scene.closest.colors).ravel()[:3]) == COLORS["collision"]
    assert "below the 20 mm margin" in app.teach.readout.content
    assert "⚠" in app.status.message or "mm" in app.status.message


def test_home_and_undo(app):
    T0 = app.T_object.copy()
    run(app, ("jog", "+x", "button"))
    run(app, ("jog", "+z", "button"))
    run(app, ("pose", "Undo", "button"))
    np.testing.assert_allclose(app.T_object[:3, 3], T0[:3, 3] + (0.01, 0, 0), atol=1e-12)
    run(app, ("pose", "Home", "button"))
    np.testing.assert_allclose(app.T_object, T0, atol=1e-12)
    run(app, ("pose", "Undo", "button"))
    np.testing.assert_allclose(app.T_object[:3, 3], T0[:3, 3] + (0.01, 0, 0), atol=1e-12)


# ---------------------------------------------------------------- playback (issue 15)
def _run_routine(app, n, confirm=False, timed=False):
    """Run routine n (step by step unless ``timed``: these tests are about playing a plan's steps;
    timed playback: test_viewer_wire.py and test_timed_playback_follows_the_trajectory)."""
    run(app, ("timed", timed))
    run(app, ("routine", next(o for o in app.controls.handles["routine"].options if o.startswith(f"{n}:"))),
        ("run", None, "button"))
    if confirm:
        run(app, ("switch", "switch and run", "button"))
    t0 = time.time()
    while app.busy and time.time() - t0 < 60:
        time.sleep(0.02)
        app.step(0.0)
    app.step(0.0)
    return app.playback


def test_playback_is_interpolated_at_real_speed(app):
    pb = _run_routine(app, 2)
    p = pb.plan
    assert p.reached and app.state.playing
    app.step(0.05)  # half of the 0.1 s between steps 0 and 1
    mid = 0.5 * (p.T_world_object[0, :3, 3] + p.T_world_object[1, :3, 3])
    np.testing.assert_allclose(app.T_object[:3, 3], mid, atol=1e-9)
    np.testing.assert_allclose(app.q["left"], 0.5 * (p.q_left[0] + p.q_left[1]), atol=1e-12)
    app.step(10.0)
    assert not app.state.playing
    np.testing.assert_allclose(app.T_object, p.T_world_object[-1], atol=1e-12)
    assert "5/5" in app.routines.status.content


def test_a_stalled_loop_does_not_skip_playback(app):
    """A loop step that took long (rebuilding the scene for a routine's own cell took 1.8 s) lets
    playback run by at most MAX_STEP_DT: the routine's start is shown, not jumped over."""
    from dualpuma.viewer.app import MAX_STEP_DT

    _run_routine(app, 2)
    app.step()
    before = app.state.play_time
    time.sleep(1.0)
    app.step()  # wall time measured: 1 s since the last step
    assert app.state.playing and 0.0 < app.state.play_time - before <= MAX_STEP_DT + 1e-9


def test_timed_playback_follows_the_trajectory(app):
    """Ticked (the default): routine 8 (its own cell, 10 mm margin) is timed; the plot's x is time,
    the readout counts the plan's steps by their row times, and playing to the end lands on the
    goal with both hands on the bar (independent FK)."""
    pb = _run_routine(app, 8, confirm=True, timed=True)
    tr = pb.plan.trajectory
    assert pb.timed and tr is not None and tr.certified and pb.x_label == "t [s]"
    assert app.routines.timeline.label == "timeline [s]" and app.routines.timeline.precision == 2  # 1.23 s, not 1.2
    assert pb.x_end <= app.routines.timeline.max < pb.x_end + 0.01 + 1e-9  # rounded up to the slider's step
    # the slider's last mark (past the end, a round number) is the end, without a "clamped" warning
    # (it said "timeline: 2.4 is beyond the limit; clamped to 2.4" at a plan's last mark)
    run(app, ("timeline", float(app.routines.timeline.max)))
    assert app.state.play_time == pytest.approx(tr.t[-1], abs=1e-12) and "clamped" not in app.message
    t_mid = 0.5 * (tr.row_times[3] + tr.row_times[4])
    run(app, ("timeline", round(t_mid - tr.t[0], 2)))
    assert f"step 3/{pb.plan.n_steps}" in app.routines.status.content
    # -1 / +1 step by the plan's rows (they stepped one 10 ms sample and looked dead)
    for button, row in (("+1", 4), ("+1", 5), ("-1", 4), ("-1", 3), ("-1", 2)):
        run(app, ("play", button, "button"))
        assert app.state.play_time == pytest.approx(tr.row_times[row], abs=1e-12), button
        assert f"step {row}/{pb.plan.n_steps}" in app.routines.status.content
    app.step(100.0)
    run(app, ("play", "play", "button"))
    app.step(100.0)
    np.testing.assert_allclose(app.T_object, pb.plan.T_world_object[-1], atol=1e-9)
    on_grasp(app)


def test_a_plan_is_judged_by_the_margin_it_kept(app):
    """Routine 8 keeps 10 mm (docs/planner.md); the cell's margin is 20 mm. Shown at its closest
    row (14.4 mm), the plot draws the 10 mm line and nothing is flagged below the margin (the old
    viewer drew 20 mm under a curve that kept 10 mm and flagged the row red)."""
    from dualpuma.viewer.scene import COLORS

    pb = _run_routine(app, 8, confirm=True, timed=False)
    assert app.cell.safety_margin == pytest.approx(0.020)
    assert app.routines.plot.margin_mm == pytest.approx(10.0)
    k = int(np.argmin(pb.plan.clearance))
    assert 0.010 < pb.plan.clearance[k] < 0.020
    run(app, ("play", "pause", "button"), ("timeline", float(k)))
    app.step(0.0)
    assert app.state.view == "plan" and app.last_clearance.distance == pytest.approx(pb.plan.clearance[k], abs=1e-6)
    assert "⚠" not in app.status._summary
    assert tuple(np.asarray(app.scene.closest.colors).ravel()[:3]) == COLORS["clear"]
    # the planner's events are in metres (API values); the page shows them in millimetres
    first = float(re.search(r"clearance (\d+\.\d+) m below", pb.plan.events[0]).group(1))
    assert f"clearance {first * 1000:.1f} mm below 10 mm" in app.routines.events.content
    assert not re.search(r"\d m\b", app.routines.events.content)


def test_pause_says_paused_and_stops_time(app):
    _run_routine(app, 8, confirm=True)
    app.step(0.3)
    run(app, ("play", "pause", "button"))
    t = app.state.play_time
    app.step(0.5)
    assert app.state.play_time == t and not app.state.playing
    assert "paused" in app.routines.status.content and "playing" not in app.routines.status.content
    assert app.status._summary.startswith("paused routine 8")  # the title bar text


def test_a_jog_keeps_the_plan_and_play_resumes_it(app):
    pb = _run_routine(app, 2)
    app.step(0.2)
    run(app, ("play", "pause", "button"), ("jog", "+z", "button"))
    assert app.plan is pb.plan and app.state.view == "teach"
    np.testing.assert_allclose(app.T_object[:3, 3], pb.plan.T_world_object[2, :3, 3] + (0, 0, 0.01), atol=1e-9)
    run(app, ("play", "play", "button"))
    assert app.state.playing and app.state.view == "plan"
    app.step(10.0)
    np.testing.assert_allclose(app.T_object, pb.plan.T_world_object[-1], atol=1e-12)


def test_a_timed_trajectory_is_played_when_the_plan_has_one():
    """Stand-in for the timed trajectories of issue 13: plan.trajectory with t, q_left, q_right."""
    p = run_routine(2)
    world = World(Cell.default())
    t = np.linspace(0.0, 2.0, 41)
    s = np.interp(t, [0.0, 2.0], [0.0, p.n_steps])
    qL = np.array([np.interp(s, np.arange(p.n_steps + 1), p.q_left[:, j]) for j in range(6)]).T
    qR = np.array([np.interp(s, np.arange(p.n_steps + 1), p.q_right[:, j]) for j in range(6)]).T
    stand_in = types.SimpleNamespace(**{k: getattr(p, k) for k in ("T_world_object", "q_left", "q_right", "clearance",
                                                                    "pair", "t", "events", "status", "reason")})
    stand_in.trajectory = types.SimpleNamespace(t=t, q_left=qL, q_right=qR)
    pb = Playback.from_plan(stand_in, "timed", world)
    assert pb.timed and pb.x_label == "t [s]" and pb.t_end == pytest.approx(2.0)
    smp = pb.sample(1.075)  # halfway between trajectory samples 21 and 22
    np.testing.assert_allclose(smp.q_left, 0.5 * (qL[21] + qL[22]), atol=1e-12)
    T = world.T_world_base["left"] @ world.arms["left"].fk(qL[20]) @ np.linalg.inv(world.T_object_hand["left"])
    np.testing.assert_allclose(pb.sample(1.0).T_object, T, atol=1e-12)
    d, _ = world.min_distance(qL[7], qR[7], pb.T_object[7])
    assert pb.clearance[7] == pytest.approx(d)
    # a plan without a usable trajectory falls back to its steps
    stand_in.trajectory = types.SimpleNamespace(t=t[::-1], q_left=qL, q_right=qR)
    assert not Playback.from_plan(stand_in, "steps", world).timed


def test_button_results_are_toasts(app):
    """Record, clear and undo told their result on the message line only, which the panel scrolls
    out of view beside the right arm's sliders (a keyboard user never saw "recorded waypoint 1")."""
    app.start()
    c = Client(ws_url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 1, what="client")
        c.set(app.controls.handles["waypoints"], "record")
        c.wait_notification("recorded waypoint 1")
        assert len(app.state.waypoints) == 1
        c.set(app.controls.handles["waypoints"], "clear")
        c.wait_notification("waypoints cleared")
        assert len(app.state.waypoints) == 0
        q0 = app.q["left"].copy()
        c.set(app.controls.handles["joint.left.0"], round(math.degrees(q0[0]) + 1.0, 1))
        wait(lambda: abs(app.q["left"][0] - q0[0]) > 0.01, what="the joint move")
        c.set(app.controls.handles["pose"], "Undo")
        c.wait_notification("undone")
        np.testing.assert_array_equal(app.q["left"], q0)
    finally:
        c.close()


def test_the_timeline_moved_without_a_plan_goes_back(app):
    """Keyboard arrows on the timeline before any plan: refused, and the page's slider stayed at
    0.3 for good (nothing wrote it back)."""
    app.start()
    c = Client(ws_url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 1, what="client")
        handle = app.controls.handles["timeline"]
        c.set(handle, 0.3)
        wait(lambda: "no plan to scrub" in app.message, what="the refusal")
        wait(lambda: handle.value == 0.0, what="the slider written back")
    finally:
        c.close()


def test_clearance_plot_has_a_numeric_axis_and_a_marker_at_the_current_step(app):
    pb = _run_routine(app, 8, confirm=True)
    plot = app.routines.plot
    assert plot.handle.scales["x"]["time"] is False
    run(app, ("timeline", 7.0))
    xs, marker, y = plot.handle.data[:3]
    k = np.flatnonzero(xs == 7.0)
    assert len(k) >= 4 and np.ptp(marker[k]) > 0  # a vertical segment at x = 7
    assert y[k[0]] == pytest.approx(pb.clearance[7] * 1000.0)
    assert app.controls.handles["timeline"].value == pytest.approx(7.0)


def test_routine1_readout_matches_the_plot(app):
    """The read-out said -247 mm bar-floor where the plot said +40 mm: the cube was not shown."""
    pb = _run_routine(app, 1, confirm=True)
    assert pb.mismatch < 1e-9
    for k in (0, 5, 10, 20):
        run(app, ("timeline", float(k)))
        shown = float(app.teach.readout.content.split("**clearance ")[1].split(" mm")[0])
        assert shown == pytest.approx(app.routines.plot.value_at(k), abs=0.051)
        assert shown == pytest.approx(pb.plan.clearance[k] * 1000.0, abs=0.051)


# ---------------------------------------------------------------- cells (issue 15)
def test_a_routine_with_its_own_cell_asks_and_back_restores_the_users_cell(tmp_path):
    app = ViewerApp(example_cell("agv"), port=0, data_dir=tmp_path, cell_label="startup: agv")
    try:
        run(app, ("joint.left.0", 62.0), ("waypoints", "record", "button"))
        pose = app.state.pose
        run(app, ("routine", next(o for o in app.controls.handles["routine"].options if o.startswith("8:"))),
            ("run", None, "button"))
        assert app.pending_routine is not None and app.cell.name == "agv" and not app.busy
        assert app.routines.switch.visible and "routine8-overhang" in app.routines.confirm.content
        run(app, ("switch", "switch and run", "button"))
        wait(lambda: app.plan is not None, step=app.step, what="routine 8", timeout=60)
        assert app.cell.name == "routine8-overhang" and app.routines.back.visible
        run(app, ("back", None, "button"))
        assert app.cell.name == "agv" and app.plan is None and len(app.state.waypoints) == 1
        assert app.state.pose is pose
        assert [o.name for o in app.world.cell.obstacles] == [o.name for o in example_cell("agv").obstacles]
    finally:
        app.close()


def test_a_routine_runs_at_once_in_a_loaded_copy_of_its_own_cell(tmp_path):
    """The routine's cell saved by the user under another name and loaded from the data directory
    is the routine's geometry: the routine runs there without asking to switch cells; one
    obstacle moved by 1 mm makes it another cell, and the switch is asked for."""
    import dataclasses

    from dualpuma.model import save_cell
    from dualpuma.scenarios import routine_cell

    data = tmp_path / "data"
    data.mkdir()
    cell = routine_cell(8)
    save_cell(dataclasses.replace(cell, name="my copy"), data / "copy.toml")
    ob = cell.obstacles[0]
    T = ob.T_world_obstacle.copy()
    T[0, 3] += 0.001
    moved = dataclasses.replace(cell, obstacles=(dataclasses.replace(ob, T_world_obstacle=T), *cell.obstacles[1:]))
    save_cell(moved, data / "moved.toml")
    app = ViewerApp(example_cell("agv"), port=0, data_dir=data, cell_label="startup: agv")
    try:
        r8 = next(o for o in app.controls.handles["routine"].options if o.startswith("8:"))
        run(app, ("cell_action", "refresh list", "button"))
        run(app, ("cell_choice", "file: copy.toml"), ("cell_action", "load cell", "button"))
        assert app.cell.name == "my copy", app.message
        run(app, ("routine", r8), ("run", None, "button"))
        assert app.pending_routine is None
        wait(lambda: app.plan is not None, step=app.step, what="routine 8", timeout=60)
        assert app.cell.name == "my copy" and app.plan.reached
        run(app, ("cell_choice", "file: moved.toml"), ("cell_action", "load cell", "button"))
        run(app, ("routine", r8), ("run", None, "button"))
        assert app.pending_routine is not None and app.cell.name == "routine8-overhang"
    finally:
        app.close()


def test_cell_selector_loads_an_example_and_a_data_file(app, tmp_path):
    from dualpuma.model import save_cell

    opts = app.controls.handles["cell_choice"].options
    assert "example: routine7_box" in opts
    run(app, ("cell_choice", "example: routine7_box"), ("cell_action", "load cell", "button"))
    assert app.cell.name == "routine7_box" and len(app.scene.geom_nodes) >= 2
    (tmp_path / "data").mkdir(exist_ok=True)
    save_cell(example_cell("agv"), tmp_path / "data" / "mine.toml")
    run(app, ("cell_action", "refresh list", "button"))
    assert "file: mine.toml" in app.controls.handles["cell_choice"].options
    run(app, ("cell_choice", "file: mine.toml"), ("cell_action", "load cell", "button"))
    assert app.cell.name == "agv" and app.cell_label == "file: mine.toml"
    run(app, ("cell_choice", "file: ../etc.toml"))
    assert "not one of the choices" in app.message


def test_a_data_file_cell_may_use_a_urdf_arm_only_from_inside_the_data_directory(app, tmp_path):
    """A cell in the data directory with robot = { urdf, tip }: the URDF next to it loads; one
    outside the directory (absolute, ``..``, or a link out) is refused before it is opened."""
    import dataclasses
    from pathlib import Path

    from dualpuma.kinematics import RobotSpec
    from dualpuma.model import ArmMount, cell_to_toml

    arm6 = Path(__file__).parent / "data" / "arm6.urdf"
    data = tmp_path / "data"
    data.mkdir(exist_ok=True)
    (data / "arm6.urdf").write_text(arm6.read_text())
    base = example_cell("mixed_puma_ur5")
    T_wb = np.eye(4)
    T_wb[:3, 3] = (2.3, -0.45, 0.0)
    T_wb[:3, :3] = np.diag([-1.0, -1.0, 1.0])
    arm = Arm.from_urdf(arm6, "tool")
    T_bh = np.linalg.inv(T_wb) @ base.T_world_object_start @ base.grasp_right.T_object_hand
    r = arm.ik(T_bh, q_near=np.array([0.0, 0.5, 1.3, 0.0, 1.3, 0.0]))
    assert r.ok
    cell = dataclasses.replace(base, right=ArmMount("right", RobotSpec(data / "arm6.urdf", "tool"), T_wb, r.q),
                               obstacles=())
    text = cell_to_toml(cell).replace(str(data / "arm6.urdf"), "arm6.urdf")
    (data / "inside.toml").write_text(text)
    outside = tmp_path / "elsewhere" / "never.urdf"  # does not exist: refused for where it is, not for that
    (data / "abs.toml").write_text(text.replace('"arm6.urdf"', f'"{outside}"'))
    (data / "up.toml").write_text(text.replace('"arm6.urdf"', '"../elsewhere/never.urdf"'))
    (data / "link.urdf").symlink_to(outside)
    (data / "link.toml").write_text(text.replace('"arm6.urdf"', '"link.urdf"'))
    run(app, ("cell_action", "refresh list", "button"))
    run(app, ("cell_choice", "file: inside.toml"), ("cell_action", "load cell", "button"))
    assert app.cell_label == "file: inside.toml" and app.world.arms["right"].robot == "arm6", app.message
    for name in ("abs", "up", "link"):
        run(app, ("cell_choice", f"file: {name}.toml"), ("cell_action", "load cell", "button"))
        assert app.cell_label == "file: inside.toml", name
        assert "outside" in app.message and "not a file" not in app.message, app.message
    # meshes: read and sent to every client, so they must be inside too (an outside file's vertices were)
    stl = "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 0.05 0 0\nvertex 0 0.05 0\nendloop\nendfacet\nendsolid t\n"
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "elsewhere" / "secret.stl").write_text(stl)
    (data / "parts").mkdir()
    (data / "parts" / "base.stl").write_text(stl)
    for name, mesh in (("meshin", "parts/base.stl"), ("meshabs", str(tmp_path / "elsewhere" / "secret.stl")),
                       ("meshup", "../elsewhere/secret.stl"), ("meshpkg", "package://elsewhere/secret.stl")):
        urdf = arm6.read_text().replace('<link name="base_link">', '<link name="base_link"><visual><geometry>'
                                        f'<mesh filename="{mesh}"/></geometry></visual>', 1)
        (data / f"{name}.urdf").write_text(urdf)
        (data / f"{name}.toml").write_text(text.replace('"arm6.urdf"', f'"{name}.urdf"'))
    run(app, ("cell_action", "refresh list", "button"))
    for name in ("meshabs", "meshup", "meshpkg"):
        run(app, ("cell_choice", f"file: {name}.toml"), ("cell_action", "load cell", "button"))
        assert app.cell_label == "file: inside.toml" and "names the mesh" in app.message, (name, app.message)
    run(app, ("cell_choice", "file: meshin.toml"), ("cell_action", "load cell", "button"))
    assert app.cell_label == "file: meshin.toml", app.message


# ---------------------------------------------------------------- files and messages
def test_waypoint_files_are_never_replaced_or_blanked_without_asking(app):
    """'overwrite' counts for one save or load, and is unticked after it (it stayed ticked, and a
    later save to another existing file replaced it unasked); a save with no waypoints writes
    nothing; a load does not drop waypoints recorded since the last save or load unless
    'overwrite' is ticked (they were replaced silently). The files are read back here."""
    import json

    f = app.data.root / "pick-1.json"
    run(app, ("file_name", "pick-1"), ("file_action", "save", "button"))
    assert "none recorded" in app.message and not f.exists()
    for _ in range(2):
        run(app, ("waypoints", "record", "button"))
    run(app, ("file_action", "save", "button"))
    two = f.read_text()
    assert len(json.loads(two)["T_world_object"]) == 2
    run(app, ("waypoints", "clear", "button"), ("waypoints", "record", "button"), ("overwrite", True),
        ("file_action", "save", "button"))
    assert "replacing the file that was there" in app.message and len(json.loads(f.read_text())["T_world_object"]) == 1
    assert app.settings["overwrite"] is False and app.controls.handles["overwrite"].value is False
    f.write_text(two)
    run(app, ("waypoints", "record", "button"), ("file_action", "save", "button"))  # 2 recorded, not ticked again
    assert "exists" in app.message and f.read_text() == two
    run(app, ("file_action", "load", "button"))
    assert "would replace the 2 waypoint(s)" in app.message and len(app.state.waypoints) == 2
    run(app, ("waypoints", "clear", "button"), ("overwrite", True), ("file_action", "save", "button"))
    assert "none recorded" in app.message and f.read_text() == two  # a real file is not blanked
    run(app, ("waypoints", "record", "button"), ("overwrite", True), ("file_action", "load", "button"))
    assert "loaded 2 waypoint(s)" in app.message and len(app.state.waypoints) == 2 and not app.settings["overwrite"]


def test_a_refused_save_or_load_uses_up_overwrite(app):
    """'overwrite' was unticked only by a save or load that succeeded: after a refused one (a bad
    name, a missing file) it stayed ticked, and the next save, by anyone, replaced an existing file
    unasked (found by a reviewer with two clients)."""
    f = app.data.root / "victim.json"
    run(app, ("waypoints", "record", "button"), ("file_name", "victim"), ("file_action", "save", "button"))
    kept = f.read_text()
    run(app, ("waypoints", "record", "button"))
    for name, action in (("victim 2", "save"), ("no-such-file", "load")):  # each refused
        run(app, ("overwrite", True), ("file_name", name), ("file_action", action, "button"))
        assert "not saved" in app.message or "not loaded" in app.message, app.message
        assert app.settings["overwrite"] is False and app.controls.handles["overwrite"].value is False
        run(app, ("file_name", "victim"), ("file_action", "save", "button"))
        assert "exists" in app.message and f.read_text() == kept


def test_waypoints_record_save_load_play(app):
    run(app, ("waypoints", "record", "button"))
    T = app.T_object.copy()
    T[:3, 3] += (-0.1, -0.05, 0.1)  # was (-0.1, 0, 0.05): robot 2's wrist vs its own pedestal (issue 13)
    run(app, ("object.x", T[0, 3] * 1000), ("object.y", T[1, 3] * 1000), ("object.z", T[2, 3] * 1000),
        ("waypoints", "record", "button"))
    run(app, ("file_name", "wp"), ("file_action", "save", "button"))
    f = app.data.root / "wp.json"
    assert f.exists() and "saved 2 waypoint(s)" in app.message
    saved = f.read_text()
    run(app, ("waypoints", "clear", "button"), ("file_action", "save", "button"))
    assert "not saved" in app.message and "exists" in app.message and f.read_text() == saved
    assert "tick 'overwrite'" in app.message and "overwrite=True" not in app.message  # the pendant's words
    run(app, ("file_action", "load", "button"))
    assert len(app.state.waypoints) == 2 and "loaded 2" in app.message
    np.testing.assert_allclose(app.state.waypoints[1], T, atol=1e-12)
    (app.data.root / "bad.json").write_text("{")
    run(app, ("file_name", "bad"), ("file_action", "load", "button"))
    assert "not loaded" in app.message and len(app.state.waypoints) == 2
    run(app, ("plan", "through waypoints", "button"))
    wait(lambda: not app.busy and app.plan is not None, step=app.step, what="the waypoint plan", timeout=60)
    assert app.plan.reached
    np.testing.assert_allclose(app.plan.T_world_object[-1], T, atol=1e-9)


def test_a_failed_save_is_told_to_its_sender_and_replaces_the_previous_message(app):
    a, b = Client(ws_url(app)), Client(ws_url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 2, what="clients")
        h = app.controls.handles["file_action"]
        a.set(app.controls.handles["waypoints"], "record")  # (nothing empty is saved)
        wait(lambda: len(app.state.waypoints) == 1, step=app.step, what="the waypoint")
        a.set(app.controls.handles["file_name"], "wp")
        a.set(h, "save")
        wait(lambda: "saved" in app.message, step=app.step, what="the save")
        a.wait_notification("saved 1 waypoint(s)")
        a.set(h, "save")
        wait(lambda: "not saved" in app.message, step=app.step, what="the refusal")
        assert "saved 1" not in app.status.line.content and "not saved" in app.status.line.content
        a.wait_notification("exists")
        time.sleep(0.3)
        assert not any("exists" in n[1] for n in b.notifications)  # told to its sender only
    finally:
        a.close()
        b.close()


# ---------------------------------------------------------------- look
def test_initial_camera_frames_the_cell_and_fit_view_moves_a_clients_camera(app):
    cam = app.server.initial_camera
    pts = app.scene.points()
    pos, look = np.asarray(cam.position), np.asarray(cam.look_at)
    fwd = (look - pos) / np.linalg.norm(look - pos)
    ang = np.degrees(np.arccos(np.clip((pts - pos) @ fwd / np.linalg.norm(pts - pos, axis=1), -1, 1)))
    assert ang.max() < np.degrees(cam.fov) / 2 * 1.6  # every point in view (horizontally wider)
    assert np.linalg.norm(look - pts.mean(axis=0)) < 1.0  # aimed at the cell, not the world origin
    c = Client(ws_url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 1, what="client")
        client = next(iter(app.server.get_clients().values()))
        before = np.asarray(client.camera.position).copy()
        c.set(app.controls.handles["fit"], "fit view")
        wait(lambda: not np.allclose(client.camera.position, before), step=app.step, what="fit view")
        assert np.linalg.norm(np.asarray(client.camera.look_at) - pts.mean(axis=0)) < 1.0
    finally:
        c.close()


def test_a_new_cell_is_framed_for_the_clients_already_here(app):
    """Loading the agv cell (a 1.2 m cart) reframes the camera of a client already connected, and
    the cart's corners are in view (only its centre was counted, and it stood half off-screen
    until 'fit view'); the corners are computed here from the cell's obstacle."""
    c = Client(ws_url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 1, what="client")
        client = next(iter(app.server.get_clients().values()))
        run(app, ("cell_choice", "example: agv"), ("cell_action", "load cell", "button"))
        app.step(0.0)
        ob = app.cell.obstacles[0]
        T = np.asarray(ob.pose_at(0.0))
        corners = np.array([T[:3, 3] + T[:3, :3] @ (0.5 * np.asarray(ob.size) * s)
                            for s in np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).T.reshape(-1, 3)])
        assert ob.shape == "box"

        def in_view() -> bool:
            pos, look = np.asarray(client.camera.position), np.asarray(client.camera.look_at)
            fwd = (look - pos) / np.linalg.norm(look - pos)
            ang = np.degrees(np.arccos(np.clip((corners - pos) @ fwd / np.linalg.norm(corners - pos, axis=1), -1, 1)))
            return bool(ang.max() < np.degrees(client.camera.fov) / 2 * 1.6)

        wait(in_view, step=app.step, what="the cart in the client's view")
        centre = np.mean([getattr(app.cell, s).T_world_base[:3, 3] for s in ("left", "right")] + [T[:3, 3]], axis=0)
        assert np.linalg.norm(centre) > 1.2  # the agv cell stands away from the world origin
        assert np.linalg.norm(np.asarray(client.camera.look_at) - centre) < 1.0  # aimed at it
    finally:
        c.close()


def test_overlays_off_by_default_with_a_legend_and_toggles(app):
    assert not app.scene.envelope.visible and not app.scene.real_envelope.visible
    assert not any(c.visible for c in app.scene.capsules.values())
    run(app, ("view.capsules", True), ("view.envelope", True), ("view.arms", False))
    assert all(c.visible for c in app.scene.capsules.values()) and app.scene.envelope.visible
    assert not app.scene.arms["left"].root.visible


def test_numbers_are_rounded_to_a_tenth(app):
    run(app, ("jog", "+rz", "button"))
    for key in ("joint.right.0", "object.x", "object.yaw"):
        v = app.controls.handles[key].value
        assert v == round(v, 1)
    assert "." in app.teach.readout.content and "mm" in app.teach.readout.content


def test_real_envelope_section_toggle(app):
    """The real envelope's x-z section: hidden at first, shown by its checkbox, and the drawn
    segments are the membership boundary (over 90 % of them, the grid resolves 25 mm)."""
    from dualpuma.envelope import contains_real

    node, env = app.scene.real_envelope, app.scene.real_envelope_model
    assert node is not None and not node.visible
    run(app, ("view.real_envelope", True))
    assert node.visible
    seg = env.xz_segments
    mid = seg.mean(axis=1)
    d = seg[:, 1] - seg[:, 0]
    normal = np.stack([-d[:, 2], np.zeros(len(d)), d[:, 0]], axis=1)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    a = contains_real(app.cell, mid + 0.01 * normal)
    b = contains_real(app.cell, mid - 0.01 * normal)
    assert np.mean(a != b) > 0.9


def test_grown_obstacles_toggle(tmp_path):
    import dataclasses

    from dualpuma.model import Obstacle

    c = dataclasses.replace(Cell.default(), obstacles=(Obstacle("b", "box", [0.1, 0.1, 0.1], np.eye(4)),))
    a2 = ViewerApp(c, port=0, data_dir=tmp_path)
    try:
        assert len(a2.scene.grown) == 1 and not a2.scene.grown[0][1].visible
        run(a2, ("view.grown", True))
        assert a2.scene.grown[0][1].visible
        g = a2.scene.grown[0][0]
        np.testing.assert_allclose(g.box_size, np.array([0.1, 0.1, 0.1]) + 2 * g.grow)
    finally:
        a2.close()


def test_the_loop_survives_a_bad_intent_and_an_internal_error(app, monkeypatch, caplog):
    def boom(*a, **k):
        raise RuntimeError("boom")

    monkeypatch.setattr(app.teach, "apply", boom)
    run(app, ("joint.left.0", 61.0))
    assert "internal error" in app.message and "boom" in app.message
    monkeypatch.undo()
    run(app, ("unknown.control", 1.0), ("joint.left.0", 61.0))
    assert math.degrees(app.q["left"][0]) == pytest.approx(61.0, abs=1e-9)


@pytest.mark.parametrize("cell", ["agv", "mixed_puma_ur5"])
def test_serve_command_prints_url_serves_and_stops_on_ctrl_c(tmp_path, cell):
    import signal
    import urllib.request

    proc = serve_process("--port", "auto", "--cell", cell, "--data-dir", str(tmp_path / "d"))
    try:
        line, t0 = "", time.time()
        while "dualpuma viewer: http://" not in line and time.time() - t0 < 60:
            line = proc.stdout.readline()
        url = line.split()[2]
        assert url.startswith("http://127.0.0.1:")
        with urllib.request.urlopen(url, timeout=10) as r:
            assert r.status == 200 and b"<html" in r.read(2000).lower()
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=20)
        assert proc.returncode == 0 and "stopped" in out and "Traceback" not in err
        assert "WARNING" not in err
    finally:
        if proc.poll() is None:
            proc.kill()


def test_serve_rejects_a_bad_cell_file(tmp_path):
    import subprocess
    import sys

    bad = tmp_path / "bad.toml"
    bad.write_text("name = 3\n")
    r = subprocess.run([sys.executable, "-m", "dualpuma.cli", "serve", "--cell", str(bad), "--port", "0"],
                       capture_output=True, text=True, timeout=60, check=False)
    assert r.returncode == 2 and "bad.toml" in r.stderr and "Traceback" not in r.stderr


def test_grasp_error_of_the_home_pose_is_zero(app):
    err = grasp_error(app.world, app.state.pose)
    assert max(e[0] for e in err.values()) < 1e-9


def test_plan_to_a_typed_goal(app):
    G = app.T_object.copy()
    G[:3, 3] += (-0.15, -0.05, 0.08)  # 50 mm in -y: robot 2's wrist stays clear of its own pedestal
    run(app, ("goal.x", G[0, 3] * 1000), ("goal.y", G[1, 3] * 1000), ("goal.z", G[2, 3] * 1000))
    np.testing.assert_allclose(app.settings["goal"], G, atol=1e-12)
    np.testing.assert_allclose(app.routines.goal.position, G[:3, 3], atol=1e-12)  # the goal gizmo follows
    run(app, ("plan", "plan to goal", "button"))
    wait(lambda: not app.busy and app.plan is not None, step=app.step, what="the plan", timeout=60)
    assert app.plan.reached and "plan to goal: reached" in app.message
    np.testing.assert_allclose(app.plan.T_world_object[-1], G, atol=1e-9)
    # at the goal, planning again has nothing to time: the message says so (it was silent)
    run(app, ("object.x", G[0, 3] * 1000), ("object.y", G[1, 3] * 1000), ("object.z", G[2, 3] * 1000))
    first = app.plan
    run(app, ("plan", "plan to goal", "button"))
    wait(lambda: not app.busy and app.plan is not first, step=app.step, what="the second plan", timeout=60)
    assert app.plan.reached and "(already at the goal), nothing to time" in app.message, app.message


def test_a_client_leaving_mid_drag_does_not_freeze_the_gizmo(app):
    c = Client(ws_url(app))
    wait(lambda: len(app.server.get_clients()) == 1, what="client")
    c.drag("/object_gizmo", "start")
    wait(lambda: app.state.dragging, step=app.step, what="the drag to start")
    c.close()
    wait(lambda: not app.state.dragging, step=app.step, what="the drag to be forgotten")
    run(app, ("jog", "+z", "button"))
    np.testing.assert_allclose(app.teach.gizmo.position, app.T_object[:3, 3], atol=1e-12)


def test_a_number_being_typed_is_applied_once_typing_pauses(app):
    """viser sends every keystroke: typing 1876.5 must not first try x = 1, 18, 187 mm."""
    app.start()
    c = Client(ws_url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 1, what="client")
        box = app.controls.handles["object.x"]
        target = round(app.T_object[0, 3] * 1000 - 10.0, 1)
        for k in range(1, len(str(target)) + 1):
            c.set(box, float(str(target)[:k].rstrip(".") or 0))
            time.sleep(0.08)
        time.sleep(0.1)
        assert box.value == pytest.approx(target)  # not overwritten while the user types
        wait(lambda: abs(app.T_object[0, 3] * 1000 - target) < 1e-9, what="the typed value", timeout=5)
        time.sleep(0.3)
        assert not [n for n in c.notifications if "refused" in n[1]]
    finally:
        c.close()


def test_a_number_typed_slowly_is_not_reset_under_the_cursor(app):
    """Typing 1876.5 into object x with 1.2 s between keys: each partial number (1, 18, 187, ...) is
    applied once typing pauses and refused (out of reach), but the box keeps what was typed until
    the next key, so the last value is the one typed, and it is applied."""
    app.start()
    c = Client(ws_url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 1, what="client")
        box = app.controls.handles["object.x"]
        before = app.T_object.copy()
        target = round(before[0, 3] * 1000 - 10.0, 1)
        text = str(target)
        for k in range(1, len(text) + 1):
            typed = float(text[:k].rstrip(".") or 0)
            c.set(box, typed)
            time.sleep(TYPING_PAUSE + 0.2)  # past it: the partial number is applied (and refused)
            assert box.value == pytest.approx(typed), f"after typing {text[:k]!r} the box shows {box.value}"
        wait(lambda: abs(app.T_object[0, 3] * 1000 - target) < 1e-9, what="the typed value", timeout=5)
        assert [n for n in c.notifications if "refused" in n[1] or "cannot" in n[1] or "reach" in n[1]]
        np.testing.assert_allclose(app.T_object[1:3, 3], before[1:3, 3], atol=1e-12)
    finally:
        c.close()


def test_refusals_in_a_row_share_one_toast(app):
    """A slider dragged where the other arm cannot follow is refused at every value: the toasts
    used to stack up (a dozen covered the 3-D view); refusals within TOAST_MERGE of each other now
    rewrite one toast, and the last refusal is what it says. A different kind of toast is new."""
    app.start()
    c = Client(ws_url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 1, what="client")
        client = next(iter(app.server.get_clients().values()))
        for k in range(12):
            app.status.tell(f"left q1 = {k} deg refused: the right arm cannot follow", "warn", client)
            time.sleep(0.05)
        app.status.tell("saved", "ok", client)
        wait(lambda: c.notifications and c.notifications[-1][1] == "saved", what="the last toast")
        assert c.toasts_shown == 2
        assert ("Refused", "left q1 = 11 deg refused: the right arm cannot follow") in c.notifications
    finally:
        c.close()


def test_a_joint_typed_into_its_slider_box_is_applied_once_typing_pauses(app):
    """Typing 45 into left q1's number box (60.6 deg) at a person's speed: viser sends 4, then 45;
    4 was applied at once and refused (the right arm cannot follow), and the box was reset under
    the cursor. The typed joint is now applied once typing pauses, like the other number boxes,
    while a drag's small moves are applied as they come."""
    app.start()
    c = Client(ws_url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 1, what="client")
        box = app.controls.handles["joint.left.0"]
        start = math.degrees(app.q["left"][0])
        assert abs(start - 45.0) > 10.0
        for typed in (4.0, 45.0):
            c.set(box, typed)
            time.sleep(0.3)  # a key every 0.3 s (below TYPING_PAUSE)
            assert box.value == pytest.approx(typed)  # not reset under the cursor
        wait(lambda: abs(math.degrees(app.q["left"][0]) - 45.0) < 1e-9, what="the typed joint", timeout=5)
        assert not [n for n in c.notifications if "refused" in n[1].lower() or "cannot" in n[1]], c.notifications
        for k in range(1, 6):  # a drag: 0.5 deg at a time, each applied (the last one is where it ends)
            c.set(box, 45.0 + 0.5 * k)
            time.sleep(0.05)
        wait(lambda: abs(math.degrees(app.q["left"][0]) - 47.5) < 1e-9, what="the dragged joint", timeout=5)
    finally:
        c.close()


# ---------------------------------------------------------------- any two arms (issue 16)
@pytest.mark.parametrize("name", ["mixed_puma_ur5", "ur5_pair"])
def test_teach_and_plan_in_a_cell_with_ur_arms(name, tmp_path):
    """The pendant drives UR5s like PUMAs: a joint move of either arm keeps both grasps (FK of each
    arm's own URDF file, built here), a hand jog moves the hand 10 mm, the readout names each arm
    and its branch, and a typed goal is planned and reached."""
    from urdf_reference import FullUrdf

    cell = example_cell(name)
    app = ViewerApp(cell, port=0, data_dir=tmp_path)
    try:
        refs = {}
        for side in ("left", "right"):
            arm = app.world.arms[side]
            refs[side] = FullUrdf(arm.urdf_path, [arm.model.names[j] for j in range(1, 7)], arm.hand_frame)

        def hand_fk(side):
            return getattr(cell, side).T_world_base @ refs[side].fk(app.q[side])

        def grasped():
            for side in ("left", "right"):
                G = app.T_object @ getattr(cell, f"grasp_{side}").T_object_hand
                np.testing.assert_allclose(hand_fk(side), G, atol=1e-9)

        for key, delta in (("joint.right.0", 3.0), ("joint.left.5", -4.0)):
            side, j = key.split(".")[1], int(key.split(".")[2])
            target = round(math.degrees(app.q[side][j]) + delta, 1)
            run(app, (key, target))
            assert math.degrees(app.q[side][j]) == pytest.approx(target, abs=1e-9), app.message
            grasped()
        H0 = hand_fk("right")
        app.intent("jog_frame", "right hand")
        run(app, ("jog", "+z", "button"))
        np.testing.assert_allclose(hand_fk("right")[:3, 3] - H0[:3, 3], [0, 0, 0.01], atol=1e-9)
        grasped()
        readout = app.teach.readout.content
        assert "ur5" in readout and ("puma560" in readout) == name.startswith("mixed")
        assert sum(b in readout for b in BRANCH_NAMES) >= 2
        # the idealised envelope is the two-PUMA model: its toggle is disabled, and ticking it says so
        app.step(0.0)
        assert app.controls.handles["view.envelope"].disabled
        run(app, ("view.envelope", True))
        assert "nothing to draw for this cell" in app.message and not app.scene.visible["envelope"]
        G = np.array(app.settings["goal"])  # the goal keeps its orientation; its position is typed
        G[:3, 3] = app.T_object[:3, 3] + (-0.08, 0.0, 0.05)
        run(app, ("goal.x", G[0, 3] * 1000), ("goal.y", G[1, 3] * 1000), ("goal.z", G[2, 3] * 1000))
        run(app, ("plan", "plan to goal", "button"))
        wait(lambda: not app.busy and app.plan is not None, step=app.step, what="the plan", timeout=60)
        assert app.plan.reached, app.message
        np.testing.assert_allclose(app.plan.T_world_object[-1], G, atol=1e-9)
    finally:
        app.close()


def test_a_timed_plan_waits_for_a_moving_ball(tmp_path):
    """A cell with a ball rising through the bar's path at t = 0.5..1.0 s: planning to a goal
    across it (timed, the default) gives a certified trajectory that waits at the start; the
    message says so; scrubbed into the wait the arms are at the start, and later the ball is drawn
    where it is at that time (its pose from its own velocity, computed here)."""
    from dualpuma.scenarios import rising_ball_cell

    cell, _, B = rising_ball_cell(0.5, 1.0)
    app = ViewerApp(cell, port=0, data_dir=tmp_path)
    try:
        G = B
        run(app, ("goal.x", G[0, 3] * 1000), ("goal.y", G[1, 3] * 1000), ("goal.z", G[2, 3] * 1000))
        run(app, ("plan", "plan to goal", "button"))
        wait(lambda: not app.busy and app.plan is not None, step=app.step, what="the plan", timeout=60)
        p, tr = app.plan, app.plan.trajectory
        assert p.reached and tr is not None and tr.certified and tr.start_delay > 0, app.message
        assert "waits" in app.message and "to let a moving obstacle pass" in app.message
        run(app, ("timeline", round(0.5 * tr.start_delay, 2)))
        np.testing.assert_allclose(app.q["left"], p.q_left[0], atol=1e-12)
        np.testing.assert_allclose(app.q["right"], p.q_right[0], atol=1e-12)
        t = 0.75
        run(app, ("timeline", t - tr.t[0]))
        assert np.abs(app.q["left"] - p.q_left[0]).max() > 1e-3  # moving by then
        node = app.scene.geom_nodes[app.world.obstacle_ids[0]]
        ball = cell.obstacles[0]
        np.testing.assert_allclose(node.position, ball.T_world_obstacle[:3, 3] + (0.0, 0.0, t - 0.5), atol=1e-9)
        on_grasp(app, atol=0.5e-3)  # the timed trajectory's closed-chain tolerance
    finally:
        app.close()


def test_the_plan_clock_is_a_setting(tmp_path):
    """A ball that parks in the bar's path: the timed plan is not certified and the message says how
    much slower a clock to plan with; typed into "step time [s]", the next plan freezes at the ball
    instead. A value beyond the range is clamped and said so."""
    import re as _re

    from dualpuma.scenarios import rising_ball_cell

    cell, _, B = rising_ball_cell(0.45, 0.6)
    app = ViewerApp(cell, port=0, data_dir=tmp_path)
    try:
        run(app, ("goal.x", B[0, 3] * 1000), ("goal.y", B[1, 3] * 1000), ("goal.z", B[2, 3] * 1000))
        run(app, ("plan", "plan to goal", "button"))
        wait(lambda: not app.busy and app.plan is not None, step=app.step, what="the plan", timeout=60)
        assert app.plan.reached and not app.plan.trajectory.certified
        m = _re.search(r"up to ([0-9.]+)x sooner than the arms can reach them", app.message)
        assert m, app.message
        factor = float(m.group(1))
        run(app, ("step_time", round(0.1 * factor, 2)))
        assert app.settings["step_time"] == pytest.approx(round(0.1 * factor, 2))
        first = app.plan
        run(app, ("plan", "plan to goal", "button"))
        wait(lambda: not app.busy and app.plan is not first, step=app.step, what="the second plan", timeout=60)
        assert app.plan.status == "frozen" and "obstacle/ball" in app.plan.reason, app.message
        run(app, ("step_time", 100.0))
        assert app.settings["step_time"] == 10.0 and "clamped" in app.message
        run(app, ("step_time", 0.0))  # the message shows the limit it clamped to, not "0.0 s"
        assert app.settings["step_time"] == 0.01 and "clamped to 0.01 s" in app.message, app.message
    finally:
        app.close()


def test_a_ur_pose_whose_meshes_may_touch_is_flagged_in_the_title(tmp_path):
    """The UR5's upper arm folded down by its base (the left arm's branch 0 at the start pose: its
    meshes intersect, tests/test_contact.py) passes the capsule checks; the title bar says it may
    touch, and stops saying so back at home."""
    import dataclasses

    from dualpuma.kinematics.dual import hands_from_object
    from dualpuma.model import example_cell
    from dualpuma.viewer.teach_moves import TeachPose

    cell = dataclasses.replace(example_cell("ur5_pair"), obstacles=())
    a = ViewerApp(cell, port=0, data_dir=tmp_path / "data")
    try:
        A = cell.T_world_object_start
        q = a.world.arms["left"].ik(hands_from_object(cell, A)[0], config=0).q
        a.state.reset(TeachPose.of(q, cell.right.q_home, A))
        a.step()
        assert "⚠ left base_link – upper_arm_link may touch" in a.status._summary
        a.state.reset(TeachPose.of(cell.left.q_home, cell.right.q_home, A))
        a.step()
        assert "may touch" not in a.status._summary
    finally:
        a.close()
