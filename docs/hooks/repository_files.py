"""mkdocs hook: the repository files the pages link to become part of the site.

Pages link to files outside docs/ (``../results/compare/leaderboard.md``, ``../README.md``,
``../examples/README.md``). On the built site such a link would point outside the site, so
this hook adds every linked repository file (and, in turn, what a linked Markdown file links
to) to the site under ``repository/`` and rewrites the pages' links to it:
``../results/x.md`` from ``docs/page.md`` becomes ``repository/results/x.md``. Markdown files
become pages of their own (not in the navigation), images and tables are copied as they are.
A link to a file that does not exist stays as it is, and ``mkdocs build --strict`` fails on it.
"""

from __future__ import annotations

import re
from pathlib import Path, PurePosixPath

from mkdocs.structure.files import File, Files

LINK = re.compile(r"(\]\()([^)\s#]+)(#[^)\s]*)?(\))")
PREFIX = "repository"
DEPTH = 10


def _targets(text: str) -> list[str]:
    return [m.group(2) for m in LINK.finditer(text)
            if not re.match(r"[a-z][a-z0-9+.-]*:", m.group(2))]


def _outside(base: Path, target: str, repo: Path, docs: Path) -> Path | None:
    """The repository file a link of a file in ``base`` names, when it lies outside docs/."""
    path = (base / target).resolve()
    if not path.is_file() or not path.is_relative_to(repo) or path.is_relative_to(docs):
        return None
    return path


def on_files(files: Files, config) -> Files:
    docs = Path(config["docs_dir"]).resolve()
    repo = docs.parent
    found: set[Path] = set()
    frontier = [(p, 0) for p in docs.glob("*.md")]
    while frontier:
        page, depth = frontier.pop()
        for target in _targets(page.read_text(encoding="utf-8")):
            path = _outside(page.parent, target, repo, docs)
            if path is None or path in found:
                continue
            found.add(path)
            if path.suffix == ".md" and depth < DEPTH:
                frontier.append((path, depth + 1))
    for path in sorted(found):
        uri = str(PurePosixPath(PREFIX, path.relative_to(repo).as_posix()))
        files.append(File.generated(config, uri, abs_src_path=str(path)))
    return files


def on_page_markdown(markdown: str, page, config, files: Files) -> str:
    docs = Path(config["docs_dir"]).resolve()
    repo = docs.parent
    source = Path(page.file.abs_src_path).resolve()
    inside = source.is_relative_to(docs) and not page.file.src_uri.startswith(PREFIX + "/")
    here = PurePosixPath(page.file.src_uri).parent

    def rewrite(match: re.Match) -> str:
        target = match.group(2)
        if re.match(r"[a-z][a-z0-9+.-]*:", target):
            return match.group(0)
        path = (source.parent / target).resolve()
        if not path.is_file() or not path.is_relative_to(repo) or (
                inside and path.is_relative_to(docs)):
            return match.group(0)
        if path.is_relative_to(docs):  # a repository page linking back into docs/
            uri = PurePosixPath(path.relative_to(docs).as_posix())
        else:
            uri = PurePosixPath(PREFIX, path.relative_to(repo).as_posix())
        if files.get_file_from_path(str(uri)) is None:
            return match.group(0)
        relative = _relative(uri, here)
        return f"{match.group(1)}{relative}{match.group(3) or ''}{match.group(4)}"

    return LINK.sub(rewrite, markdown)


def _relative(uri: PurePosixPath, here: PurePosixPath) -> str:
    """``uri`` relative to the folder ``here`` (both relative to docs/)."""
    up = len(here.parts)
    common = 0
    for a, b in zip(here.parts, uri.parts):
        if a != b:
            break
        common += 1
    return "/".join([".."] * (up - common) + list(uri.parts[common:])) or "."
