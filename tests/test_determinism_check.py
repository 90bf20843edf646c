"""benchmarks/determinism_check.py: its comparison of one condition's answers with the
reference's, and its refusal of a condition list that does not start with the reference."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "determinism_check.py"
_spec = importlib.util.spec_from_file_location("determinism_check", SCRIPT)
check = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(check)


def rows(q: np.ndarray, success: list[bool], order: list[int]) -> pd.DataFrame:
    frame = pd.DataFrame(q, columns=[f"q{j}" for j in range(q.shape[1])])
    frame.insert(0, "target", range(len(q)))
    frame.insert(1, "success", success)
    return frame.iloc[order].reset_index(drop=True)  # rows in any order: matched by target


def test_answers_are_matched_by_target_and_compared_joint_by_joint():
    q = np.array([[0.1, 0.2], [0.3, 0.4], [0.5, 0.6]])
    moved = q.copy()
    moved[1, 1] += 1e-6
    moved[2, 0] += np.pi
    out = check.compare(rows(moved, [True, True, False], [2, 0, 1]),
                        rows(q, [True, False, False], [0, 1, 2]), atol=1e-9)
    assert out["same_answers"] == 1 and out["successes"] == 2
    assert out["success_differs"] == 1
    assert out["max_diff_deg"] == pytest.approx(180.0)
    assert check.compare(rows(q, [True] * 3, [1, 2, 0]), rows(q, [True] * 3, [0, 1, 2]),
                         atol=0.0)["same_answers"] == 3


@pytest.mark.parametrize("conditions", ["blas-haswell,reference", "reference,no-such"])
def test_conditions_start_with_the_reference_and_are_known(conditions, capsys):
    with pytest.raises(SystemExit) as stop:
        check.main(["--conditions", conditions])
    assert stop.value.code == 2
    assert "--conditions" in capsys.readouterr().err
