"""Generated blocks (ikbench.render.blocks): README.md's and docs/'s measured figures are
rendered from committed results files, and each block equals a fresh render."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from ikbench.core.errors import InputError
from ikbench.render.blocks import blocks, check_files, documents, render_text
from tests.conftest import REPO


def test_every_generated_block_equals_a_fresh_render():
    stale = check_files(documents(REPO), REPO)
    assert not stale, "run `ikbench reproduce --docs`:\n" + "\n".join(stale)


def test_readme_has_its_leaderboard_as_a_block():
    kinds = [(b.renderer, b.source) for b in blocks(REPO / "README.md")]
    assert ("compare-table", "results/compare/leaderboard.csv") in kinds


@pytest.fixture
def results(tmp_path):
    folder = tmp_path / "results" / "study"
    folder.mkdir(parents=True)
    (folder / "table.csv").write_text("method,time_s,ok\nfast,0.00123,True\nslow,2.5,False\n")
    (folder / "run.json").write_text(json.dumps({
        "git_commit": "0123456789abcdef0123", "git_clean": True, "cpu": "Test CPU",
        "cpu_count": 2, "load_average": [1.5, 1.0, 0.5], "created_utc": "2026-11-25T10:00"}))
    return tmp_path


def test_a_table_block_renders_the_rows_and_the_provenance(results):
    text = ("before\n<!-- generated: table results/study/table.csv where=ok:True "
            "columns='method,time_s:time [s]' -->\nold\n<!-- /generated -->\nafter\n")
    out = render_text(text, results)
    assert "| method | time [s] |" in out and "| fast | 0.00123 |" in out
    assert "slow" not in out
    assert ("*Measured at commit 0123456789ab, clean tree on Test CPU (2 logical CPUs), load "
            "1.5, 1, 0.5, 2026-11-25; from `results/study/table.csv`.*") in out
    assert out.startswith("before\n") and out.endswith("after\n")
    assert render_text(out, results) == out           # rendering again changes nothing


def test_a_value_block_stands_inline(results):
    text = ("fast takes <!-- generated: value results/study/table.csv where=method:fast "
            "column=time_s scale=1000 unit=ms format=.2f --><!-- /generated --> per call")
    out = render_text(text, results)
    assert "-->1.23 ms<!--" in out


def test_a_retyped_figure_is_found_stale(results, tmp_path):
    page = tmp_path / "page.md"
    page.write_text("<!-- generated: value results/study/table.csv where=method:slow "
                    "column=time_s unit=s -->2.4 s<!-- /generated -->\n")
    assert len(check_files([page], tmp_path)) == 1
    page.write_text(render_text(page.read_text(), tmp_path))
    assert check_files([page], tmp_path) == []


@pytest.mark.parametrize("spec, message", [
    ("table", "needs 'RENDERER SOURCE'"),
    ("nonsense results/study/table.csv", "renderer 'nonsense' is unknown"),
    ("value results/study/table.csv column=time_s", "leaves 2 rows, not one"),
    ("value results/study/table.csv column=nope where=method:fast", "column='nope'"),
    ("table results/missing.csv", "does not exist"),
    ("table results/study/table.csv where=nope:1", "no column 'nope'"),
])
def test_a_bad_block_is_one_clear_error(results, spec, message):
    with pytest.raises(InputError, match=message):
        render_text(f"<!-- generated: {spec} --><!-- /generated -->", results)


def test_reproduce_docs_and_plan_through_the_cli():
    docs = subprocess.run([sys.executable, "-m", "ikbench.cli", "reproduce", "--docs"],
                          cwd=REPO, capture_output=True, text=True, timeout=120)
    assert docs.returncode == 0 and docs.stdout.startswith("rendered: nothing changed"), \
        docs.stdout + docs.stderr
    plan = subprocess.run([sys.executable, "-m", "ikbench.cli", "reproduce", "--plan"],
                          cwd=REPO, capture_output=True, text=True, timeout=120)
    assert plan.returncode == 0, plan.stderr
    assert "ikbench reproduce --output results" in plan.stderr
    assert "ikbench compare --methods" in plan.stderr
    bad = subprocess.run([sys.executable, "-m", "ikbench.cli", "reproduce", "--all", "--only",
                          "nope"], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "--only: nope is not a study" in bad.stderr
