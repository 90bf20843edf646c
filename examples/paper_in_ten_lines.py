"""The paper in ten lines: ours-lm on the paper's seven targets, through the Python API.

Shows ``ikbench.run``: it builds the paper's seven line tasks on NICO's right arm (start pose
and touch poses of Lucny et al.), solves them with ``ours-lm`` (the paper's L0..L6 objective
by Levenberg-Marquardt), measures the written trajectories and returns the table as a pandas
DataFrame. ``output=None`` writes nothing; ``output="runs"`` writes the run folder
``runs/ours-lm/`` (trajectory CSVs, figures, report.md), as ``ikbench run`` does.

Run:  python examples/paper_in_ten_lines.py     (about 15 s on 2 busy cores, start-up included)
(IKBENCH_EXAMPLES_QUICK=1 solves trajectories 1 and 2 only.)
"""

import os

import ikbench

only = "1,2" if os.environ.get("IKBENCH_EXAMPLES_QUICK") else None
table = ikbench.run("ours-lm", only=only, output=None, progress=False)
columns = ["trajectory", "iterations", "duration_s", "line_distance_mean_mm",
           "pointing_deviation_mean_deg", "end_point_error_mm"]
print(table[columns].to_string(index=False, float_format=lambda v: f"{v:.3f}"))
print(f"mean line distance {table['line_distance_mean_mm'].mean():.2f} mm, mean pointing "
      f"deviation {table['pointing_deviation_mean_deg'].mean():.2f} deg")
