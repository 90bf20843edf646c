"""Every ``ikbench ...`` command line quoted in a fenced code block of docs/index.md and
docs/getting-started.md is run here (issue 64: index.md's ``ikbench export
runs/compare/ours-exact --timing topp`` failed), or listed in :data:`SKIPPED` with why.

index.md's block is one user's session, run in order in an empty folder that holds
``my_arm.urdf`` (the shipped Panda's URDF under that name): ``robot init`` as written;
``compare`` as written plus ``--only 1 --steps 10`` (:data:`SHRUNK`: the same five methods on
one target, seconds instead of minutes); ``view`` as written (plus ``--no-browser``) with the
server's loop replaced by a stub (it serves until Ctrl-C), so the folders, robot and timing
are all loaded; ``export`` exactly as written. getting-started's main job (``ikbench run
--method ours``: the paper's seven trajectories, about 50 s) runs under ``-m slow``.
"""

from __future__ import annotations

import json
import re
import shlex
import shutil
from pathlib import Path

import pytest

from ikbench.cli import main
from tests.conftest import REPO

PAGES = ("index.md", "getting-started.md")
#: Commands not run, and why.
SKIPPED = {
    "ikbench recommend --robot my_arm/my_arm.toml":
        "a study that spends its --minutes budget (2 min by default) by design",
}
#: Options appended to a documented command to keep it quick (the same command on less work).
SHRUNK = {
    "ikbench compare --robot my_arm/my_arm.toml --methods ours-exact,sequential-ik,rtb-lm,"
    "placo,pink": ["--only", "1", "--steps", "10"],
}
#: getting-started's main job (slow: the paper's seven trajectories).
MAIN_JOB = "ikbench run --method ours"


def documented(page: str) -> list[str]:
    """The ``ikbench ...`` command lines of ``page``'s fenced code blocks, comments dropped
    (a command after ``&&``, as ``.venv/bin/ikbench``, counted too)."""
    text = (REPO / "docs" / page).read_text(encoding="utf-8")
    blocks = re.findall(r"^```[^\n]*\n(.*?)^```", text, flags=re.S | re.M)
    out = []
    for block in blocks:
        for line in block.splitlines():
            for part in line.split("&&"):
                part = part.split("  #")[0].strip()
                part = re.sub(r"^(\S*/)?\.venv/bin/", "", part)
                if part.startswith("ikbench "):
                    out.append(part)
    return out


def test_every_documented_command_is_run_here_or_skipped_with_a_reason():
    """A command added to the pages must be classified here (run, shrunk or skipped)."""
    known = {*SKIPPED, *SHRUNK, MAIN_JOB, *INDEX_AS_IS}
    commands = [c for page in PAGES for c in documented(page)]
    assert commands, "no command found"
    assert set(commands) <= known, sorted(set(commands) - known)


#: index.md's commands run exactly as written.
INDEX_AS_IS = ("ikbench robot init my_arm.urdf --output my_arm/",
               "ikbench view runs/compare",
               "ikbench export runs/compare/ours-exact --timing topp")


def test_index_pages_session_runs_in_order(tmp_path, monkeypatch, capsys):
    """docs/index.md's "I have my robot's URDF" session, in order (see the module doc)."""
    pytest.importorskip("viser")
    import ikbench.viewer.server as server

    served = []
    monkeypatch.setattr(server, "run_forever", lambda robot, runs, **kw: served.append(runs))
    shutil.copy(REPO / "urdf" / "panda.urdf", tmp_path / "my_arm.urdf")
    monkeypatch.chdir(tmp_path)
    for command in documented("index.md"):
        if command in SKIPPED:
            continue
        argv = shlex.split(command)[1:] + SHRUNK.get(command, [])
        if argv[0] == "view":
            argv.append("--no-browser")
        code = main(argv)
        err = capsys.readouterr().err
        assert code in ((0, 1) if argv[0] == "compare" else (0,)), (command, err[-2000:])
    assert (tmp_path / "my_arm" / "my_arm.toml").is_file()
    assert served and served[0], "view loaded no run"
    exported = sorted((tmp_path / "runs" / "compare" / "ours-exact" / "export").iterdir())
    assert [p.name for p in exported] == ["trajectory_1.json"]
    assert json.loads(exported[0].read_text())["points"]


@pytest.mark.slow
def test_getting_starteds_main_job_runs(tmp_path, monkeypatch):
    assert MAIN_JOB in documented("getting-started.md")
    monkeypatch.chdir(tmp_path)
    assert main(shlex.split(MAIN_JOB)[1:]) == 0
    assert (Path(tmp_path) / "runs" / "ours" / "run.json").is_file()
