"""Make the hard-set fixture of bench_hard_set.py (36 problems: 12 per family; see
dualpuma.scenarios.hard). Run: PYTHONPATH=src python benchmarks/make_hard_set.py [out.json]"""

import sys
import time
from pathlib import Path

from dualpuma.scenarios.hard import hard_problems, problems_to_json

if __name__ == "__main__":
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent / "fixtures" / "hard_set.json"
    tic = time.perf_counter()
    problems = hard_problems(12, seed=0)
    out.write_text(problems_to_json(problems) + "\n")
    print(f"{len(problems)} problems -> {out} ({time.perf_counter() - tic:.0f} s)")
