"""Every layer type-checks (mypy over ikbench/ and baselines/, configured in pyproject.toml),
the package says so (py.typed), ``Method`` is abstract, and the module paths of ikbench 0.1
are plain modules (no import hook)."""

from __future__ import annotations

import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

#: Module path of ikbench 0.1 -> the module it is now.
MOVED = {
    **{f"ikbench.{m}": f"ikbench.core.{m}" for m in (
        "errors", "io", "provenance", "robot", "kinematics", "task", "shapes", "letters",
        "targets", "losses", "metrics", "trajectory")},
    **{f"ikbench.{m}": f"ikbench.studies.{m}" for m in (
        "run", "report", "ablation", "sweep", "bench", "batch")},
    "ikbench.compare": "ikbench.paper.comparison", "ikbench.reproduce": "ikbench.paper.reproduce",
    "ikbench.commands": "ikbench.cli.commands",
}


@pytest.mark.skipif(shutil.which("mypy") is None and not (Path(sys.executable).parent / "mypy")
                    .exists(), reason="mypy is not installed (pip install -e '.[test]')")
def test_every_layer_type_checks(tmp_path):
    """mypy with pyproject.toml's settings over the installed layout: ``ikbench/`` with the
    top-level ``baselines/`` as ``ikbench/baselines/`` (pyproject's package-dir), made of
    symlinks to the checkout. In the checkout itself mypy finds no ``ikbench/baselines/`` (it
    follows no setuptools editable finder), so every ``ikbench.baselines`` import would be
    ``Any`` there and the modules of baselines/ unchecked against each other."""
    package = tmp_path / "ikbench"
    package.mkdir()
    for entry in (REPO / "ikbench").iterdir():
        if entry.name != "__pycache__":
            (package / entry.name).symlink_to(entry)
    (package / "baselines").symlink_to(REPO / "baselines")
    proc = subprocess.run([sys.executable, "-m", "mypy", "--config-file",
                           str(REPO / "pyproject.toml"), "--cache-dir", str(tmp_path / "cache"),
                           "ikbench"], cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "Success: no issues found" in proc.stdout


def test_mypy_covers_every_layer():
    config = tomllib.loads((REPO / "pyproject.toml").read_text())
    assert config["tool"]["mypy"]["files"] == ["ikbench", "baselines"]
    assert not config["tool"]["mypy"].get("ignore_errors")
    assert "py.typed" in config["tool"]["setuptools"]["package-data"]["ikbench"]
    assert (REPO / "ikbench" / "py.typed").is_file()


def test_method_is_abstract():
    from ikbench.methods.base import Method
    from ikbench.methods.registry import available_methods

    assert Method.__abstractmethods__ == {"solve"}
    with pytest.raises(TypeError, match="abstract"):
        Method()  # type: ignore[abstract]
    for name, cls in available_methods().items():
        assert not cls.__abstractmethods__, name
        cls()


def test_old_module_paths_give_the_moved_module():
    # in a fresh interpreter: ``import ikbench.run`` binds ``ikbench.run`` to the module (as
    # the import hook of 0.1 did), which would shadow the function ``ikbench.run`` here
    code = ("import importlib, sys; moved = dict(a.split('=') for a in sys.argv[1:]); "
            "bad = [o for o, n in moved.items() "
            "if importlib.import_module(o) is not importlib.import_module(n)]; "
            "assert not bad, bad")
    proc = subprocess.run([sys.executable, "-c", code, *(f"{o}={n}" for o, n in MOVED.items())],
                          cwd=REPO, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_no_import_hook():
    code = ("import sys; before = list(sys.meta_path); import ikbench, ikbench.compare; "
            "from ikbench.compare import compare; import ikbench.paper.comparison as c; "
            "assert ikbench.compare is c and compare is c.compare; "
            "assert sys.meta_path == before, sys.meta_path")
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True,
                          text=True)
    assert proc.returncode == 0, proc.stderr
