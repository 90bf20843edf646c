"""One adapter per library (issue 45): the registry finds the adapters by scanning
``ikbench.methods`` and ``ikbench.baselines`` and the entry-point group, with no list of names;
a package that declares an ADAPTER in the entry-point group is found by every command."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from ikbench.methods import registry
from tests.conftest import REPO

#: A third-party package: one trajectory method (ours-lm under another name, with an option of
#: its own) and one single-pose solver (one damped least-squares descent, sequential-ik's).
PLUGIN = textwrap.dedent('''
    from dataclasses import dataclass

    from ikbench.baselines.sequential_ik import DLSSolver
    from ikbench.methods.options import option
    from ikbench.methods.ours_lm import OursLM, OursLMSettings
    from ikbench.methods.registry import Adapter


    @dataclass
    class DummySettings(OursLMSettings):
        dummy_gain: float = option(1.0, help="a dummy option", flag="dummy-gain")


    class DummyMethod(OursLM):
        name = "dummy-lm"
        description = "a dummy library's method (ours-lm under another name)"
        Settings = DummySettings


    class DummySolver(DLSSolver):
        name, library = "dummy-ik", "fake-plugin"
        rank = 5000


    ADAPTER = Adapter(library="fake-plugin", methods=(DummyMethod,), solvers=(DummySolver,))
''')


@pytest.fixture
def plugin_env(tmp_path: Path) -> dict[str, str]:
    """An installed distribution (a dist-info on PYTHONPATH) whose entry point names an
    adapter."""
    (tmp_path / "dummy_adapter.py").write_text(PLUGIN)
    info = tmp_path / "fake_plugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: fake-plugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[ikbench.methods]\ndummy = dummy_adapter:ADAPTER\n")
    return {**os.environ, "COLUMNS": "400",  # argparse wraps help at COLUMNS
            "PYTHONPATH": os.pathsep.join([str(tmp_path), str(REPO)])}


def _ikbench(env: dict[str, str], *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ikbench.cli", *args], capture_output=True,
                          text=True, env=env, cwd=env["PYTHONPATH"].split(os.pathsep)[0],
                          timeout=600)


def test_an_entry_point_adapter_is_found_by_every_command(plugin_env):
    listing = _ikbench(plugin_env, "methods")
    assert listing.returncode == 0, listing.stderr
    rows = {line.split()[0]: line for line in listing.stdout.splitlines() if line.strip()}
    assert "available" in rows["dummy-lm"] and "ours-lm" in rows

    ik_help = _ikbench(plugin_env, "ik", "--help").stdout
    assert "dummy-ik" in ik_help
    compare_help = _ikbench(plugin_env, "compare", "--help").stdout
    assert "dummy-lm" in compare_help
    assert "--dummy-gain" in _ikbench(plugin_env, "run", "--help-methods").stdout

    ik = _ikbench(plugin_env, "ik", "--robot", "panda", "--methods", "dummy-ik,sequential-ik",
                  "--count", "4", "--budget-ms", "inf", "--attempts", "2", "--output", "out",
                  "--quiet")
    assert ik.returncode == 0, ik.stderr
    board = (Path(plugin_env["PYTHONPATH"].split(os.pathsep)[0]) / "out" / "ik" / "panda" /
             "leaderboard.md").read_text()
    assert "dummy-ik" in board and "sequential-ik" in board

    compare = _ikbench(plugin_env, "compare", "--methods", "dummy-lm", "--only", "1",
                       "--output", "out", "--quiet")
    assert compare.returncode in (0, 1), compare.stderr  # 1: a row that misses the contract
    board = (Path(plugin_env["PYTHONPATH"].split(os.pathsep)[0]) / "out" / "compare" /
             "leaderboard.csv").read_text()
    assert "dummy-lm" in board


def test_every_built_in_module_of_baselines_exports_one_adapter():
    """A library is one module (or package) of baselines/: each exports ADAPTER, and the
    registry's methods and solvers are exactly the adapters' (no name is listed elsewhere)."""
    folder = REPO / "baselines"
    modules = sorted(p.stem for p in folder.glob("*.py") if not p.stem.startswith("_"))
    modules += sorted(p.parent.name for p in folder.glob("*/__init__.py"))
    adapters = {f.where.rpartition(".")[2]: f.adapter for f in registry._found()
                if f.where.startswith("ikbench.baselines.")}
    assert sorted(adapters) == sorted(modules)
    assert all(a is not None for a in adapters.values())
    methods = [m.name for a in registry.adapters() for m in a.methods]
    solvers = [s.name for a in registry.adapters() for s in a.solvers]
    assert list(registry.method_status()) == methods  # registry order = the adapters' ranks
    assert sorted(registry.solver_status()) == sorted(solvers)
    assert len(set(methods)) == len(methods) and len(set(solvers)) == len(solvers)


def test_a_method_class_without_its_abstract_hook_cannot_be_built():
    from ikbench.schemes.single_pose import PoseSolver

    class NoSolve(PoseSolver):
        name = "no-solve"

    with pytest.raises(TypeError, match="abstract method solve"):
        NoSolve(None)  # type: ignore[arg-type,abstract]


def test_listing_order_is_the_ranks_not_a_list():
    ranks = [a.rank for a in registry.adapters()]
    assert ranks == sorted(ranks)
    solver_ranks = [registry.solver_status()[n].cls.rank for n in registry.available_solvers()]
    assert solver_ranks == sorted(solver_ranks)


def test_every_library_of_the_libs_extra_has_an_adapter_and_the_docs_count_them():
    """The libraries the docs name and count are rendered from the registry and pyproject's
    [libs] (render/blocks.py ``libraries``): each adapter of baselines/ whose library is not
    ikbench's own dependency is in [libs], and README and docs/index.md carry the count."""
    import tomllib

    from ikbench.render.blocks import render_libraries

    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    libs = " ".join(project["optional-dependencies"]["libs"]).lower()
    own = {f.adapter.library for f in registry._found()
           if f.adapter is not None and f.where.startswith("ikbench.baselines.")}
    core = " ".join(project["dependencies"]).lower()
    missing = [name for name in own if name.lower() not in libs and name.lower() not in core]
    assert not missing, f"adapters whose library is not in [libs]: {missing}"
    count = render_libraries(REPO / "pyproject.toml", {"form": "count"}, REPO)
    for page in ("README.md", "docs/index.md"):
        text = (REPO / page).read_text()
        assert f"<!-- generated: libraries pyproject.toml form=count -->{count}<" in text
