"""The documentation site builds with ``mkdocs build --strict`` (mkdocs.yml at the repository
root), and every relative link of README.md and docs/*.md names a file of the repository.

Links to files outside docs/ (``../results/...``) become part of the site through the hook
docs/hooks/repository_files.py; the strict build fails on any other dead link, and the built
site is checked for links that lead nowhere."""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
LINK = re.compile(r"\]\(([^)\s]+)\)")


@pytest.mark.skipif(importlib.util.find_spec("mkdocs") is None, reason="needs mkdocs")
def test_mkdocs_build_strict_passes(tmp_path):
    site = tmp_path / "site"
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(site)],
        cwd=REPO, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    assert (site / "index.html").is_file()
    assert "ikbench.methods.base.Method" in (site / "api" / "index.html").read_text()
    dead = _dead_links(site)
    assert not dead, dead[:20]
    # the results the pages link to are reachable on the site
    assert (site / "repository" / "results" / "compare" / "leaderboard" / "index.html").is_file()


HREF = re.compile(r'(?:href|src)="([^"]+)"')


def _dead_links(site: Path) -> list[str]:
    """Relative links of the built site's pages that lead to no file of the site."""
    dead = []
    for page in site.rglob("*.html"):
        for target in HREF.findall(page.read_text(encoding="utf-8")):
            if re.match(r"[a-z][a-z0-9+.-]*:", target) or target.startswith(("#", "/")):
                continue
            path = (page.parent / target.split("#")[0].split("?")[0]).resolve()
            if not path.is_relative_to(site.resolve()):
                dead.append(f"{page.relative_to(site)} -> {target} (outside the site)")
            elif not (path.is_file() or (path / "index.html").is_file()):
                dead.append(f"{page.relative_to(site)} -> {target}")
    return dead


def _relative_links(path: Path):
    for target in LINK.findall(path.read_text()):
        if re.match(r"[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
            continue  # a URL or an anchor in the same page
        yield target.split("#", 1)[0]


@pytest.mark.parametrize("page", [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))],
                         ids=lambda p: p.relative_to(REPO).as_posix())
def test_every_relative_link_names_a_file_of_the_repository(page):
    missing = [t for t in _relative_links(page) if not (page.parent / t).exists()]
    assert not missing, missing


def test_the_layout_picture_names_every_layer():
    """docs/contributing.md's picture of the layers names each layer the architecture test
    knows (a new layer is drawn or the test fails)."""
    from tests.test_architecture import LAYERS

    text = (REPO / "docs" / "contributing.md").read_text()
    picture = text.split("```mermaid", 1)[1].split("```", 1)[0]
    drawn = set(re.findall(r"^\s*(\w+)\[", picture, flags=re.M))
    assert drawn == set(LAYERS), (sorted(drawn), sorted(LAYERS))


#: Folders of this repository whose files a page may cite by path.
_CITED_ROOTS = ("ikbench/", "baselines/", "tests/", "benchmarks/", "urdf/", "examples/")


@pytest.mark.parametrize("page", [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))],
                         ids=lambda p: p.relative_to(REPO).as_posix())
def test_every_cited_source_file_exists(page):
    """A path of this repository written in backticks (`ikbench/schemes/track.py`) names a
    file or folder that exists (docs/baselines.md cited moved files; issue 45). The worked
    example of docs/contributing.md (an imaginary library) is the one exception."""
    roots = "|".join(_CITED_ROOTS)
    cited = re.findall(rf"`((?:{roots})[\w./-]*)`", page.read_text())
    installed = {"ikbench/robots/": "urdf/", "ikbench/baselines/": "baselines/"}  # the wheel's
    for name, folder in installed.items():
        cited = [folder + c.removeprefix(name) if c.startswith(name) else c for c in cited]
    missing = [c for c in cited if not (REPO / c.rstrip("/")).exists()
               and c != "baselines/fastik_ik.py"]
    assert not missing, missing
