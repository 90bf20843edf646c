"""What the paper adds to a method's report.md: its Table 1 or Table 2 beside the measured.

Only on the paper's task: its targets and start pose, a straight line, pointing along it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ikbench.paper.baseline_claims import scheme_of
from ikbench.paper.comparison import table2_section
from ikbench.paper.values import PAPER_STEPS, table1_comparison
from ikbench.render.run_report import markdown_table

if TYPE_CHECKING:
    import pandas as pd

    from ikbench.core.targets import Targets
    from ikbench.runtime.record import RunRecord

#: The methods whose runs the paper's tables describe: Table 2's baseline as the paper's text
#: describes it (the sequential-ik family) and as the authors ran it (the ikpy family, their
#: library; ikpy-walk, their call). Each Table 2 section says which task the run solved (the
#: walk's touch-pose-only task, as the paper's baseline, or the track's: the paper's task).
TABLE1_METHOD = "ours"
TABLE2_METHODS = ("sequential-ik", "sequential-ik-walk", "ikpy", "ikpy-walk")


def paper_task(record: RunRecord, targets: Targets) -> bool:
    """True when a run solved the paper's own task (targets, start pose, line, pointing)."""
    return targets.is_paper and record.shape == "line" and record.direction is None


def run_section(method: str, table: pd.DataFrame, record: RunRecord, targets: Targets
                ) -> list[str]:
    """Table 1 beside ``ours``, Table 2 beside a baseline, on the paper's task; else none."""
    if not paper_task(record, targets) or table["line_distance_mean_mm"].isna().any():
        return []
    if method == TABLE1_METHOD:
        lines = ["## Beside the paper's Table 1", "",
                 "Columns named *paper* are copied from the paper. Its \"distance from the "
                 "line [mm]\" values are in centimetres (its unit label is off by a factor of "
                 "ten, see ikbench/paper/data/reference/README.md), so they are shown here "
                 "x 10, in mm.", ""]
        if record.steps != PAPER_STEPS:
            lines += [f"The paper used n = {PAPER_STEPS} segments; this run used "
                      f"n = {record.steps}.", ""]
        return lines + [markdown_table(table1_comparison(table),
                                       {"loss": 2, "duration [s]": 2}), ""]
    if method in TABLE2_METHODS:
        orientation = record.method_settings().get("orientation")
        return table2_section(table, record.steps, method=method,
                              scheme=scheme_of(method, record),
                              orientation=None if orientation is None else str(orientation))
    return []
