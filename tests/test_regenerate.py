"""``ikbench reproduce --all`` (ikbench.studies.regeneration): the plan, resuming, a dirty tree."""

from __future__ import annotations

import json
import sys

import pytest

from ikbench.core.errors import InputError
from ikbench.studies import regeneration as regen


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
    assert ran == [] and any("made at aaaaaaaaaaaa: skipped" in line for line in lines)
    regen.regenerate(tmp_path, only=["sweep"], force=True, say=lines.append,
                     runner=lambda argv: ran.append(argv) or 0)
    assert len(ran) == 1


def test_a_study_made_at_an_unchanged_ancestor_is_skipped(tmp_path, clean, monkeypatch):
    """Resuming after the studies done so far were committed: a study recorded at another
    commit is skipped when nothing but RESUMABLE_CHANGES changed since, and runs otherwise."""
    ran = []
    regen.regenerate(tmp_path, only=["sweep", "batch"], say=lambda text: None,
                     runner=lambda argv: ran.append(argv) or 0)
    record = json.loads((tmp_path / regen.RECORD).read_text())
    record["sweep"]["commit"], record["batch"]["commit"] = "b" * 40, "c" * 40
    (tmp_path / regen.RECORD).write_text(json.dumps(record))
    monkeypatch.setattr(regen, "unchanged_since",
                        lambda commit, modules=None: commit == "b" * 40)
    ran.clear()
    lines: list[str] = []
    regen.regenerate(tmp_path, only=["sweep", "batch"], say=lines.append,
                     runner=lambda argv: ran.append(argv) or 0)
    assert len(ran) == 1 and ran[0][-1] == f"{tmp_path}/batch"
    assert any("sweep" in line and "made at bbbbbbbbbbbb: skipped" in line for line in lines)


def test_unchanged_since_knows_what_makes_a_study_stale():
    """HEAD stands; the parent of the last commit that changed a solver does not; nor does a
    commit git does not know."""
    import subprocess

    from ikbench.studies.regeneration import REPO, unchanged_since

    def git(*args):
        return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True,
                              timeout=30).stdout.strip()

    head = git("rev-parse", "HEAD")
    if not head:
        pytest.skip("needs the git checkout")
    assert unchanged_since(head)
    solver_change = git("log", "-1", "--format=%H", "--", "ikbench/methods")
    parent = git("rev-parse", f"{solver_change}~1")
    if parent:
        assert not unchanged_since(parent)
    assert not unchanged_since("f" * 40)


def test_a_study_that_recorded_what_it_ran_stands_until_one_of_those_changes():
    """Resume with ``modules``: a Python file the study did not run leaves it standing; one it
    ran, any file but Python (read, not imported: not in the record), or a method added to
    baselines/ when it ran the registry make it run again. Without the record: any change."""
    ran = ["ikbench/studies/ik.py", "ikbench/methods/ours_lm/pose_solver.py"]
    assert regen.stands([], ran) and regen.stands([])
    assert regen.stands(["ikbench/methods/ours_lm/compiled.py"], ran)  # not run
    assert not regen.stands(["ikbench/methods/ours_lm/compiled.py"])  # no record
    assert not regen.stands(["ikbench/studies/ik.py"], ran)
    assert not regen.stands(["urdf/nico_right_arm.urdf"], ran)
    assert not regen.stands(["constraints.txt"], ran)
    assert regen.stands(["baselines/new_ik.py"], ran, ["baselines/new_ik.py"])
    assert not regen.stands(["baselines/new_ik.py"], [*ran, regen.REGISTRY],
                            ["baselines/new_ik.py"])


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


def test_every_plan_entry_validates_and_its_command_parses(tmp_path):
    """Each entry is a valid spec, and each ikbench command of the plan is one the CLI takes
    (a typo in the plan is caught here, not an hour into a regeneration)."""
    from ikbench.cli import build_parser

    assert regen.plan() == list(regen.STUDIES)
    for study in regen.STUDIES:
        study.validate()
        if not study.script:
            argv = study.arguments(tmp_path)
            build_parser(argv).parse_args(argv)


@pytest.mark.parametrize("field, value, match", [
    ("name", "a,b", "one word"), ("argv", ("bench",), "writes nowhere under"),
    ("writes", ("../x",), "inside the results directory"), ("writes", (), "inside the results"),
    ("script", "benchmarks/nope.py", "not a file"), ("minutes", 0, "positive")])
def test_a_bad_plan_entry_is_refused_naming_the_value(field, value, match):
    from dataclasses import replace

    good = next(s for s in regen.STUDIES if s.name == "sweep")
    good.validate()
    with pytest.raises(InputError, match=match):
        replace(good, **{field: value}).validate()


def test_the_paper_entry_lists_what_reproduce_writes():
    from ikbench.paper.reproduce import WRITES

    paper = next(s for s in regen.STUDIES if s.name == "paper")
    assert sorted(paper.writes) == sorted(WRITES)


def test_the_spec_refuses_an_unknown_study_before_running(tmp_path):
    spec = regen.RegenerationSpec(tmp_path, only=("nope",))
    with pytest.raises(InputError, match="nope is not a study"):
        spec.validate()


@pytest.mark.parametrize("name, robot", [("recommend-ur5", "example-robot-data:ur5"),
                                         ("recommend-panda", "example-robot-data:panda")])
def test_the_recommend_studies_write_where_recommend_writes(name, robot, tmp_path):
    """A 6-DoF and a 7-DoF recommendation are in the plan (issue 58), and each entry's
    ``writes`` is the folder ``ikbench recommend`` writes for its robot."""
    from ikbench.cli import build_parser
    from ikbench.render.recommend_report import folder_of

    study = next(s for s in regen.STUDIES if s.name == name)
    argv = study.arguments(tmp_path)
    args = build_parser(argv).parse_args(argv)
    assert args.robot == robot and args.minutes <= 5

    class Named:  # folder_of reads the robot's name only
        name = robot

    assert [str(tmp_path / w) for w in study.writes] == [str(folder_of(tmp_path, Named()))]


def _timed_runner(events, lock, hold_s=0.2):
    """A runner that records when each study starts and ends (by its --output folder)."""
    import threading
    import time

    def runner(argv):
        name = argv[argv.index("--output") + 1]  # the folder names the study
        with lock:
            events.append(("start", name, time.monotonic(), threading.active_count()))
        time.sleep(hold_s)
        with lock:
            events.append(("end", name, time.monotonic(), 0))
        return 0
    return runner


def _concurrent(events):
    """The pairs of studies whose runs overlapped in time."""
    spans = {}
    for kind, name, t, _ in events:
        spans.setdefault(name, [0.0, 0.0])[0 if kind == "start" else 1] = t
    names = sorted(spans)
    return {(a, b) for i, a in enumerate(names) for b in names[i + 1:]
            if spans[a][0] < spans[b][1] and spans[b][0] < spans[a][1]}


def test_jobs_runs_studies_at_once_and_records_every_one(tmp_path, clean):
    import threading

    events, lock = [], threading.Lock()
    times = regen.regenerate(tmp_path, only=["sweep", "batch", "letters-sweep"], jobs=2,
                             say=lambda text: None, runner=_timed_runner(events, lock))
    assert sorted(times) == ["batch", "letters-sweep", "sweep"]
    assert _concurrent(events)  # two ran at once
    record = regen.read_record(tmp_path)
    assert sorted(record) == ["batch", "letters-sweep", "sweep"]
    assert {entry["jobs"] for entry in record.values()} == {2}
    # never more than two at once
    starts = sorted((t, 1) for kind, _, t, _ in events if kind == "start")
    ends = sorted((t, -1) for kind, _, t, _ in events if kind == "end")
    running, most = 0, 0
    for _, step in sorted(starts + ends, key=lambda e: (e[0], e[1])):
        running += step
        most = max(most, running)
    assert most == 2


def test_jobs_never_runs_two_studies_that_write_into_the_same_folder(tmp_path, clean,
                                                                   monkeypatch):
    import threading

    inner = regen.Study("inner", ("sweep", "--output", "{out}/x/y"), ("x/y",), 1.0)
    outer = regen.Study("outer", ("sweep", "--output", "{out}/x"), ("x",), 1.0)
    other = regen.Study("other", ("sweep", "--output", "{out}/z"), ("z",), 1.0)
    assert regen._overlaps(inner, outer) and regen._overlaps(outer, inner)
    assert not regen._overlaps(inner, other)
    monkeypatch.setattr(regen, "STUDIES", (inner, outer, other))
    events, lock = [], threading.Lock()
    regen.regenerate(tmp_path, only=["inner", "outer", "other"], jobs=3,
                     say=lambda text: None, runner=_timed_runner(events, lock, 0.1))
    together = {tuple(sorted(p.rsplit("/", 1)[-1] for p in pair))
                for pair in _concurrent(events)}
    assert ("x", "y") not in together and together  # other ran beside one of them


def test_jobs_below_one_is_refused(tmp_path):
    with pytest.raises(InputError, match="--jobs: 0"):
        regen.regenerate(tmp_path, only=["sweep"], jobs=0, say=lambda text: None,
                         runner=lambda argv: 0)


def test_a_failed_study_under_jobs_starts_no_new_one_and_is_not_recorded(tmp_path, clean):
    ran = []

    def runner(argv):
        ran.append(argv)
        return 3 if "sweep" in argv[-1] else 0
    with pytest.raises(InputError, match="study sweep failed .exit code 3."):
        regen.regenerate(tmp_path, only=["sweep", "batch", "letters", "letters-sweep"], jobs=2,
                         say=lambda text: None, runner=runner)
    assert "sweep" not in regen.read_record(tmp_path)
    assert len(ran) <= 3  # the one beside it may finish; nothing starts after the failure


def test_jobs_runs_a_study_marked_alone_with_nothing_beside_it(tmp_path, clean, monkeypatch):
    """A per-call timing table (``alone``) starts when nothing runs and nothing starts beside
    it, while the other studies still run two at once."""
    import threading

    studies = [regen.Study(name, ("sweep", "--output", f"{{out}}/{name}"), (name,), 1.0,
                           alone=name == "timed") for name in ("a", "timed", "b", "c")]
    monkeypatch.setattr(regen, "STUDIES", tuple(studies))
    events, lock = [], threading.Lock()
    times = regen.regenerate(tmp_path, only=["a", "timed", "b", "c"], jobs=2,
                             say=lambda text: None, runner=_timed_runner(events, lock, 0.1))
    assert sorted(times) == ["a", "b", "c", "timed"]
    together = {tuple(sorted(p.rsplit("/", 1)[-1] for p in pair))
                for pair in _concurrent(events)}
    assert together and not any("timed" in pair for pair in together), together


def test_the_per_call_tables_of_the_plan_run_alone():
    alone = {s.name for s in regen.STUDIES if s.alone}
    assert {"ik-ur5", "ik-panda", "zoo-ur10", "bare-calls"} <= alone
    assert "compare" not in alone


SLEEPER = [sys.executable, "-c", "import time; time.sleep(120)"]


def test_an_interrupted_runner_leaves_no_study_running():
    """Ctrl-C while a study runs (one lane: the main thread waits on it) interrupts the study
    too, instead of leaving it to write into the results after the runner has gone."""
    import signal
    import threading
    import time

    seen = []

    def interrupt():
        for _ in range(200):  # until the study has started
            with regen._CHILDREN_LOCK:
                seen.extend(regen._CHILDREN)
            if seen:
                break
            time.sleep(0.05)
        signal.pthread_kill(threading.main_thread().ident, signal.SIGINT)  # as Ctrl-C

    threading.Thread(target=interrupt, daemon=True).start()
    with pytest.raises(KeyboardInterrupt):
        regen._run(SLEEPER)
    assert seen and seen[0].poll() == -signal.SIGINT  # interrupted, not waited for
    assert not regen._CHILDREN


def test_the_other_lanes_studies_are_ended_with_the_runner():
    """Under --jobs the other lanes' threads end with the runner: their studies are ended by
    _stop_children, a study that ignores SIGINT killed after the grace time."""
    import subprocess

    stubborn = [sys.executable, "-c",
                "import signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); "
                "print('ready', flush=True); time.sleep(120)"]
    polite = subprocess.Popen(SLEEPER)
    deaf = subprocess.Popen(stubborn, stdout=subprocess.PIPE, text=True)
    assert deaf.stdout.readline().strip() == "ready"  # its SIGINT handler is in place
    with regen._CHILDREN_LOCK:
        regen._CHILDREN.update({polite, deaf})
    try:
        regen._stop_children(grace_s=1.0)
        assert polite.returncode is not None and deaf.returncode == -9
    finally:
        with regen._CHILDREN_LOCK:
            regen._CHILDREN.difference_update({polite, deaf})
        for p in (polite, deaf):
            if p.poll() is None:
                p.kill()
