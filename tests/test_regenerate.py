"""``ikbench reproduce --all`` (ikbench.paper.regenerate): the plan, resuming, a dirty tree."""

from __future__ import annotations

import json

import pytest

from ikbench.core.errors import InputError
from ikbench.paper import regenerate as regen


@pytest.fixture
def clean(monkeypatch):
    monkeypatch.setattr(regen, "git_state", lambda: ("a" * 40, True))
    monkeypatch.setattr(regen, "render_files", lambda paths, root: [])


def test_every_committed_results_folder_has_a_study():
    """Each folder and file of results/ (but the record itself) is written by a study."""
    written = {w.split("/")[0] for s in regen.STUDIES for w in s.writes}
    here = {p.name for p in (regen.REPO / "results").iterdir()} - {regen.RECORD}
    assert here <= written, sorted(here - written)


def test_the_plan_runs_each_study_once_and_resumes(tmp_path, clean):
    ran, lines = [], []
    times = regen.regenerate(tmp_path, only=["sweep", "batch"], say=lines.append,
                             runner=lambda argv: ran.append(argv) or 0)
    assert list(times) == ["sweep", "batch"] and len(ran) == 2
    assert ran[0][-3:] == ["c1=10,50,200,500", "--output", f"{tmp_path}/sweep"]
    assert lines[0].startswith("plan: 2 studies")
    record = json.loads((tmp_path / regen.RECORD).read_text())
    assert record["sweep"]["commit"] == "a" * 40 and record["sweep"]["clean"] is True
    assert record["sweep"]["command"] == ("ikbench sweep --weight c0=1,10,100,1000 --weight "
                                          f"c1=10,50,200,500 --output {tmp_path}/sweep")
    ran.clear()
    assert regen.regenerate(tmp_path, only=["sweep", "batch"], say=lines.append,
                            runner=lambda argv: ran.append(argv) or 0) == {}
    assert ran == [] and any("made at this commit: skipped" in line for line in lines)
    regen.regenerate(tmp_path, only=["sweep"], force=True, say=lines.append,
                     runner=lambda argv: ran.append(argv) or 0)
    assert len(ran) == 1


def test_a_failed_study_stops_the_run_and_is_not_recorded(tmp_path, clean):
    with pytest.raises(InputError, match="study sweep failed .exit code 3."):
        regen.regenerate(tmp_path, only=["sweep", "batch"], say=lambda text: None,
                         runner=lambda argv: 3)
    assert regen.read_record(tmp_path) == {}


def test_exit_1_finishes_a_study_whose_rows_may_fail(tmp_path, clean):
    """compare exits 1 when a method does not meet the contract (its rows say so): the study is
    made and recorded with its exit code; exit 1 of a study without failing rows stops the run."""
    assert regen.plan(["compare"])[0].rows_may_fail and not regen.plan(["sweep"])[0].rows_may_fail
    times = regen.regenerate(tmp_path, only=["compare"], say=lambda text: None,
                             runner=lambda argv: 1)
    assert list(times) == ["compare"]
    assert regen.read_record(tmp_path)["compare"]["exit_code"] == 1
    with pytest.raises(InputError, match="study sweep failed .exit code 1."):
        regen.regenerate(tmp_path, only=["sweep"], say=lambda text: None, runner=lambda argv: 1)
    with pytest.raises(InputError, match="study compare failed .exit code 2."):
        regen.regenerate(tmp_path, only=["compare"], force=True, say=lambda text: None,
                         runner=lambda argv: 2)


def test_a_dirty_tree_is_refused_unless_allowed(tmp_path, monkeypatch, clean):
    monkeypatch.setattr(regen, "git_state", lambda: ("b" * 40, False))
    with pytest.raises(InputError, match="--allow-dirty"):
        regen.regenerate(tmp_path, only=["sweep"], say=lambda text: None,
                         runner=lambda argv: 0)
    regen.regenerate(tmp_path, only=["sweep"], allow_dirty=True, say=lambda text: None,
                     runner=lambda argv: 0)
    assert regen.read_record(tmp_path)["sweep"]["clean"] is False


@pytest.mark.parametrize("name", ["compare", "compare-panda", "cartesian", "cartesian-methods"])
def test_the_path_studies_measure_each_methods_first_call(name, tmp_path):
    """The regenerated compare and cartesian leaderboards carry the first-call column: their
    commands pass --first-call, and the command's parser takes it."""
    from ikbench.cli import build_parser

    study = next(s for s in regen.STUDIES if s.name == name)
    argv = study.arguments(tmp_path)
    assert "--first-call" in argv
    assert build_parser(argv).parse_args(argv).first_call is True
