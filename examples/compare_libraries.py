"""Compare libraries: ours-lm against other kinematics libraries on the same tasks.

Shows ``ikbench.studies.compare.compare``: every method gets the same line tasks under one task
contract (start and touch poses fixed, the line, pointing, the joints' speed limits, stated
tolerances); the study times every solve itself and judges every written trajectory by the
contract. ``ours-lm`` and ``sequential-ik`` (damped least squares on Pinocchio) are always
installed; ikpy, pink, TRAC-IK and mink join when installed (``pip install 'ikbench[libs]'``).
``result.leaderboard`` has one row per method and track, ``result.results`` one per task.

Run:  python examples/compare_libraries.py     (about 13 min on 2 busy cores, most of it
ikpy's per-point solves; progress on stderr)
(IKBENCH_EXAMPLES_QUICK=1: ours-lm and sequential-ik on trajectories 1 and 2 only: about 20 s.)
"""

import os
import sys

from ikbench.methods.registry import method_status
from ikbench.studies.compare import compare

quick = bool(os.environ.get("IKBENCH_EXAMPLES_QUICK"))
methods = ["ours-lm", "sequential-ik"]
if not quick:
    status = method_status()
    methods += [name for name in ("ikpy", "pink", "trac-ik", "mink") if status[name].available]

print(f"compare_libraries: {', '.join(methods)} on {'2' if quick else '7'} trajectories, one "
      f"warm-up and one timed round each: about {'20 s' if quick else '13 min'} on 2 busy "
      "cores; progress below", file=sys.stderr, flush=True)
result = compare(methods, only="1,2" if quick else None, repeat=1, warmup=1, output=None,
                 progress=True, sweep=False)
board = result.leaderboard
board = board[board["track"] == "paper"]  # start and touch poses both fixed (the paper's)
columns = ["method", "library", "scheme", "success", "line_distance_max_mm",
           "pointing_deviation_judged_mean_deg", "speed_limit_use", "time_median_s"]
print(board[columns].to_string(index=False, float_format=lambda v: f"{v:.4g}"))
