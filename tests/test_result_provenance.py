"""Every committed result names the clean commit that made it (issue 36): an ancestor of HEAD,
with no change since to the code that produced its numbers (the methods, the library
adapters, the planning schemes, the kinematics, and the studies: the judge, the restart loop,
the clock). A result made from a modified tree, or before its solver or study changed, fails
here: regenerate it (``ikbench reproduce --all``)."""

from __future__ import annotations

import csv
import json
import subprocess
from pathlib import Path

import pytest

from tests.conftest import REPO

RESULTS = REPO / "results"
#: The records a results folder holds (run.json of runs and studies, the benchmarks').
RECORDS = ("run.json", "benchmark.json", "throughput.json", "batch.json", "sweep.json",
           "dataset.json", "design.json", "analysis.json", "power.json", "methods.json",
           "learned.json", "bare_calls.json")
#: The code a result's numbers come from: a commit after it that touches these makes it stale
#: (a module added to baselines/ too: the registry finds it, and "every installed method"
#: changes).
SOLVER_CODE = ("ikbench/methods", "baselines", "ikbench/schemes", "ikbench/core/kinematics")
#: The studies (the judge, the restart loop, the clock): a change to a module that ran makes a
#: result stale; a module added since (a new study) did not run.
STUDY_CODE = ("ikbench/studies",)
#: The plan's runner (``reproduce --all``) starts each study's command in its own process and
#: records its wall time and load; it computes nothing a study writes, so a change to it does
#: not make a result stale.
RUNNER = "ikbench/studies/regeneration.py"


def _changed(commit: str) -> list[str]:
    """The solver and study files changed from ``commit`` to HEAD (see the constants)."""
    solvers = _git("diff", "--name-only", commit, "HEAD", "--", *SOLVER_CODE).stdout.split()
    studies = _git("diff", "--name-only", "--diff-filter=MDR", commit, "HEAD", "--",
                   *STUDY_CODE).stdout.split()
    return solvers + [path for path in studies if path != RUNNER]


def _git(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True, timeout=60)


pytestmark = pytest.mark.skipif(not (REPO / ".git").exists() or _git("rev-parse", "HEAD")
                                .returncode != 0, reason="needs the git checkout")


def _first_row(path: Path) -> dict[str, str]:
    with path.open(newline="") as stream:
        return next(csv.DictReader(stream), {})


def _records() -> list[Path]:
    """Every JSON record under results/, and the CSVs that carry their provenance per row."""
    jsons = [p for name in RECORDS for p in RESULTS.rglob(name)]
    csvs = [p for p in RESULTS.glob("*.csv") if "git_commit" in _first_row(p)]
    return sorted(jsons + csvs)


def _load(path: Path) -> dict:
    if path.suffix == ".csv":  # the first row's provenance columns
        row = _first_row(path)
        return {"git_commit": row["git_commit"], "git_clean": row.get("git_clean") == "True"}
    return json.loads(path.read_text())


def _commit(record: dict) -> tuple[str | None, bool | None]:
    record = record.get("provenance", record)
    commit = record.get("git_commit") or record.get("git_revision")
    return commit, record.get("git_clean", None if commit is None
                                          else not str(commit).endswith("-dirty"))


def test_every_results_folder_has_a_record():
    assert len(_records()) >= 20


@pytest.mark.parametrize("path", _records(), ids=lambda p: str(p.relative_to(RESULTS)))
def test_a_committed_result_names_a_clean_ancestor_with_its_solvers_unchanged(path):
    commit, clean = _commit(_load(path))
    assert commit, f"{path}: no git commit recorded"
    assert clean, f"{path}: made from a modified tree ({commit})"
    commit = str(commit).removesuffix("-dirty")
    assert _git("merge-base", "--is-ancestor", commit, "HEAD").returncode == 0, (
        f"{path}: {commit} is not an ancestor of HEAD")
    changed = _changed(commit)
    assert not changed, f"{path}: made at {commit[:12]}; changed since: {changed[:10]}"


def test_every_study_of_the_regeneration_record_is_clean_and_current():
    """results/regenerated.json (``ikbench reproduce --all``): each study from a clean tree, at
    an ancestor of HEAD with its solvers unchanged since."""
    record = json.loads((RESULTS / "regenerated.json").read_text())
    assert record
    for name, study in record.items():
        assert study["clean"], name
        assert _git("merge-base", "--is-ancestor", study["commit"], "HEAD").returncode == 0, name
        changed = _changed(study["commit"])
        assert not changed, (name, changed[:10])
