"""``ikbench reproduce``: the whole pipeline end to end on the quick configuration, and clear
errors when a part it needs is missing."""

from __future__ import annotations

import sys

import pandas as pd

import ikbench.reproduce as reproduce_module
from ikbench.cli import main
from ikbench.errors import InputError


def test_quick_pipeline_end_to_end(tmp_path, capsys):
    out = tmp_path / "results"
    assert main(["reproduce", "--quick", "--output", str(out)]) == 0
    captured = capsys.readouterr()
    assert "stage 5/5" in captured.err and "total time" in captured.err
    assert captured.out.splitlines()[-1].startswith("total")
    for name in ["ours/table.csv", "sequential-ik/table.csv", "ablation/table.csv",
                 "ablation/report.md", "ablation/metrics.png", "README.md"]:
        assert (out / name).stat().st_size > 0, name
    ablation = pd.read_csv(out / "ablation/table.csv")
    assert list(ablation["variant"]) == ["full", "no-L0", "no-L1", "no-L2", "no-L3", "no-L4",
                                         "no-L5", "no-L6", "no-L2-L3-L4-L5"]
    readme = (out / "README.md").read_text()
    for heading in ["## Table 1", "## Table 2", "## Comparison of the two",
                    "## Ablation of the loss terms", "## Deviations from the paper",
                    "## Versions and machine"]:
        assert heading in readme
    assert "quick pipeline check" in readme
    assert "paper line distance [mm]" in readme and "paper start point variation [mm]" in readme
    assert readme.count("**holds**") + readme.count("**does not hold**") == 6
    # every figure and report the page links to exists
    for link in [part.split(")")[0] for part in readme.split("](")[1:]]:
        assert (out / link).exists(), link


def test_missing_baseline_is_a_clear_error_before_any_work(tmp_path, monkeypatch, capsys):
    real = reproduce_module.get_method

    def no_baseline(name):
        if name == "sequential-ik":
            raise InputError(f"--method: unknown method {name!r}; available: ours")
        return real(name)

    monkeypatch.setattr(reproduce_module, "get_method", no_baseline)
    assert main(["reproduce", "--quick", "--output", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ikbench: error: Table 2 needs the method 'sequential-ik' "
                          "(baselines/sequential_ik.py)")
    assert not (tmp_path / "r").exists()


def test_missing_comparison_is_a_clear_error(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ikbench.compare", None)
    assert main(["reproduce", "--quick", "--output", str(tmp_path / "r")]) == 2
    assert "the comparison report needs ikbench.compare.write_comparison_report" in (
        capsys.readouterr().err)
    assert not (tmp_path / "r").exists()
