"""The record of the checkout's files a study's processes ran (``ikbench.core.module_log``):
what ``reproduce --all`` writes as a study's ``modules`` and the provenance test reads."""

from __future__ import annotations

import json
import os
import subprocess
import sys

from ikbench.core import module_log
from ikbench.studies import regeneration as regen
from tests.conftest import REPO

CHILD = ("import subprocess, sys\n"
         "import ikbench.core.errors\n"
         "subprocess.run([sys.executable, '-c', 'import ikbench.core.rotations'], check=True)\n")


def _python(code: str, log=None) -> None:
    env = {k: v for k, v in os.environ.items() if k != module_log.ENV}
    if log is not None:
        env[module_log.ENV] = str(log)
    subprocess.run([sys.executable, "-c", code], cwd=REPO, env=env, check=True, timeout=120)


def test_a_process_and_the_process_it_starts_record_the_checkout_files_they_ran(tmp_path):
    log = tmp_path / "modules.log"
    _python(CHILD, log)
    ran = module_log.read(log)
    assert "ikbench/__init__.py" in ran and "ikbench/core/errors.py" in ran  # the process
    assert "ikbench/core/rotations.py" in ran  # the process it started, by the environment
    assert "ikbench/methods/registry.py" not in ran  # what neither imported
    assert all(not path.startswith(("/", ".")) and path.endswith(".py") for path in ran)
    assert not any("site-packages" in path or path.startswith("numpy") for path in ran)
    assert ran == sorted(set(ran))
    assert module_log.read(tmp_path / "absent.log") == []  # no process of the study wrote


def test_the_runner_hands_its_study_a_log_and_records_what_it_ran(tmp_path, monkeypatch):
    """``reproduce --all``'s own runner: the study's ``modules`` in regenerated.json are the
    files its command's processes wrote to the log the runner named."""
    code = regen._run([sys.executable, "-c", "import ikbench.core.errors"], tmp_path / "m.log")
    assert code == 0 and "ikbench/core/errors.py" in module_log.read(tmp_path / "m.log")

    def fake(argv, log):
        log.write_text("ikbench/core/errors.py\nikbench/__init__.py\nikbench/core/errors.py\n")
        return 0

    monkeypatch.setattr(regen, "_run", fake)
    monkeypatch.setattr(regen, "render_files", lambda *args: [])
    regen.regenerate(tmp_path / "out", only=["sweep"], allow_dirty=True, say=lambda text: None)
    study = json.loads((tmp_path / "out" / regen.RECORD).read_text())["sweep"]
    assert study["modules"] == ["ikbench/__init__.py", "ikbench/core/errors.py"]


def test_a_runner_of_its_own_records_no_modules(tmp_path, monkeypatch):
    monkeypatch.setattr(regen, "render_files", lambda *args: [])
    regen.regenerate(tmp_path, only=["sweep"], allow_dirty=True, say=lambda text: None,
                     runner=lambda argv: 0)
    assert "modules" not in json.loads((tmp_path / regen.RECORD).read_text())["sweep"]
