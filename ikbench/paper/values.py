"""The paper's printed values (Table 1, Table 2) and the helpers that set them beside ours.

Values are copied from the paper into ``data/paper_values.json``; they appear in reports only
in columns labelled *paper*, beside the measured ones.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Mapping
from importlib import resources
from typing import Any

import pandas as pd

#: The paper's number of segments n (51 poses per trajectory).
PAPER_STEPS = 50


@functools.lru_cache(maxsize=1)
def paper_values() -> dict:
    """The paper's Table 1 and Table 2 (see ikbench/paper/data/paper_values.json)."""
    text = resources.files("ikbench.paper").joinpath("data/paper_values.json").read_text()
    return json.loads(text)


def accuracy_beside_paper(row: Mapping[str, Any], paper_row: dict[str, Any] | None,
                          scale: float) -> dict[str, Any]:
    """Measured line distance and pointing (mean ± std) beside the paper's printed values.

    Args:
        row: measured figures (``line_distance_mean_mm``, ``..._std_mm``,
            ``pointing_deviation_mean_deg``, ``..._std_deg``).
        paper_row: the paper's row (``*_printed`` distances), or None off the paper's targets.
        scale: factor turning the paper's printed distances into mm (its cm slip).
    """
    p = paper_row
    return {
        "line distance [mm]": f"{row['line_distance_mean_mm']:.2f} ± "
                              f"{row['line_distance_std_mm']:.2f}",
        "paper line distance [mm]": p and
        f"{p['line_distance_mean_printed'] * scale:.1f} ± "
        f"{p['line_distance_std_printed'] * scale:.1f}",
        "pointing deviation [deg]": f"{row['pointing_deviation_mean_deg']:.2f} ± "
                                    f"{row['pointing_deviation_std_deg']:.2f}",
        "paper pointing deviation [deg]": p and
        f"{p['pointing_deviation_mean_deg']} ± {p['pointing_deviation_std_deg']}",
    }


def table1_comparison(table: pd.DataFrame) -> pd.DataFrame:
    """Measured Table 1 figures beside the paper's (distance converted to mm)."""
    paper = paper_values()["table1"]
    scale = paper_values()["table1_cm_to_mm"]
    rows = []
    for _, row in table.iterrows():
        p = paper.get(str(row["trajectory"]))
        rows.append({
            "trajectory": str(row["trajectory"]),
            "iterations": int(row["iterations"]),
            "paper iterations": p and p["iterations"],
            "loss": row["loss"],
            "paper loss": p and p["loss"],
            **accuracy_beside_paper(row, p, scale),
            "duration [s]": row["duration_s"],
            "paper duration [s]": p and p["duration_s"],
        })
    return pd.DataFrame(rows)
