"""The leaderboard says which methods' deterministic answers hold on another machine."""

from __future__ import annotations

from ikbench.methods.registry import solver_status
from ikbench.render.ik_report import stability_note


def test_stability_note_groups_the_methods_by_their_measured_flag():
    methods = {"a": {"stable_across_machines": True}, "b": {"stable_across_machines": False},
               "c": {"stable_across_machines": None}, "d": {}}
    text = stability_note(methods)[0]
    assert "stable: a;" in text and "not stable: b;" in text and "not measured: c, d." in text


def test_the_flags_are_the_measured_ones():
    """mink's products move with OpenBLAS' kernels; sequential-ik makes no BLAS call
    (benchmarks/determinism_check.py, docs/ik.md)."""
    status = solver_status()
    flags = {name: s.cls.stable_across_machines for name, s in status.items()
             if s.cls is not None}
    assert flags.get("mink", False) is False and flags.get("sequential-ik", True) is True
    assert set(flags.values()) <= {True, False, None}
