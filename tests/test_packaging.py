"""pyproject.toml lists its packages explicitly (the robot models come from the top-level
urdf/ folder, the library methods from the top-level baselines/ folder as ikbench.baselines):
every package folder must be listed, and every data file shipped, or a wheel installed from
/tmp misses it while the editable install in the checkout still works; and the wheel installs
nothing beside ``ikbench``."""

from __future__ import annotations

import fnmatch
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

from tests.conftest import REPO

SETUPTOOLS = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
#: Top-level folders whose Python packages the wheel installs (baselines/ as ikbench.baselines).
ROOTS = ("ikbench", "baselines")
#: What a wheel is built from (a copy of them, so no stale build/ of the checkout leaks in).
SOURCES = ("pyproject.toml", "README.md", "LICENSE", "ikbench", "baselines", "urdf")


def package_dirs() -> dict[str, Path]:
    """Dotted name -> folder of every listed package (``package-dir`` applied)."""
    mapped = SETUPTOOLS.get("package-dir", {})

    def folder(name: str) -> Path:
        # setuptools maps a package under a mapped parent into the parent's folder
        parts = name.split(".")
        for k in range(len(parts), 0, -1):
            parent = ".".join(parts[:k])
            if parent in mapped:
                return REPO.joinpath(mapped[parent], *parts[k:])
        return REPO.joinpath(*parts)

    return {name: folder(name) for name in SETUPTOOLS["packages"]}


def folders_with_python(root: Path):
    """Every folder under ``root`` (itself included) that holds a .py file."""
    for path in sorted({p.parent for p in root.rglob("*.py")}):
        if "__pycache__" not in path.parts:
            yield path


@pytest.mark.parametrize("root", ROOTS)
def test_every_package_folder_is_listed(root):
    listed = {path.resolve() for path in package_dirs().values()}
    missing = [str(folder.relative_to(REPO)) for folder in folders_with_python(REPO / root)
               if folder.resolve() not in listed]
    assert not missing, f"add to [tool.setuptools] packages in pyproject.toml: {missing}"


@pytest.mark.parametrize("root", ROOTS)
def test_every_package_folder_is_a_package(root):
    """A folder of modules without __init__.py would be a namespace package, which the
    explicit list does not pick up."""
    plain = [str(folder.relative_to(REPO)) for folder in folders_with_python(REPO / root)
             if not (folder / "__init__.py").is_file()]
    assert not plain, f"add __init__.py to: {plain}"


def test_every_listed_package_exists():
    gone = [name for name, folder in package_dirs().items() if not folder.is_dir()]
    assert not gone, f"listed in pyproject.toml but not a folder: {gone}"


def test_every_package_is_inside_ikbench():
    """No top-level package but ``ikbench``: a generic ``baselines`` in site-packages would
    collide with any other package of that name (issue 27)."""
    outside = [name for name in SETUPTOOLS["packages"] if name.split(".")[0] != "ikbench"]
    assert not outside, f"installed outside the ikbench namespace: {outside}"
    assert SETUPTOOLS["package-dir"]["ikbench.baselines"] == "baselines"


def test_the_wheel_installs_no_top_level_package_but_ikbench(tmp_path):
    """Build the wheel (from a copy of the sources, ~2 s) and read its file list: everything
    under ``ikbench/`` (``baselines/*.py`` as ``ikbench/baselines/*.py``) and its dist-info."""
    source = tmp_path / "src"
    source.mkdir()
    ignore = shutil.ignore_patterns("__pycache__", "*.egg-info")
    for name in SOURCES:
        path = REPO / name
        if path.is_dir():
            shutil.copytree(path, source / name, ignore=ignore)
        else:
            shutil.copy2(path, source / name)
    build = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-index",
                            "--no-build-isolation", "-q", "-w", str(tmp_path / "dist"),
                            str(source)], capture_output=True, text=True)
    assert build.returncode == 0, build.stdout + build.stderr
    (wheel,) = (tmp_path / "dist").glob("ikbench-*.whl")
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
        info = next(n.split("/")[0] for n in names if n.endswith(".dist-info/RECORD"))
        top_level = archive.read(f"{info}/top_level.txt").decode().split()
    assert top_level == ["ikbench"]
    outside = sorted({n.split("/")[0] for n in names} - {"ikbench", info})
    assert not outside, f"the wheel installs beside ikbench: {outside}"
    shipped = {n for n in names if n.endswith(".py")}
    expected = {f"{name.replace('.', '/')}/{path.name}"
                for name, folder in package_dirs().items() for path in folder.glob("*.py")}
    assert "ikbench/baselines/trac_ik.py" in expected
    assert shipped == expected


def test_the_shipped_data_is_declared():
    """The data files the code reads at run time match a package-data pattern."""
    data = SETUPTOOLS["package-data"]
    folders = package_dirs()
    for package, subfolder in [("ikbench.paper", "data/reference"),
                               ("ikbench.paper", "data"),
                               ("ikbench", "data/cppflow"),
                               ("ikbench.robots", "")]:
        base = folders[package]
        files = [p for p in (base / subfolder).rglob("*") if p.is_file()
                 and p.suffix != ".py" and "__pycache__" not in p.parts
                 and (subfolder or p.parent == base)]
        assert files, (package, subfolder)
        for path in files:
            relative = path.relative_to(base).as_posix()
            assert any(fnmatch.fnmatch(relative, pattern) and relative.count("/")
                       == pattern.count("/") for pattern in data[package]), (
                f"{path.relative_to(REPO)} is not in [tool.setuptools.package-data] "
                f"{package!r}")


def test_citation_names_this_version_and_the_paper():
    import yaml

    citation = yaml.safe_load((REPO / "CITATION.cff").read_text())
    version = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["version"]
    assert citation["cff-version"] == "1.2.0" and citation["version"] == version
    paper = citation["references"][0]
    assert paper["title"] == ("Generating and Customizing Robotic Arm Trajectories using "
                              "Neural Networks")
    assert [a["family-names"] for a in paper["authors"]] == [
        "Lúčny", "Antonj", "Mazzola", "Hornáčková", "Farkaš"]
