"""Every layer type-checks (mypy over ikbench/ and baselines/, configured in pyproject.toml),
the package says so (py.typed), ``Method`` is abstract, and the module paths of ikbench 0.1
are retired."""

from __future__ import annotations

import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

#: Module paths of ikbench 0.1, kept by shims until 0.3.0.
RETIRED = [f"ikbench.{m}" for m in (
    "errors", "io", "provenance", "robot", "kinematics", "task", "shapes", "letters", "targets",
    "losses", "metrics", "trajectory", "run", "report", "ablation", "sweep", "bench", "batch",
    "compare", "reproduce", "commands")]


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


def test_the_retired_module_paths_are_gone():
    """The 0.1 module paths (``ikbench.run``, ``ikbench.compare``, ...) were retired in 0.3.0
    (CHANGELOG): only ``__init__`` and ``__main__`` stand at the package root, and the public
    names are attributes of ``ikbench`` (``ikbench.run`` is the function)."""
    root = sorted(p.name for p in (REPO / "ikbench").glob("*.py"))
    assert root == ["__init__.py", "__main__.py"], root
    code = ("import importlib, sys, ikbench; missing = []\n"
            "for old in sys.argv[1:]:\n"
            "    try: importlib.import_module(old)\n"
            "    except ModuleNotFoundError: missing.append(old)\n"
            "assert missing == sys.argv[1:], set(sys.argv[1:]) - set(missing)\n"
            "assert callable(ikbench.run) and not hasattr(ikbench.run, '__path__')")
    proc = subprocess.run([sys.executable, "-c", code, *RETIRED], cwd=REPO,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
