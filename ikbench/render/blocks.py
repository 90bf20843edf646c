"""Generated blocks: every measured figure in README.md and docs/ rendered from a results file.

A block is a pair of HTML comments around text that a renderer writes from a committed results
file::

    <!-- generated: table results/compare/leaderboard.csv columns=method,success_count -->
    | method | success_count |
    ...
    <!-- /generated -->

The opening comment names the renderer, the source file (relative to the repository root) and
the renderer's options (``key=value``; quote a value with spaces: ``columns="a:A b"``).
:func:`render_text` rewrites every block of a text; :func:`check_files` says which blocks differ
from a fresh render (the test suite runs it, so a retyped or stale figure fails). Blocks may stand
inline in a sentence (``value``, ``range``, ``fraction``, ``provenance``) or on lines of their own
(``table`` and the named renderers).

Renderers (:data:`RENDERERS`):

- ``table SOURCE [where=COL:VALUE[|VALUE][;COL:VALUE]] [columns=COL[:Header],...] [digits=N]``:
  a Markdown table of a CSV's rows (rows where each COL equals one of its VALUEs as text),
  followed by the provenance line of the folder's run record.
- ``value SOURCE column=COL [where=...] [agg=median] [format=.3g] [unit=ms] [scale=1000]``:
  one cell (the single row the filter leaves, or ``agg`` of the rows it leaves: min, max,
  median, mean, sum, count), formatted, with its unit. For a JSON source (``dataset.json``,
  ``run.json``): ``key=this_run.trajectories_per_s`` instead of ``column``.
- ``range SOURCE column=COL [where=...] [format] [unit] [scale]``: "min-max unit" of a column
  over the rows the filter leaves (one value when they are equal).
- ``fraction SOURCE column=COL [where=...]``: "k/N", the rows whose COL is true (True, 1) among
  the N the filter leaves.
- ``list SOURCE column=COL [where=...] [format] [unit] [scale]``: the column's values of the rows
  the filter leaves, in file order, comma-separated.
- ``provenance SOURCE``: "measured at commit C (clean) on CPU, N cores, load L, DATE", from the
  JSON record beside the source (run.json, benchmark.json, throughput.json, ...).
- ``ik-table FOLDER [robots=a,b] [rule=auto]``: the single-pose IK leaderboards of
  ``FOLDER/<robot>/summary.csv`` (``ikbench ik``) side by side: a row per method, per robot its
  success and per-call median time under the attempts rule (a rule run several times,
  ``--repeat``: the median and its min-max over the runs), then the batched rates and each
  robot's provenance.
- ``libraries pyproject.toml [form=names|count]``: the kinematics libraries ikbench runs, from
  the registry's adapters whose library is a distribution of the ``[libs]`` extra of
  ``pyproject.toml`` and not a dependency of ikbench itself (``count``: how many, in words);
  inline.
- ``paired SOURCE column=COL a=METHOD b=METHOD [b_source=PATH] [key=trajectory] [where=...]
  [higher=better|worse] [format=.3g] [pending=1]``: a paired verdict of two methods over the
  same trajectories or targets (:func:`render_paired`); inline.
- ``compare-table SOURCE [reference=ours-lm]``: README's leaderboard of a compare folder's
  ``leaderboard.csv`` (:func:`ikbench.render.leaderboard.readme_table`), then its provenance.
"""

from __future__ import annotations

import json
import math
import re
import shlex
import tomllib
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from ikbench.core.defaults import REFERENCE_METHOD
from ikbench.core.errors import InputError
from ikbench.core.intervals import paired_verdict
from ikbench.core.io import atomic_write_text
from ikbench.methods.registry import adapters
from ikbench.render.leaderboard import readme_table

#: ``<!-- generated: RENDERER SOURCE OPTIONS -->`` ... ``<!-- /generated -->``
BLOCK = re.compile(r"(<!-- generated: (?P<spec>[^>]*?) -->)(?P<body>.*?)(<!-- /generated -->)",
                   re.S)
#: JSON records a results folder may hold, in the order they are looked for.
RECORDS = ("run.json", "benchmark.json", "throughput.json", "batch.json", "sweep.json",
           "manifest.json", "analysis.json", "design.json", "power.json", "methods.json",
           "learned.json", "bare_calls.json")

#: renderer name -> function(source path, options, repo root) -> text
Renderer = Callable[[Path, dict[str, str], Path], str]
RENDERERS: dict[str, Renderer] = {}


@dataclass(frozen=True)
class Block:
    """One generated block of a file."""

    file: Path
    renderer: str
    source: str
    options: dict[str, str]
    body: str
    line: int


def register(name: str, renderer: Renderer) -> None:
    """Add a named renderer (``name SOURCE OPTIONS`` in a block's opening comment)."""
    RENDERERS[name] = renderer


def parse_spec(spec: str, where: str = "") -> tuple[str, str, dict[str, str]]:
    """(renderer, source, options) of an opening comment's text; InputError naming ``where``
    when it is malformed."""
    try:
        words = shlex.split(spec)
    except ValueError as exc:
        raise InputError(f"{where}: cannot read {spec!r}: {exc}") from None
    if len(words) < 2:
        raise InputError(f"{where}: a generated block needs 'RENDERER SOURCE', got {spec!r}")
    options = {}
    for word in words[2:]:
        key, sep, value = word.partition("=")
        if not sep:
            raise InputError(f"{where}: option {word!r} is not key=value")
        options[key] = value
    if words[0] not in RENDERERS:
        raise InputError(f"{where}: renderer {words[0]!r} is unknown; known: "
                         f"{', '.join(sorted(RENDERERS))}")
    return words[0], words[1], options


def blocks(path: Path) -> list[Block]:
    """Every generated block of the file at ``path``."""
    text = path.read_text(encoding="utf-8")
    out = []
    for match in BLOCK.finditer(text):
        line = text.count("\n", 0, match.start()) + 1
        renderer, source, options = parse_spec(match["spec"], f"{path}:{line}")
        out.append(Block(path, renderer, source, options, match["body"], line))
    return out


def render_block(block: Block, root: Path) -> str:
    """The block's body as its renderer writes it now (inline blocks stay on their line)."""
    source = root / block.source
    if not source.exists():
        raise InputError(f"{block.file}:{block.line}: source {block.source} does not exist")
    text = RENDERERS[block.renderer](source, block.options, root)
    return text if "\n" not in text else f"\n{text}\n"


def render_text(text: str, root: Path, where: str = "") -> str:
    """``text`` with every block rendered afresh."""
    def replace(match: re.Match) -> str:
        line = text.count("\n", 0, match.start()) + 1
        renderer, source, options = parse_spec(match["spec"], f"{where}:{line}")
        body = render_block(Block(Path(where), renderer, source, options, "", line), root)
        return f"{match[1]}{body}{match[4]}"

    return BLOCK.sub(replace, text)


def render_files(paths: Iterable[Path], root: Path) -> list[Path]:
    """Rewrite every block of ``paths``; return the files that changed."""

    changed = []
    for path in paths:
        text = path.read_text(encoding="utf-8")
        new = render_text(text, root, str(path))
        if new != text:
            atomic_write_text(path, new)
            changed.append(path)
    return changed


def check_files(paths: Iterable[Path], root: Path) -> list[str]:
    """One line per block whose text differs from a fresh render (empty: all current)."""
    stale = []
    for path in paths:
        for block in blocks(path):
            if block.body != render_block(block, root):
                stale.append(f"{path.relative_to(root)}:{block.line}: {block.renderer} "
                             f"{block.source} differs from a fresh render")
    return stale


def documents(root: Path) -> list[Path]:
    """README.md and every page of docs/: the files whose blocks are rendered."""
    return [root / "README.md", *sorted((root / "docs").glob("*.md"))]


# ----- the generic renderers -----------------------------------------------------------------
def _rows(source: Path, options: dict[str, str]) -> pd.DataFrame:
    frame = pd.read_csv(source, dtype=str, keep_default_na=False)
    for condition in filter(None, options.get("where", "").split(";")):
        column, _, value = condition.partition(":")
        if column not in frame.columns:
            raise InputError(f"{source}: where={condition!r}: no column {column!r}")
        frame = frame[frame[column].isin(value.split("|"))]
    return frame


def _number(text: str, digits: int) -> str:
    try:
        value = float(text)
    except ValueError:
        return text
    if math.isnan(value):
        return ""
    if value == int(value) and abs(value) < 1e15:
        return str(int(value))
    if abs(value) >= 10 ** digits:
        return f"{value:.0f}"  # 1892, not 1.89e+03
    return f"{value:.{digits}g}"


def render_table(source: Path, options: dict[str, str], root: Path) -> str:
    """A Markdown table of a CSV's rows (see the module docstring), then its provenance."""
    frame = _rows(source, options)
    digits = int(options.get("digits", "3"))
    spec = [c.partition(":") for c in options.get("columns", "").split(",") if c] or \
        [(c, "", "") for c in frame.columns]
    missing = [c for c, _, _ in spec if c not in frame.columns]
    if missing:
        raise InputError(f"{source}: columns {missing} are not in the file")
    head = [h or c for c, _, h in spec]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    for _, row in frame.iterrows():
        lines.append("| " + " | ".join(_number(row[c], digits) for c, _, _ in spec) + " |")
    return "\n".join(lines) + "\n\n" + render_provenance(source, {}, root)


#: ``agg=`` of ``value``: name -> reduction of a column's values.
AGGREGATES: dict[str, Callable[[pd.Series], float]] = {
    "min": lambda v: float(v.min()), "max": lambda v: float(v.max()),
    "median": lambda v: float(v.median()), "mean": lambda v: float(v.mean()),
    "sum": lambda v: float(v.sum()), "count": lambda v: float(len(v))}


def _column(source: Path, options: dict[str, str]) -> pd.Series:
    """The ``column=`` values (float) of the rows ``where=`` leaves; InputError when the column
    is missing or no row is left."""
    frame = _rows(source, options)
    column = options.get("column")
    if column not in frame.columns:
        raise InputError(f"{source}: column={column!r} is not in the file")
    if frame.empty:
        raise InputError(f"{source}: where={options.get('where')!r} leaves no row")
    values = frame[column].replace({"True": "1", "False": "0"})
    try:
        return values.astype(float)
    except ValueError:
        raise InputError(f"{source}: column {column!r} holds text, not numbers") from None


def _json_value(source: Path, key: str) -> float:
    """The number at a dotted ``key`` of a JSON file."""
    value: Any = json.loads(source.read_text(encoding="utf-8"))
    for part in key.split("."):
        if not isinstance(value, dict) or part not in value:
            raise InputError(f"{source}: key={key!r}: no {part!r} there")
        value = value[part]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{source}: key={key!r} is {value!r}, not a number")
    return float(value)


def _formatted(value: float, options: dict[str, str]) -> str:
    value *= float(options.get("scale", "1"))
    unit = options.get("unit", "")
    return f"{value:{options.get('format', '.3g')}}" + (f" {unit}" if unit else "")


def render_value(source: Path, options: dict[str, str], root: Path) -> str:
    """One cell of a CSV, or an aggregate of a column, or a number of a JSON file, formatted,
    with its unit (see the module docstring)."""
    if source.suffix == ".json":
        return _formatted(_json_value(source, options.get("key", "")), options)
    values = _column(source, options)
    agg = options.get("agg")
    if agg is not None:
        if agg not in AGGREGATES:
            raise InputError(f"{source}: agg={agg!r} is unknown; known: "
                             f"{', '.join(AGGREGATES)}")
        return _formatted(AGGREGATES[agg](values), options)
    if len(values) != 1:
        raise InputError(f"{source}: where={options.get('where')!r} leaves {len(values)} rows, "
                         "not one (or give agg=)")
    return _formatted(float(values.iloc[0]), options)


def render_range(source: Path, options: dict[str, str], root: Path) -> str:
    """"min-max unit" of a column over the rows the filter leaves (see the module docstring)."""
    values = _column(source, options)
    low, high = (_formatted(float(v), {**options, "unit": ""})
                 for v in (values.min(), values.max()))
    unit = options.get("unit", "")
    return (low if low == high else f"{low}-{high}") + (f" {unit}" if unit else "")


def render_list(source: Path, options: dict[str, str], root: Path) -> str:
    """The column's values, comma-separated, in file order (see the module docstring)."""
    values = _column(source, options)
    unit = options.get("unit", "")
    return ", ".join(_formatted(float(v), {**options, "unit": ""}) for v in values) + \
        (f" {unit}" if unit else "")


def render_fraction(source: Path, options: dict[str, str], root: Path) -> str:
    """"k/N": the rows whose column is true among those the filter leaves."""
    values = _column(source, options)
    return f"{int((values != 0).sum())}/{len(values)}"


#: Columns by which a CSV's rows carry their own provenance (benchmarks/ours_speed.py's).
ROW_PROVENANCE = ("git_commit", "git_revision")


def record_of(source: Path) -> dict[str, Any]:
    """The provenance of ``source`` (a file or folder): a CSV's own columns when its rows carry
    it (:data:`ROW_PROVENANCE`: the first row), else the JSON run record beside it: the first
    of :data:`RECORDS` in its folder or the folders above it within results/."""
    if source.suffix == ".csv":
        head = pd.read_csv(source, nrows=1)
        if any(c in head.columns for c in ROW_PROVENANCE) and len(head):
            return head.iloc[0].to_dict()
    folder = source if source.is_dir() else source.parent
    for candidate in [folder, *folder.parents]:
        for name in RECORDS:
            if (candidate / name).is_file():
                record = json.loads((candidate / name).read_text(encoding="utf-8"))
                return record.get("provenance", record) if isinstance(record, dict) else {}
        if candidate.name == "results" or (candidate / ".git").exists():
            break
    raise InputError(f"{source}: no run record ({', '.join(RECORDS)}) beside it")


def render_provenance(source: Path, options: dict[str, str], root: Path) -> str:
    """"Measured at commit C on CPU (N logical CPUs), load L, DATE; from SOURCE." """
    record = record_of(source)
    commit = record.get("git_commit") or record.get("git_revision") or "unknown commit"
    clean = record.get("git_clean")
    if clean is None and str(commit).endswith("-dirty"):
        clean = False
    state = "" if clean is None else (", clean tree" if clean else ", modified tree")
    load = record.get("load_average")
    load_text = f", load {', '.join(f'{v:g}' for v in load)}" if load else ""
    date = str(record.get("created_utc", ""))[:10]
    relative = source.relative_to(root) if source.is_relative_to(root) else source
    return (f"*Measured at commit {str(commit)[:12]}{state} on {record.get('cpu', '?')} "
            f"({record.get('cpu_count', '?')} logical CPUs){load_text}, {date}; from "
            f"`{relative}`.*")


def render_compare_table(source: Path, options: dict[str, str], root: Path) -> str:
    """README's leaderboard (:func:`ikbench.render.leaderboard.readme_table`) of a compare
    folder's ``leaderboard.csv``, then its provenance."""
    board = pd.read_csv(source)
    return readme_table(board, options.get("reference", REFERENCE_METHOD)) + "\n\n" + \
        render_provenance(source, {}, root)


def render_ik_table(source: Path, options: dict[str, str], root: Path) -> str:
    """``ikbench ik``'s summaries of several robots in one table (see the module docstring):
    "success %, per-call median ms" per robot and method, methods in the first robot's order."""
    if not source.is_dir():
        raise InputError(f"{source}: ik-table takes a folder of ikbench ik results (results/ik)")
    names = [r for r in options.get("robots", "").split(",") if r] or \
        sorted(p.parent.name for p in source.glob("*/summary.csv"))
    if not names:
        raise InputError(f"{source}: no <robot>/summary.csv in it")
    rule = options.get("rule", "auto")
    frames = {}
    for name in names:
        path = source / name / "summary.csv"
        if not path.is_file():
            raise InputError(f"{path}: not found (robots={options.get('robots')!r})")
        frame = pd.read_csv(path, dtype={"attempts_rule": str})
        frames[name] = frame[frame["attempts_rule"] == rule].set_index("method")
        if frames[name].empty:
            raise InputError(f"{path}: no row with attempts_rule {rule!r}")
    methods = list(dict.fromkeys(m for f in frames.values() for m in f.index))
    head = ["method", *(f"{n}: success, per-call median" for n in names)]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    for method in methods:
        cells = [method]
        for name in names:
            frame = frames[name]
            if method not in frame.index:
                cells.append("not run")
                continue
            row = frame.loc[method]
            time_ms = _number(row["time_median_ms"], 3)
            success = f"{row['success_pct']:.2f} %"
            if row.get("runs", 1) > 1:  # repeated (--repeat): median (min-max) over the runs
                success += f" ({row['success_pct_min']:.2f}-{row['success_pct_max']:.2f})"
                if time_ms:
                    time_ms += (f" ({_number(row['time_median_ms_min'], 3)}-"
                                f"{_number(row['time_median_ms_max'], 3)})")
            cells.append(f"{success}, " + (f"{time_ms} ms" if time_ms else
                                           "no call timed (failed rows)"))
        lines.append("| " + " | ".join(cells) + " |")
    batched = []
    for name in names:
        rows = frames[name].dropna(subset=["batched_per_s"])
        batched += [f"{m} {row['batched_per_s']:,.0f} IK/s on {name} "
                    f"({int(row['batched_threads'])} threads)" for m, row in rows.iterrows()]
    text = "\n".join(lines)
    if batched:
        text += "\n\nBatched (every target in one call, not a per-call time): " + \
            "; ".join(batched) + "."
    return text + "\n\n" + "\n".join(render_provenance(source / n / "summary.csv", {}, root)
                                      for n in names)


#: Numbers in words, for "ten kinematics libraries".
_WORDS = ("no", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten",
          "eleven", "twelve", "thirteen", "fourteen", "fifteen")


def render_libraries(source: Path, options: dict[str, str], root: Path) -> str:
    """The libraries of the ``[libs]`` extra that an adapter runs (see the module docstring):
    their distributions' names in the registry's order, or their count in words."""
    project = tomllib.loads(source.read_text(encoding="utf-8"))["project"]

    def names_of(lines: list[str]) -> set[str]:
        return {re.split(r"[=<>!~\[ ;]", line.strip(), maxsplit=1)[0].lower() for line in lines}

    # the extra's libraries that ikbench does not itself depend on (Pinocchio is its own)
    names = names_of(project["optional-dependencies"]["libs"]) - names_of(
        project["dependencies"])
    libraries = list(dict.fromkeys(a.library for a in adapters() if a.library.lower() in names))
    form = options.get("form", "names")
    if form == "count":
        return _WORDS[len(libraries)] if len(libraries) < len(_WORDS) else str(len(libraries))
    if form != "names":
        raise InputError(f"libraries: form={form!r} is not names or count")
    return ", ".join(f"`{name}`" for name in libraries)


register("table", render_table)
register("libraries", render_libraries)
register("compare-table", render_compare_table)
register("ik-table", render_ik_table)
register("value", render_value)
register("range", render_range)
register("fraction", render_fraction)
register("list", render_list)
register("provenance", render_provenance)


def _paired_side(source: Path, options: dict[str, str], method: str, key: str,
                 column: str) -> pd.Series:
    """``column`` (float) of ``method``'s rows of ``source`` (after ``where=``), by ``key``."""
    frame = _rows(source, options)
    for name in ("method", key, column):
        if name not in frame.columns:
            raise InputError(f"{source}: paired: no column {name!r}")
    rows = frame[frame["method"] == method]
    if rows.empty:
        raise InputError(f"{source}: paired: no row of method {method!r}")
    if rows[key].duplicated().any():
        raise InputError(f"{source}: paired: method {method!r} has {key} values twice; "
                         "narrow it with where=")
    return rows.set_index(key)[column].replace({"": "nan"}).astype(float)


def render_paired(source: Path, options: dict[str, str], root: Path) -> str:
    """A paired verdict between two methods (:func:`ikbench.core.intervals.paired_verdict`):
    ``paired SOURCE column=COL a=METHOD b=METHOD [b_source=PATH] [key=trajectory]
    [where=...] [higher=better|worse] [format=.3g] [pending=1]``; inline. The pairs are the
    ``key`` values both methods have (``b`` from ``b_source`` when given, e.g. another run's
    details.csv); the text states the count, the sign test's p, the bootstrap interval of the
    paired median difference and "a tie" unless a difference is shown. ``pending=1``: a
    column the file lacks renders as "not measured in SOURCE yet" (a column that comes with
    the next regeneration) instead of failing."""
    column, key = options.get("column", ""), options.get("key", "trajectory")
    a, b = options.get("a", ""), options.get("b", "")
    if not (column and a and b):
        raise InputError(f"{source}: paired needs column=, a= and b=")
    other = root / options["b_source"] if "b_source" in options else source
    if options.get("pending") == "1":
        for path in (source, other):
            if column not in pd.read_csv(path, nrows=0).columns:
                return (f"not measured in `{path.relative_to(root)}` yet (its column "
                        f"`{column}` comes with the next regeneration)")
    higher = options.get("higher", "better")
    if higher not in ("better", "worse"):
        raise InputError(f"{source}: paired: higher={higher!r} is not better or worse")
    left = _paired_side(source, options, a, key, column)
    right = _paired_side(other, {k: v for k, v in options.items() if k != "where"} if
                         "b_source" in options else options, b, key, column)
    both = left.index.intersection(right.index)
    if not len(both):
        raise InputError(f"{source}: paired: {a} and {b} share no {key}")
    verdict = paired_verdict(left.loc[both].to_numpy(), right.loc[both].to_numpy(), (a, b),
                             higher_is_better=higher == "better",
                             fmt=options.get("format", ".3g"))
    return verdict["text"]


register("paired", render_paired)
