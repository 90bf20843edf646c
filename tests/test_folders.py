"""Output folders come from one table (issue 45): every command's default ``--output``, the
folders studies write inside it, and the names a method run may not take."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from ikbench.core.errors import InputError
from ikbench.studies.folders import OWN, RESERVED_NAMES, RESULTS, RUNS, WITHIN, default_output
from ikbench.studies.run import check_name

PACKAGE = Path(__file__).resolve().parents[1] / "ikbench"


def _output_defaults(tree: ast.AST):
    """String constants that stand as a default: a parameter's, a ``default=`` keyword's, or
    a module constant named like ``DEFAULT_OUTPUT``."""
    for node in ast.walk(tree):
        if isinstance(node, ast.arguments):
            yield from node.defaults + [d for d in node.kw_defaults if d is not None]
        elif isinstance(node, ast.keyword) and node.arg == "default":
            yield node.value
        elif isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and "OUTPUT" in t.id for t in node.targets):
            yield node.value


def test_no_output_folder_is_spelled_outside_the_table():
    """No module but folders.py gives "runs" or "runs/..." as a default of its own."""
    found = []
    for path in PACKAGE.rglob("*.py"):
        if path.name == "folders.py":
            continue
        for node in _output_defaults(ast.parse(path.read_text())):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and (
                    node.value in (RUNS, RESULTS) or node.value.startswith(f"{RUNS}/")):
                found.append(f"{path.relative_to(PACKAGE)}:{node.lineno} {node.value!r}")
    assert not found, found


@pytest.mark.parametrize("name", RESERVED_NAMES)
def test_a_run_may_not_take_another_studys_folder(name):
    with pytest.raises(InputError, match=f"--name: '{name}' is the folder of another command"):
        check_name(name)


def test_reserved_names_cover_every_study_folder():
    assert set(WITHIN.values()) | set(OWN.values()) <= set(RESERVED_NAMES)
    assert default_output("letters") == "runs/letters" and default_output("compare") == "runs"


@pytest.mark.parametrize("command, study", [("compare", "compare"), ("ik", "ik"),
                                            ("cartesian", "cartesian"), ("letters", "letters"),
                                            ("sweep", "sweep"), ("batch", "batch"),
                                            ("dataset", "dataset"), ("run", "run")])
def test_help_shows_the_derived_default(command, study, capsys):
    from ikbench.cli import main
    with pytest.raises(SystemExit):
        main([command, "--help"])
    assert default_output(study) in capsys.readouterr().out
