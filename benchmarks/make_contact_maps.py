"""Derive the contact maps shipped in src/dualpuma/model/data/contact_maps.npz (dualpuma.model.contact:
the UR arms' always-close link pairs on their meshes; about 4 minutes of coal queries on 2 cores).
Run: PYTHONPATH=src python benchmarks/make_contact_maps.py [out.npz] [robot ...]"""

import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from dualpuma.kinematics import Arm
from dualpuma.kinematics.urdf import read_arm
from dualpuma.model.contact import MAP_FILE, derive_contact_maps, map_file_entries, write_map_file


def derive(robot: str) -> dict:
    arm = Arm.load(robot)
    tic = time.perf_counter()
    derived = derive_contact_maps(arm, read_arm(arm.urdf_path, arm.hand_frame).geometry)
    for (a, b), (_, blocked, queries) in derived.items():
        print(f"{robot} {a} - {b}: {queries} coal queries, {blocked.mean():.4f} of the cells blocked", flush=True)
    print(f"{robot}: {time.perf_counter() - tic:.0f} s", flush=True)
    return map_file_entries(arm, derived)


if __name__ == "__main__":
    here = Path(__file__).resolve().parents[1] / "src" / "dualpuma" / "model" / "data" / MAP_FILE
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else here
    robots = sys.argv[2:] or ["ur3", "ur5", "ur10"]
    with ProcessPoolExecutor(2) as pool:
        entries = dict(zip(robots, pool.map(derive, robots)))
    write_map_file(out, entries)
    print(f"-> {out}")
