"""Record the seed's routines 1-8 to .viser files and assemble a static page that plays them back in
any browser, without Python (viser's built client; no network needed).

    python web_demo/record_routines.py                 # -> web_demo/site/
    python -m http.server -d web_demo/site 8000        # open http://127.0.0.1:8000/

Options: --out DIR, --routines 2 7 8, --fps 10 (frames per second of the recording, at most 60; the
motion runs as the live viewer plays it: timed under the joint limits, or step by step where it
cannot be timed, the page says which), --force
(replace files of a site recorded before: without it, an existing index.html, viewer.html or
recording is refused before anything is recorded).
"""

from __future__ import annotations

import argparse
import html
import socket
from pathlib import Path

import numpy as np
import viser

from dualpuma.checks import real
from dualpuma.errors import DualpumaError, FileError, ParameterError
from dualpuma.files import atomic_write, check_writable
from dualpuma.scenarios import ROUTINES, routine
from dualpuma.viewer.camera import set_initial_camera
from dualpuma.viewer.jobs import JobResult, routine_job
from dualpuma.viewer.scene import Scene


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def record(n: int, out: Path, fps: float = 10.0, overwrite: bool = False) -> tuple[Path, JobResult]:
    """Record routine ``n`` (scene + the motion as the live viewer plays it: timed under the joint
    limits where it can be, else step by step, :func:`dualpuma.viewer.jobs.routine_job`) to
    ``out / routine{n}.viser`` (an existing file only with ``overwrite``). Returns the file and the
    job (its plan, playback and the note on how it is played)."""
    job = routine_job(n, None, timed=True)
    world, pb = job.world, job.playback
    cell = world.cell
    server = viser.ViserServer(host="127.0.0.1", port=_free_port(), verbose=False)
    try:
        scene = Scene(server, world)
        scene.set_path(job.plan.T_world_object)
        rec = server.get_scene_serializer()
        for k, t in enumerate(np.arange(pb.t[0], pb.t_end + 0.5 / fps, 1.0 / fps)):
            s = pb.sample(float(t))
            c = world.clearance(s.q_left, s.q_right, s.T_object, s.t)
            hands = world.hand_poses(s.q_left, s.q_right)
            with server.atomic():
                scene.update(s.q_left, s.q_right, c, s.T_object, hands, cell.safety_margin, s.t)
            if k == 0:
                set_initial_camera(server, scene.points())
            rec.insert_sleep(1.0 / fps)
        rec.insert_sleep(1.0)
        return atomic_write(out / f"routine{n}.viser", rec.serialize(), overwrite=overwrite), job
    finally:
        server.stop()


def _checked(numbers, fps) -> tuple[list[int], float]:
    """The routines (each of 1-8, once, in the order given) and the frame rate (in (0, 60] per s)."""
    if isinstance(numbers, (str, bytes)) or not all(isinstance(n, int) and n in ROUTINES for n in numbers) or not numbers:
        raise ParameterError(f"routines: expected numbers among {sorted(ROUTINES)}, got {numbers!r}")
    return list(dict.fromkeys(numbers)), real(fps, "fps", lo=0.0, hi=60.0, lo_open=True, unit="1/s")


def build_site(out: Path, numbers: list[int], fps: float = 10.0, overwrite: bool = False) -> Path:
    """Record the routines and write ``index.html`` (the list) and ``viewer.html`` (viser's client).
    Files there from before are replaced only with ``overwrite``: without it any of them is refused
    (FileError) before anything is recorded or written; so are bad routines or ``fps``
    (ParameterError)."""
    numbers, fps = _checked(numbers, fps)
    rec_dir = out / "recordings"
    targets = [out / "index.html", out / "viewer.html"] + [rec_dir / f"routine{n}.viser" for n in numbers]
    there = [str(t) for t in targets if t.exists() or t.is_symlink()]
    if there and not overwrite:
        raise FileError(f"{', '.join(there)}: exist(s); pass --force (overwrite=True) to replace them")
    rec_dir.mkdir(parents=True, exist_ok=True)
    for t in targets:
        check_writable(t, overwrite=True)  # a directory or a device in the way: refused before the work
    client = Path(viser.__file__).parent / "client" / "build" / "index.html"
    if not client.exists():
        raise SystemExit(f"viser's built client is missing ({client}); reinstall viser")
    atomic_write(out / "viewer.html", client.read_bytes(), overwrite=overwrite)
    items = []
    for n in numbers:
        path, job = record(n, rec_dir, fps, overwrite)
        p, r = job.plan, routine(n)
        how = (f"timed: {p.trajectory.duration:.2f} s under the joint limits" if p.trajectory is not None
               else job.note or "played step by step")
        items.append(
            f'<li><a href="viewer.html?playbackPath=recordings/{path.name}">Routine {n}: {html.escape(r.title)}</a> '
            f"— <code>{p.status}</code>, {p.n_steps} steps ({html.escape(how)}). {html.escape(r.description)}</li>"
        )
    page = ("<!doctype html><meta charset='utf-8'><title>dualpuma: the seed's routines</title>"
            "<h1>dualpuma — two PUMA 560s carrying a bar: the seed's routines 1–8</h1>"
            "<p>Recorded with <code>web_demo/record_routines.py</code>; each link plays back in viser's client.</p>"
            f"<ul>{''.join(items)}</ul>")
    atomic_write(out / "index.html", page.encode("utf-8"), overwrite=overwrite)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=str(Path(__file__).parent / "site"))
    ap.add_argument("--routines", nargs="*", type=int, default=sorted(ROUTINES))
    ap.add_argument("--fps", type=float, default=10.0)
    ap.add_argument("--force", action="store_true", help="replace the files of a site recorded before")
    a = ap.parse_args()
    try:
        out = build_site(Path(a.out), a.routines, a.fps, a.force)
    except DualpumaError as exc:  # bad routines or fps, files in the way: said before anything is written
        ap.exit(2, f"record_routines.py: error: {exc}\n")
    print(f"wrote {out}/index.html; serve it with: python -m http.server -d {out} 8000")


if __name__ == "__main__":
    main()
