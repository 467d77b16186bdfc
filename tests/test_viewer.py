"""Viewer (Python level): GUI handles drive the state, the loop moves nodes to Pinocchio's poses."""

from __future__ import annotations

import json
import socket
import time

import numpy as np
import pinocchio as pin
import pytest

from dualpuma.model import Cell
from dualpuma.viewer.app import ViewerApp, capsule_mesh


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture()
def app():
    a = ViewerApp(Cell.default(), port=free_port())
    yield a
    a.close()


def _capsule_pose(app, side, name, q):
    """Independent FK of one capsule with the arm's own Pinocchio model."""
    arm = app.world.arms[side]
    data = arm.model.createData()
    pin.forwardKinematics(arm.model, data, q)
    cap = next(c for c in arm.capsules if c.name == name)
    return getattr(app.cell, side).T_world_base @ data.oMi[cap.joint].homogeneous @ cap.placement


def _node(app, name):
    return app.scene.geom_nodes[[g.name for g in app.world.geoms].index(name)]


def _hand(app, side, q):
    return getattr(app.cell, side).T_world_base @ app.world.arms[side].fk(q)


def test_capsule_mesh_surface():
    v, f = capsule_mesh(0.05, 0.3)
    core = np.maximum(np.abs(v[:, 2]) - 0.15, 0)
    np.testing.assert_allclose(np.hypot(np.hypot(v[:, 0], v[:, 1]), core), 0.05, atol=1e-6)
    assert f.max() < len(v) and (np.abs(v[:, 2]) > 0.15).any()


def test_slider_moves_forearm_node_to_pinocchio_pose(app):
    app.sliders[("left", 0)].value = 10.0  # runs on_update synchronously
    app.step()
    q = np.array(app.cell.left.q_home, float)
    q[0] = np.deg2rad(10.0)
    M = _capsule_pose(app, "left", "forearm", q)
    np.testing.assert_allclose(_node(app, "left/forearm").position, M[:3, 3], atol=1e-6)
    assert "min clearance" in app.readout.content and "left/up" in app.readout.content


def test_coordinated_sliders_move_both_arms_with_the_bar(app):
    app.teach.obj["x"].value = app.teach.obj["x"].value - 100.0
    app.step()
    T = app.teach.object_target()
    np.testing.assert_allclose(app.T_object, T, atol=1e-12)
    for side in ("left", "right"):
        np.testing.assert_allclose(_hand(app, side, app.q[side]), T @ getattr(app.cell, f"grasp_{side}").T_object_hand, atol=1e-9)
        M = _capsule_pose(app, side, "gripper", app.q[side])
        np.testing.assert_allclose(_node(app, f"{side}/gripper").position, M[:3, 3], atol=1e-6)
    bar = _node(app, "bar")
    np.testing.assert_allclose(bar.position, (T @ app.cell.bar.T_object_bar)[:3, 3], atol=1e-6)
    assert app.mode == "coordinated" and app.teach.mode.value == "coordinated"


def test_cartesian_jog_and_refusals(app):
    q0 = app.q["left"].copy()
    H0 = _hand(app, "left", q0)
    app.teach.jog_mm.value = 20.0
    app.teach.jog_buttons[("z", 1)].click() if hasattr(app.teach.jog_buttons[("z", 1)], "click") else app.teach.jog("z", 1)
    app.step()
    H1 = _hand(app, "left", app.q["left"])
    np.testing.assert_allclose(H1[:3, 3] - H0[:3, 3], [0, 0, 0.02], atol=1e-9)
    np.testing.assert_allclose(H1[:3, :3], H0[:3, :3], atol=1e-9)
    # far beyond reach: refused with a message, nothing moves
    q1 = app.q["left"].copy()
    app.teach.jog_mm.value = 200.0
    for _ in range(8):
        app.teach.jog("x", -1)
    app.step()
    assert "not moved" in app.message
    assert np.all(np.isfinite(app.q["left"]))
    # an object pose nobody can reach is refused, the arms stay put
    q_before = {s: app.q[s].copy() for s in ("left", "right")}
    T = app.T_object.copy()
    T[:3, 3] += (0.0, -2.0, 0.0)
    app.request_object(T)
    app.step()
    assert "refused" in app.message
    for s in ("left", "right"):
        np.testing.assert_array_equal(app.q[s], q_before[s])
    assert not np.array_equal(q1, q0)


def test_collision_highlight_turns_red(app):
    app.sliders[("left", 1)].value = -10.0
    app.sliders[("left", 2)].value = 40.0  # elbow straight down: the bar goes through the floor
    app.step()
    assert app.last_clearance.distance < app.cell.safety_margin
    assert tuple(np.asarray(app.scene.closest.colors).ravel()[:3]) == (230, 30, 30)
    assert "BELOW THE MARGIN" in app.readout.content


def _wait_plan(app, timeout=60.0):
    t0 = time.time()
    while time.time() - t0 < timeout:
        app.step(1.0)  # 1 s per call: playback advances quickly
        if app.plan is not None and not app.playing and not app.busy:
            return app.plan
        time.sleep(0.01)
    raise AssertionError("plan did not arrive")


def test_routine_runs_in_worker_and_plays_to_the_end(app):
    app.routines.choice.value = app.routines.choice.options[1]  # routine 2
    app.routines.run.click() if hasattr(app.routines.run, "click") else app.run_routine(2)
    p = _wait_plan(app)
    assert p.reached and p.n_steps == 5
    assert app.routines.timeline.value == p.n_steps and "5/5" in app.routines.status.content
    M = _capsule_pose(app, "right", "forearm", p.q_right[-1])
    np.testing.assert_allclose(_node(app, "right/forearm").position, M[:3, 3], atol=1e-6)
    assert app.scene.path.visible and len(app.scene.path.points) == p.n_steps
    app.seek(2)
    app.step(0.0)
    np.testing.assert_allclose(app.T_object, p.T_world_object[2])


def test_waypoints_record_save_load_play(app, tmp_path):
    app.record_waypoint()
    T = app.T_object.copy()
    T[:3, 3] += (-0.1, -0.05, 0.1)  # was (-0.1, 0, 0.05): robot 2's wrist vs its own pedestal (issue 13)
    app.request_object(T)
    app.step()
    app.record_waypoint()
    f = tmp_path / "wp.json"
    app.save_waypoints(str(f))
    saved = f.read_text()
    assert len(json.loads(saved)["T_world_object"]) == 2
    app.clear_waypoints()
    app.save_waypoints(str(f))  # exists, no overwrite: refused, file intact
    assert "not saved" in app.message and f.read_text() == saved
    app.load_waypoints(str(f))
    assert len(app.waypoints) == 2
    np.testing.assert_allclose(app.waypoints[1], T)
    (tmp_path / "bad.json").write_text("{")
    app.load_waypoints(str(tmp_path / "bad.json"))
    assert "not loaded" in app.message and len(app.waypoints) == 2
    app.plan_waypoints()
    p = _wait_plan(app)
    assert p.reached
    np.testing.assert_allclose(p.T_world_object[-1], T, atol=1e-12)


def test_view_toggles(app):
    import dataclasses

    from dualpuma.model import Obstacle

    app.show_frames.value = False
    assert not app.scene.frames["world"].visible
    c = dataclasses.replace(Cell.default(), obstacles=(Obstacle("b", "box", [0.1, 0.1, 0.1], np.eye(4)),))
    a2 = ViewerApp(c, port=free_port())
    try:
        assert len(a2.scene.grown) == 1 and not a2.scene.grown[0][1].visible
        a2.show_grown.value = True
        assert a2.scene.grown[0][1].visible
        g = a2.scene.grown[0][0]
        np.testing.assert_allclose(g.box_size, np.array([0.1, 0.1, 0.1]) + 2 * g.grow)
    finally:
        a2.close()


def test_real_envelope_section_toggle(app):
    """The real envelope's x-z section: hidden at first, shown by its checkbox, and the drawn
    segments are the membership boundary: 10 mm to one side of a segment's middle is in the set
    and 10 mm to the other side is not, for over 90 % of them (the grid resolves 25 mm)."""
    from dualpuma.envelope import contains_real

    node, env = app.scene.real_envelope, app.scene.real_envelope_model
    assert node is not None and not node.visible and not app.show_real_env.disabled
    app.show_real_env.value = True
    assert node.visible
    np.testing.assert_array_equal(np.asarray(node.points), env.xz_segments.astype(np.float32))
    seg = env.xz_segments
    mid = seg.mean(axis=1)
    d = seg[:, 1] - seg[:, 0]
    normal = np.stack([-d[:, 2], np.zeros(len(d)), d[:, 0]], axis=1)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    a = contains_real(app.cell, mid + 0.01 * normal)
    b = contains_real(app.cell, mid - 0.01 * normal)
    assert np.mean(a != b) > 0.9  # one side in, the other out: the segments are the boundary
    assert np.allclose(seg[..., 1], env.y_slice_m)


def test_serve_command_prints_url_serves_and_stops_on_ctrl_c():
    import signal
    import subprocess
    import sys
    import urllib.request

    port = free_port()
    proc = subprocess.Popen([sys.executable, "-m", "dualpuma.cli", "serve", "--port", str(port), "--cell", "agv"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = ""
        t0 = time.time()
        while "dualpuma viewer: http://" not in line and time.time() - t0 < 60:
            line = proc.stdout.readline()
        assert f"http://127.0.0.1:{port}" in line
        with urllib.request.urlopen(f"http://127.0.0.1:{port}", timeout=10) as r:
            assert r.status == 200 and b"<html" in r.read(2000).lower()
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=20)
        assert proc.returncode == 0 and "stopped" in out and "Traceback" not in err
    finally:
        if proc.poll() is None:
            proc.kill()


def test_serve_rejects_a_bad_cell_file(tmp_path):
    import subprocess
    import sys

    bad = tmp_path / "bad.toml"
    bad.write_text("name = 3\n")
    r = subprocess.run([sys.executable, "-m", "dualpuma.cli", "serve", "--cell", str(bad), "--port", str(free_port())],
                       capture_output=True, text=True, timeout=60, check=False)
    assert r.returncode == 2 and "bad.toml" in r.stderr and "Traceback" not in r.stderr
