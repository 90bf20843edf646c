"""The ``learned`` study (ikbench/studies/learned.py) on one robot at a tiny size, and its
plan entry."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("torch")
pytest.importorskip("pyarrow")
pytest.importorskip("roboticstoolbox")

import pandas as pd  # noqa: E402

from ikbench.studies import learned as study  # noqa: E402
from ikbench.studies import regeneration as regen  # noqa: E402


def test_the_study_writes_its_table_with_the_model_columns_where_they_belong(tmp_path, capsys):
    code = study.main(["--output", str(tmp_path), "--robots", "nico_right_arm",
                       "--trajectories", "40", "--epochs", "2", "--count", "5", "--quiet"])
    assert code == 0
    table = pd.read_csv(tmp_path / "learned.csv")
    assert list(table.columns) == study.COLUMNS
    assert len(table) == len(study.METHODS) * len(study.INITS) * len(study.ATTEMPTS)
    assert set(table["init"]) == set(study.INITS)
    assert set(table["method"]) == set(study.METHODS)
    assert set(table["attempts_rule"].astype(str)) == {str(a) for a in study.ATTEMPTS}
    learned, others = table[table["init"] == "learned"], table[table["init"] != "learned"]
    model_columns = ["model_error_mm", "model_error_deg", "model_query_ms",
                     "training_samples", "training_cpu_min"]
    assert learned[model_columns].notna().all().all()
    assert others[model_columns].isna().all().all()
    assert table["success_pct"].between(0, 100).all()
    record = json.loads((tmp_path / "learned.json").read_text())
    model = record["models"]["nico_right_arm"]
    assert (learned["training_samples"] == model["training_samples"]).all()
    assert record["settings"]["dataset_seed"] not in (1, 4)
    assert record["settings"]["train_seed"] not in (1, 4)
    # the record names no machine's folder; the datasets and models are not kept
    assert model["model_file"] == "nico_right_arm/pose.pt" and len(model["model_sha256"]) == 64
    assert model["dataset"]["path"] == "nico_right_arm/dataset"
    assert str(tmp_path) not in (tmp_path / "learned.json").read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["learned.csv", "learned.json"]


def test_keep_names_the_folder_the_models_stay_in(tmp_path):
    keep = tmp_path / "kept"
    code = study.main(["--output", str(tmp_path / "out"), "--robots", "nico_right_arm",
                       "--trajectories", "20", "--epochs", "1", "--count", "2", "--quiet",
                       "--keep", str(keep)])
    assert code == 0 and (keep / "nico_right_arm" / "pose.pt").is_file()


def test_the_plan_has_the_learned_entry_and_its_script():
    entry = next(s for s in regen.STUDIES if s.name == "learned")
    entry.validate()
    assert entry.writes == ("learned",)
    assert (regen.REPO / entry.script).is_file()
    assert entry.arguments(regen.REPO / "results")[-1].endswith("results/learned")
