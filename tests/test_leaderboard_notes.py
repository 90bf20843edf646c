"""The compare leaderboard says what a row cannot fail, which rows are one result, and what
ran each method (issue 36: by-construction criteria, shared schemes, backends)."""

from __future__ import annotations

import numpy as np

from ikbench.methods.base import Solution
from ikbench.render.leaderboard import backend_notes, construction_notes
from ikbench.runtime.harness import Outcome
from ikbench.studies.compare import identical_methods


def _outcomes(*poses):
    return [Outcome(task=None, solution=Solution(np.asarray(p, float), 1, 0.0, None),  # type: ignore[arg-type]
                    wall_s=0.0) for p in poses]


def test_identical_methods_groups_equal_trajectories_only():
    a = np.zeros((3, 2))
    last = {"pink": _outcomes(a, a + 1), "mink": _outcomes(a + 1e-8, a + 1),
            "ours-lm": _outcomes(a, a + 1.1), "trac-ik": _outcomes(a, a + 1)}
    last["failed"] = [Outcome(task=None, solution=None, wall_s=0.0, failure="E")]  # type: ignore[arg-type]
    assert identical_methods(last) == [["pink", "mink", "trac-ik"]]
    assert identical_methods(last, tolerance=1e-9) == [["pink", "trac-ik"]]


def test_the_notes_name_the_scheme_the_twins_and_the_backends():
    record = {"schemes": {"ours-lm": "whole path", "pink": "track", "mink": "track, x",
                          "ikpy-walk": "walk, orientation position"},
              "identical": [["pink", "mink"]],
              "runtimes": {"ours-lm": {"backend": "numba", "threads": 2},
                           "pink": {"backend": "pin-pink"}}}
    text = "\n".join(construction_notes(record))
    assert "track scheme (pink, mink)" in text and "start and touch" in text
    assert "walk (ikpy-walk)" in text and "ours-lm" not in text.split("Backends")[0]
    assert "Same trajectories: pink and mink" in text
    assert "Backends: ours-lm numba (2 threads); pink pin-pink." in text
    assert construction_notes({}) == []


def test_the_header_says_when_ours_lm_did_not_run_compiled():
    """numba is the published configuration: any other backend of ours-lm is named above
    the table (issue 50), with numba's import error when that was the reason."""
    numpy = {"ours-lm": {"backend": "numpy", "threads": 1, "numba": "numba is not installed"}}
    text = "\n".join(construction_notes({"runtimes": numpy}))
    assert "**ours-lm ran on numpy** (numba cannot import: numba is not installed)" in text
    assert backend_notes({"ours-lm": {"backend": "numba", "threads": 2}}) == []
    assert backend_notes({"pink": {"backend": "pin-pink"}}) == []
    assert "ours-lm ran on torch (cpu, float64)" in "\n".join(
        backend_notes({"ours-lm": {"backend": "torch (cpu, float64)"}}))


def test_run_json_records_numba_and_llvmlite():
    from ikbench.core.provenance import provenance

    packages = provenance()["packages"]
    assert packages["numba"] and packages["llvmlite"]
