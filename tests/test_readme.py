"""The README's Python example runs, and runs again in the same directory (its files are written
with overwrite=True; a second run used to fail on save_npz)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import dualpuma

README = Path(__file__).resolve().parents[1] / "README.md"


def test_the_readme_example_runs_twice_in_a_row(tmp_path):
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), flags=re.DOTALL)
    assert len(blocks) == 2  # the API tour, and any two arms
    src = str(Path(dualpuma.__file__).parents[1])  # the dualpuma under test, whatever the cwd
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([src, os.environ.get("PYTHONPATH", "")])}
    for k, block in enumerate(blocks):
        script = tmp_path / f"readme_example_{k}.py"
        script.write_text(block, encoding="utf-8")
        for run in (1, 2):
            r = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True,
                               timeout=600, check=False)
            assert r.returncode == 0, f"block {k}, run {run}:\n{r.stderr[-3000:]}"
            assert "Traceback" not in r.stderr
            if "# reached" in block:  # the printed status the README promises
                assert r.stdout.split() and r.stdout.split()[-1] == "reached", r.stdout
            if k == 0:  # the tour's comments: the closest pair at home, the plan's status and steps
                lines = r.stdout.splitlines()
                assert lines[0].endswith("('right/pedestal', 'right/wrist')") and "('right/pedestal', 'right/wrist')" in block
                assert lines[1].startswith("reached 6 ") and "# -> reached 6 ..." in block, lines[1][:200]
    assert (tmp_path / "plan.npz").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan.npz", "readme_example_0.py", "readme_example_1.py"]
