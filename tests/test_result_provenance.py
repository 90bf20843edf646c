"""Every committed result names the clean commit that made it (issue 36): an ancestor of HEAD,
with no change since to the code that produced its numbers (the methods, the library
adapters, the planning schemes, the kinematics, and the studies: the judge, the restart loop,
the clock). Where ``regenerated.json`` records the files the study's processes ran
(``modules``), only a change to one of those counts; a record without them counts every
change to that code. A result made from a modified tree, or before code it ran changed,
fails here: regenerate it (``ikbench reproduce --all``)."""

from __future__ import annotations

import csv
import json
import subprocess
from pathlib import Path

import pytest

from ikbench.studies.regeneration import REGISTRY  # a study that ran it lists every method
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




def _changed(commit: str, modules: list[str] | None = None) -> list[str]:
    """The solver and study files changed from ``commit`` to HEAD (see the constants; a
    rename is the old file deleted). With ``modules``, the checkout's files the study's
    processes ran (``regenerated.json``, :mod:`ikbench.core.module_log`), only those of them
    that changed, and a file added to baselines/ when the study ran the registry; without,
    every one (a record made before the modules were recorded)."""
    solvers = _git("diff", "--name-only", "--no-renames", commit, "HEAD", "--",
                   *SOLVER_CODE).stdout.split()
    studies = _git("diff", "--name-only", "--no-renames", "--diff-filter=MD", commit, "HEAD",
                   "--", *STUDY_CODE).stdout.split()
    changed = solvers + [path for path in studies if path != RUNNER]
    if modules is None:
        return changed
    ran = set(modules)
    added = set(_git("diff", "--name-only", "--no-renames", "--diff-filter=A", commit, "HEAD",
                     "--", "baselines").stdout.split()) if REGISTRY in ran else set()
    return [path for path in changed if path in ran or path in added]


def _ran(path: Path, commit: str) -> list[str] | None:
    """The files the studies of ``regenerated.json`` that wrote ``path`` at ``commit`` ran
    (their union); None unless every such study recorded them, or when none did."""
    record = json.loads((RESULTS / "regenerated.json").read_text())
    where = path.relative_to(RESULTS).as_posix()
    studies = [s for s in record.values() if str(s.get("commit")) == commit
               and any(w in ("", ".") or where == w or where.startswith(w.rstrip("/") + "/")
                       for w in s.get("writes") or [""])]
    if not studies or any("modules" not in s for s in studies):
        return None
    return sorted({m for s in studies for m in s["modules"]})


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
    changed = _changed(commit, _ran(path, commit))
    assert not changed, f"{path}: made at {commit[:12]}; changed since: {changed[:10]}"


def test_every_study_of_the_regeneration_record_is_clean_and_current():
    """results/regenerated.json (``ikbench reproduce --all``): each study from a clean tree, at
    an ancestor of HEAD with its solvers unchanged since."""
    record = json.loads((RESULTS / "regenerated.json").read_text())
    assert record
    for name, study in record.items():
        assert study["clean"], name
        assert _git("merge-base", "--is-ancestor", study["commit"], "HEAD").returncode == 0, name
        changed = _changed(study["commit"], study.get("modules"))
        assert not changed, (name, changed[:10])


def _last(change: str, where: str) -> tuple[str, list[str]]:
    """The newest commit with a ``change`` (git's --diff-filter) under ``where``: its parent
    and the files it changed there."""
    commit = _git("log", "-n", "1", f"--diff-filter={change}", "--no-renames", "--format=%H",
                  "--", where).stdout.strip()
    if not commit or _git("rev-parse", "--verify", "-q", f"{commit}^").returncode != 0:
        pytest.skip(f"no commit with a parent changes {where}")
    files = _git("diff", "--name-only", "--no-renames", f"--diff-filter={change}", f"{commit}^",
                 commit, "--", where).stdout.split()
    return f"{commit}^", files


def test_a_study_that_recorded_what_it_ran_is_stale_only_when_that_changed():
    before, touched = _last("M", "ikbench/methods")
    assert touched and set(touched) <= set(_changed(before))  # no record: every change
    assert set(touched) <= set(_changed(before, touched))  # it ran them
    assert _changed(before, ["ikbench/core/rotations.py"]) == []  # it ran none of them


def test_a_method_added_to_baselines_stales_a_study_that_ran_the_registry():
    before, added = _last("A", "baselines")
    assert added and set(added) <= set(_changed(before, [REGISTRY]))
    assert not set(added) & set(_changed(before, ["ikbench/core/rotations.py"]))
