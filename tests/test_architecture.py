"""The package's shape: layers, no method named in generic code, a registry that a missing
library cannot break, and a wheel that lists every package."""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
#: Layer of each top-level part; a module may import only its own layer or lower ones.
LAYERS = {"core": 0, "methods": 1, "schemes": 1, "baselines": 1, "runtime": 2, "render": 2,
          "studies": 3, "hw": 3, "paper": 4, "viewer": 4, "experiment": 4,
          # learned trains on the dataset study's shards and serves the ik study's learned
          # starts (ik --init learned) and the learned study: a sibling of studies/
          "learned": 3,
          "cli": 5}


def _modules():
    for path in sorted([*(REPO / "ikbench").rglob("*.py"), *(REPO / "baselines").rglob("*.py")]):
        rel = path.relative_to(REPO).with_suffix("")
        parts = rel.parts
        if parts[0] == "baselines":  # the folder of the package ikbench.baselines
            yield path, "baselines"
        elif len(parts) > 2 or (len(parts) == 2 and parts[1] != "__init__"
                                and parts[1] != "__main__"):
            yield path, parts[1]


def _imported(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
            names.update(f"{node.module}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
    return names


def _part(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] == "ikbench" and len(parts) > 1 and parts[1] in LAYERS:
        return parts[1]
    return None


def test_every_module_imports_only_its_layer_or_lower():
    bad = []
    for path, part in _modules():
        if part not in LAYERS:
            continue
        for name in _imported(path):
            other = _part(name)
            if other is not None and LAYERS[other] > LAYERS[part]:
                bad.append(f"{path.relative_to(REPO)} ({part}) imports {name} ({other})")
    assert not bad, "\n".join(bad)


def test_nothing_names_the_retired_top_level_baselines():
    """baselines/ installs as ``ikbench.baselines`` (issue 27): no import, and no "module:Class"
    or importlib string, names the top-level ``baselines`` any more."""
    bad = []
    folders = ("ikbench", "baselines", "tests", "examples", "benchmarks")
    for path in sorted(p for folder in folders for p in (REPO / folder).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level:
                names = [node.module or ""]
            elif isinstance(node, ast.Constant) and isinstance(node.value, str):
                target = re.fullmatch(r"(baselines(?:\.\w+)+)(?::\w+)?", node.value)
                names = [target.group(1)] if target else []
            else:
                continue
            if any(name == "baselines" or name.startswith("baselines.") for name in names):
                bad.append(f"{path.relative_to(REPO)}:{node.lineno}: {names}")
    assert not bad, "write ikbench.baselines:\n" + "\n".join(bad)


#: The parts that work for every method: none of them names one.
GENERIC = ("core", "runtime", "render", "studies", "cli")


def _method_names() -> set[str]:
    """Every registered method's name (the registry's built-ins) and every single-pose
    solver's (``ikbench ik``)."""
    from ikbench.methods.registry import method_status, solver_status

    return set(method_status()) | set(solver_status())


def test_generic_code_names_no_method():
    """core, runtime, render, studies and cli work for every method: no string literal in them
    is a method's name or a comma-separated list of names. A default that names a method is a
    constant of ikbench/core/defaults.py (``DEFAULT_METHOD``, ``REFERENCE_METHOD``, ...), the
    one exception; code about one method takes the name from its class (``OursLM.name``)."""
    names = _method_names()
    assert {"ours", "ours-lm", "sequential-ik", "trac-ik", "rtb-nr"} <= names
    bad = []
    for path, part in _modules():
        if part not in GENERIC or path == REPO / "ikbench" / "core" / "defaults.py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.Constant) and isinstance(node.value, str)
                    and all(piece.strip() in names for piece in node.value.split(","))):
                bad.append(f"{path.relative_to(REPO)}:{node.lineno}: {node.value!r}")
    assert not bad, "import the name from ikbench.core.defaults or the method's class:\n" + \
        "\n".join(bad)


#: The defaults several layers share, each defined once in ikbench/core/defaults.py.
SHARED_DEFAULTS = ("DEFAULT_ROBOT", "DEFAULT_DURATION_S")


def _is_default_duration(node: ast.expr | None) -> bool:
    """``node`` is the number 2 (the default duration written out)."""
    from ikbench.core.defaults import DEFAULT_DURATION_S

    return (isinstance(node, ast.Constant) and isinstance(node.value, (int, float))
            and not isinstance(node.value, bool) and node.value == DEFAULT_DURATION_S)


def _defaults_of(node: ast.FunctionDef | ast.AsyncFunctionDef):
    args = node.args
    positional = [*args.posonlyargs, *args.args]
    yield from zip(positional[len(positional) - len(args.defaults):], args.defaults)
    yield from zip(args.kwonlyargs, args.kw_defaults)


def test_each_shared_default_is_defined_once():
    """The robot and the movement duration used when none is given are defined in
    ikbench/core/defaults.py only: no other module assigns those names, nor gives a
    ``duration_s`` parameter or field or a ``--duration`` option the 2 s written out."""
    from ikbench.core import defaults

    assert defaults.DEFAULT_ROBOT == "nico_right_arm" and defaults.DEFAULT_DURATION_S == 2.0
    bad = []
    for path, _ in _modules():
        if path == REPO / "ikbench" / "core" / "defaults.py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            where = f"{path.relative_to(REPO)}:{getattr(node, 'lineno', '?')}"
            if isinstance(node, (ast.Assign, ast.AnnAssign)):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                names = {t.id for t in targets if isinstance(t, ast.Name)}
                if names & set(SHARED_DEFAULTS):
                    bad.append(f"{where}: defines {sorted(names)}")
                if "duration_s" in names and _is_default_duration(node.value):
                    bad.append(f"{where}: duration_s = 2")
            elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                bad += [f"{where}: {node.name}(duration_s=2)"
                        for arg, value in _defaults_of(node)
                        if arg.arg == "duration_s" and _is_default_duration(value)]
            elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                  and node.func.attr == "add_argument" and node.args
                  and isinstance(node.args[0], ast.Constant) and node.args[0].value == "--duration"
                  and any(k.arg == "default" and _is_default_duration(k.value)
                          for k in node.keywords)):
                bad.append(f"{where}: --duration with default 2")
    assert not bad, "import it from ikbench.core.defaults:\n" + "\n".join(bad)


ROBOT_MODULES = ("ikbench/core/robot.py", "ikbench/core/robot_config.py")


def _robot_config(node: ast.expr) -> bool:
    """True for ``<robot>.config``: an attribute ``config`` of something named like a robot
    (``robot``, ``problem_robot``, ``self.robot``)."""
    if not (isinstance(node, ast.Attribute) and node.attr == "config"):
        return False
    owner = node.value
    name = owner.id if isinstance(owner, ast.Name) else getattr(owner, "attr", "")
    return "robot" in name.lower()


def robot_config_key_reads(tree: ast.AST, where: str) -> list[str]:
    """``robot.config["x"]``, ``robot.config.get("x")`` and ``"x" in robot.config`` in
    ``tree``: key reads of a robot config that :class:`RobotConfig` gives as attributes."""
    bad = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Subscript) and _robot_config(node.value):
            bad.append(f"{where}:{node.lineno}: robot.config[...]")
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
              and node.func.attr in ("get", "keys", "items") and _robot_config(node.func.value)):
            bad.append(f"{where}:{node.lineno}: robot.config.{node.func.attr}(...)")
        elif (isinstance(node, ast.Compare) and any(isinstance(op, (ast.In, ast.NotIn))
                                                  for op in node.ops)
              and any(_robot_config(c) for c in node.comparators)):
            bad.append(f"{where}:{node.lineno}: ... in robot.config")
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
              and node.func.id == "getattr" and len(node.args) >= 2
              and isinstance(node.args[1], ast.Constant) and node.args[1].value == "config"
              and isinstance(node.args[0], ast.Name) and "robot" in node.args[0].id
              and isinstance(getattr(node, "parent", None), ast.BoolOp)):
            bad.append(f"{where}:{node.lineno}: getattr(robot, 'config') or {{}}")
    return bad


def test_robot_config_read_by_attribute_outside_the_robot_module():
    bad = []
    for path, _ in _modules():
        where = str(path.relative_to(REPO))
        if where in ROBOT_MODULES:
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for parent in ast.walk(tree):
            for child in ast.iter_child_nodes(parent):
                child.parent = parent  # type: ignore[attr-defined]
        bad += robot_config_key_reads(tree, where)
    assert not bad, "read RobotConfig's attributes, not keys:\n" + "\n".join(bad)


@pytest.mark.parametrize("source", ['robot.config.get("targets")', 'robot.config["config_path"]',
                                    '"pointing_axis" in self.robot.config',
                                    'getattr(robot, "config", None) or {}'])
def test_the_robot_config_check_sees_key_reads(source):
    tree = ast.parse(source)
    for parent in ast.walk(tree):
        for child in ast.iter_child_nodes(parent):
            child.parent = parent  # type: ignore[attr-defined]
    assert robot_config_key_reads(tree, "x")


def test_pyproject_lists_every_package():
    listed = set(tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
                 ["packages"])
    # baselines/ installs as ikbench.baselines (package-dir in pyproject.toml)
    found = {str(p.parent.relative_to(REPO)).replace(os.sep, ".")
             for p in (REPO / "ikbench").rglob("__init__.py")}
    found |= {"ikbench." + str(p.parent.relative_to(REPO)).replace(os.sep, ".")
              for p in (REPO / "baselines").rglob("__init__.py")}
    assert found <= listed, f"not in pyproject.toml: {sorted(found - listed)}"


@pytest.fixture
def broken_plugins(tmp_path):
    """An installed distribution (a dist-info on PYTHONPATH) whose entry points name a method
    module that imports a missing library, one whose class does not exist, and a good one."""
    (tmp_path / "plugin_methods.py").write_text(
        "import not_a_real_kinematics_library  # noqa\n")
    (tmp_path / "plugin_good.py").write_text(
        "from ikbench.methods.ours_lm import OursLM\n\n"
        "class Renamed(OursLM):\n    name = 'plugin-lm'\n    description = 'ours-lm again'\n")
    info = tmp_path / "fake_plugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: fake-plugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[ikbench.methods]\nbroken = plugin_methods:Broken\nmissing-class = plugin_good:Nope\n"
        "plugin-lm = plugin_good:Renamed\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(REPO)])}
    return env


def _ikbench(env, *args):
    return subprocess.run([sys.executable, "-m", "ikbench.cli", *args], capture_output=True,
                          text=True, env=env, cwd=env["PYTHONPATH"].split(os.pathsep)[0])


def test_a_method_whose_library_is_missing_breaks_nothing(broken_plugins):
    listing = _ikbench(broken_plugins, "methods")
    assert listing.returncode == 0, listing.stderr
    lines = {line.split()[0]: line for line in listing.stdout.splitlines()}
    assert "UNAVAILABLE" in lines["broken"]
    assert "No module named 'not_a_real_kinematics_library'" in lines["broken"]
    assert "UNAVAILABLE" in lines["missing-class"] and "Nope" in lines["missing-class"]
    assert "available" in lines["plugin-lm"] and "ours-lm" in lines
    fk = _ikbench(broken_plugins, "fk", "--json")
    assert fk.returncode == 0 and fk.stderr == ""
    run = _ikbench(broken_plugins, "run", "--method", "broken", "--quiet")
    assert run.returncode == 2
    assert run.stderr.startswith("ikbench: error: --method: broken is not available here: "
                                 "failed to import: ModuleNotFoundError")
    good = _ikbench(broken_plugins, "run", "--method", "plugin-lm", "--only", "1",
                    "--steps", "5", "--quiet", "--output", "out")
    assert good.returncode == 0, good.stderr


def test_a_built_in_method_with_its_library_missing_is_listed_with_the_extra(monkeypatch):
    from ikbench.methods import registry

    class NeedsLib:
        name = "needs-lib"

    needs = registry.Adapter(library="x", requires=("not_a_real_kinematics_library",),
                             methods=(NeedsLib,))
    monkeypatch.setattr(registry, "_FOUND", [*registry._found(),
                                             registry._Found(needs, "built-in", "x")])
    monkeypatch.setattr(registry, "_STATUS", None)
    status = registry.method_status()["needs-lib"]
    assert not status.available
    assert status.reason == ("needs not_a_real_kinematics_library (pip install "
                             "'ikbench[libs]')")
    assert "ours-lm" in registry.available_methods()


def test_fk_imports_no_method_and_no_torch():
    code = ("import sys; from ikbench.cli import main; main(['fk', '--json']); "
            "print(sorted(m for m in sys.modules if m.startswith(('ikbench.methods', "
            "'ikbench.baselines', 'baselines', 'torch'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=REPO).stdout.splitlines()
    assert out[-1] == "[]"


#: Folders whose modules form ikbench's import graph, and the package each installs as.
PACKAGE_FOLDERS = {"ikbench": "ikbench", "baselines": "ikbench.baselines", "urdf": "ikbench.robots"}
#: A string naming a module, as the registries and entry points write one: "ikbench.x.y" or
#: "ikbench.x.y:attr".
MODULE_STRING = re.compile(r"(ikbench(?:\.\w+)+)(?::\w+(?:\.\w+)*)?")


def _module_files() -> dict[str, Path]:
    """Every module's dotted name (as installed) -> its file; a package is its ``__init__``."""
    files = {}
    for folder, package in PACKAGE_FOLDERS.items():
        for path in sorted((REPO / folder).rglob("*.py")):
            parts = path.relative_to(REPO / folder).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            files[".".join([package, *parts])] = path
    return files


def _target(name: str, modules) -> str | None:
    """The module that importing ``name`` loads for its importer: the longest prefix of
    ``name`` that is one of ``modules`` (a submodule rather than the package that holds it)."""
    parts = name.split(".")
    for end in range(len(parts), 0, -1):
        prefix = ".".join(parts[:end])
        if prefix in modules:
            return prefix
    return None


def _imports_of(module: str, path: Path, modules) -> set[str]:
    """The modules of ``modules`` that ``module`` imports, wherever the import stands (top level,
    ``if TYPE_CHECKING:``, inside a function) and however it is written: ``import a.b``,
    ``from a import b`` (b a submodule: that submodule; b a name: the module a), relative
    imports, and strings that name a module ("ikbench.x.y" or "ikbench.x.y:attr"). Importing
    ``a.b.c`` counts as importing ``a.b.c`` only, not the packages ``a`` and ``a.b`` that
    Python runs first: those are arrows only where their own names are taken."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(_target(a.name, modules) for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, *([base] if base else [])])
            for alias in node.names:
                found.add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules
                          else _target(base, modules))
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            named = MODULE_STRING.fullmatch(node.value)
            # a package of its own named alone (the registry scanning ikbench.methods' folder)
            # is no arrow: Python imports a module's packages before the module itself
            if named and not (named.group(0) == named.group(1)
                              and module.startswith(named.group(1) + ".")):
                found.add(_target(named.group(1), modules))
    return {name for name in found if name is not None and name != module}


def import_graph() -> dict[str, set[str]]:
    """ikbench's modules (ikbench/, baselines/ as ikbench.baselines, urdf/ as ikbench.robots),
    each with the modules it imports."""
    files = _module_files()
    return {module: _imports_of(module, path, files) for module, path in files.items()}


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of ``graph`` with more than one module (Tarjan's
    algorithm, iterative), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, edges = work[-1]
            for other in edges:
                if other not in index:
                    index[other] = low[other] = len(index)
                    stack.append(other)
                    on_stack.add(other)
                    work.append((other, iter(sorted(graph.get(other, ())))))
                    break
                if other in on_stack:
                    low[node] = min(low[node], index[other])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    if len(component) > 1:
                        cycles.append(sorted(component))
    return cycles


#: Circles being taken apart elsewhere: (the prefix of all their modules, a module they hold).
KNOWN_CYCLES: tuple[tuple[str, str], ...] = ()


def _files(modules: list[str]) -> list[str]:
    files = _module_files()
    return [str(files[m].relative_to(REPO)) for m in modules]


def test_the_import_graph_sees_every_kind_of_import(tmp_path):
    """Every import form a cycle can hide in is an arrow: under ``if TYPE_CHECKING:``, inside a
    function, relative, ``from package import submodule``, a "module:attr" string; a package
    importing a submodule is not an arrow to the package's own ``__init__``."""
    modules = {"ikbench", "ikbench.a", "ikbench.a.b", "ikbench.a.c", "ikbench.d", "ikbench.e",
               "ikbench.f", "ikbench.g", "ikbench.h"}
    source = tmp_path / "c.py"
    source.write_text(
        "from typing import TYPE_CHECKING\n"
        "from ikbench.a import b\n"                     # a submodule: ikbench.a.b
        "from ikbench.d import name\n"                  # a name: the module ikbench.d
        "if TYPE_CHECKING:\n    from ikbench.e import E\n"
        "def f():\n    from . import b\n    import ikbench.f\n"
        "TARGET = 'ikbench.g:function'\nOTHER = 'ikbench.h'\n"
        "PACKAGE = 'ikbench.a'\nTEXT = 'see ikbench.g'\n")
    assert _imports_of("ikbench.a.c", source, modules) == {
        "ikbench.a.b", "ikbench.d", "ikbench.e", "ikbench.f", "ikbench.g", "ikbench.h"}
    graph = import_graph()
    assert "ikbench.core.robot" in graph["ikbench.core.losses"]        # under TYPE_CHECKING
    assert "ikbench.paper.report_tables" in graph["ikbench"]           # a "module:attr" string
    assert "ikbench.baselines.drake.common" in graph["ikbench.baselines.drake.ik"]
    assert "ikbench.methods" not in graph["ikbench.methods.registry"]  # scans its own package
    assert import_cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert import_cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycles():
    """No two modules of ikbench (baselines/ and urdf/ included) import each other, through
    any chain of imports of any kind: at the top, under ``if TYPE_CHECKING:`` (a type-only
    cycle still means two files are one concept or a third is missing), inside a function, or
    by a string naming a module ("ikbench.x.y:attr", imported later by importlib). Where two
    modules share something, a third module holds it (a Protocol, a dataclass, constants)."""
    cycles = [cycle for cycle in import_cycles(import_graph())
              if not any(member in cycle and all(m.startswith(prefix) for m in cycle)
                         for prefix, member in KNOWN_CYCLES)]
    assert not cycles, "import cycles:\n" + "\n".join(
        " <-> ".join(_files(cycle)) for cycle in cycles)
