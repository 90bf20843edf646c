"""Every script in examples/ runs as a user runs it (a subprocess, from another folder), with
IKBENCH_EXAMPLES_QUICK=1 for small sizes, and prints what its docstring promises."""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys

import pytest

from tests.conftest import REPO

EXAMPLES = REPO / "examples"
#: script -> text its output must contain
EXPECTED = {
    "paper_in_ten_lines.py": ["trajectory  iterations", "mean line distance"],
    "own_arm_from_urdf.py": ["panda: 7 joints", "within limits: True"],
    "compare_libraries.py": ["ours-lm", "sequential-ik"],
    "pose_path.py": ["fetch_arm__hello", "valid by CppFlow's criteria: True"],
    "play_on_emulated_bus.py": ["50 of 50 segments sent", "0 limit violations"],
    "pointing_study.py": ["SIMULATED participants", "hit rate by cell and method",
                          "false-positive rate"],
}
#: script -> what it prints on stderr: its expected time, then progress (the long ones;
#: compare_libraries ran 260 s without a word)
PROGRESS = {"compare_libraries.py": ["about 20 s on 2 busy cores; progress below",
                                     "[compare] "]}


def test_every_example_is_tested_and_documented():
    scripts = sorted(p.name for p in EXAMPLES.glob("*.py"))
    assert scripts == sorted(EXPECTED)
    for name in scripts:
        doc = ast.get_docstring(ast.parse((EXAMPLES / name).read_text()))
        assert doc and f"python examples/{name}" in doc, name
        assert re.search(r"\(about \d+ (s|min)\b", doc), f"{name}: state the expected time"


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_example_runs(tmp_path, name):
    env = {**os.environ, "IKBENCH_EXAMPLES_QUICK": "1", "PYTHONPATH": str(REPO)}
    done = subprocess.run([sys.executable, str(EXAMPLES / name)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    for text in EXPECTED[name]:
        assert text in done.stdout, done.stdout
    for text in PROGRESS.get(name, []):
        assert text in done.stderr, done.stderr
    assert list(tmp_path.iterdir()) == []  # nothing written where it was run
