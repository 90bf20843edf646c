"""Every option of every command survives hostile input (issue 39).

The cases are generated from the parser (tests/hostile.py): every subcommand, every argument
that takes a value, each of 13 hostile values (nan, inf, -inf, -1, 0, 1e308, 1e-300, 1e12, an
empty string, a 10,000-character string, an empty directory, /proc, a missing file), so a new
option is covered without touching this file. They run in one child process under a memory
limit (``resource.setrlimit``, :data:`MEMORY_LIMIT_BYTES`), each through the entry point's
parse-and-run with the command stopped where its input is checked (nothing solved or written
by a value it accepts).

What must hold for each case: exit code 2 with exactly one line on stderr naming the argument,
or (for the values some options take: 0, -1, 1e-300, 1e12, a folder, a new file, and a word such
as ``nan`` for an option that takes text) the input accepted; never a traceback or a crash;
at most :data:`MAX_CASE_S` seconds; nothing written; and the whole child within the memory
limit.
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from tests import hostile

#: The child's address-space limit: no command may need more before refusing a value.
MEMORY_LIMIT_BYTES = 2 * 2**30
#: The most one case may take, start-up of the command's libraries included [s].
MAX_CASE_S = 10.0
#: Values refused by every option, and by options taking numbers also the non-finite and
#: overflowing ones.
REFUSED_BY_ALL = {"empty", "long", "proc"}
REFUSED_BY_NUMBERS = REFUSED_BY_ALL | {"nan", "inf", "-inf", "1e308"}


def _limit_memory() -> None:  # runs in the child before it starts
    resource.setrlimit(resource.RLIMIT_DATA, (MEMORY_LIMIT_BYTES, MEMORY_LIMIT_BYTES))


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> dict:
    """Every case's outcome (the child's JSON), run once for this module."""
    cwd = tmp_path_factory.mktemp("hostile_cwd")
    out = tmp_path_factory.mktemp("hostile") / "results.json"
    done = subprocess.run([sys.executable, str(Path(hostile.__file__)), str(out)], cwd=cwd,
                          capture_output=True, text=True, timeout=600,
                          preexec_fn=_limit_memory)
    assert done.returncode == 0, done.stderr[-3000:]
    assert list(cwd.iterdir()) == []  # nothing written where the commands ran
    return json.loads(out.read_text())


def _numbers(case: dict, kinds: dict) -> bool:
    return kinds.get((case["command"], case["argument"])) in ("number", "number or inf")


@pytest.fixture(scope="module")
def kinds() -> dict:
    """(command, argument) -> "number", "number or inf" (a Number whose ``infinite`` says
    what inf means: ``ik --budget-ms inf``, no budget) or "text", from the parser."""
    from ikbench.cli import build_parser
    from ikbench.cli.values import Number

    parser = build_parser(None)
    out = {}
    for command, sub in hostile._subparsers(parser).items():
        for action in sub._actions:
            if action.nargs != 0:
                number = isinstance(action.type, Number)
                out[(command, hostile._name(action))] = (
                    ("number or inf" if action.type.infinite else "number") if number
                    else "text")
    return out


def test_every_argument_of_every_command_is_covered(results, kinds):
    """13 values for each argument that takes one: the count is stated here and in the
    report of issue 39."""
    covered = {(c["command"], c["argument"]) for c in results["cases"]}
    assert covered == set(kinds)
    assert len(results["cases"]) == len(kinds) * len(hostile.HOSTILE)
    assert len(results["cases"]) > 2500  # 6,058 here: 466 arguments, every library installed


def _failures(results: dict, kinds: dict, command: str) -> list[str]:
    bad = []
    for case in (c for c in results["cases"] if c["command"] == command):
        label = f"{command} {case['argument']}={case['value']}"
        lines = case["stderr"].strip().splitlines()
        refused = REFUSED_BY_NUMBERS if _numbers(case, kinds) else REFUSED_BY_ALL
        if kinds.get((command, case["argument"])) == "number or inf":
            refused = refused - {"inf"}
        if case["crash"] or "Traceback" in case["stderr"]:
            bad.append(f"{label}: crashed: {case['crash'] or case['stderr'][-300:]}")
        elif case["code"] is None:
            if case["value"] in refused:
                bad.append(f"{label}: accepted")
        elif case["code"] != 2:
            bad.append(f"{label}: exit code {case['code']}: {case['stderr'][-300:]}")
        elif len(lines) != 1:
            bad.append(f"{label}: {len(lines)} lines on stderr: {case['stderr'][-300:]}")
        elif not _names(lines[0], case["argument"]):
            bad.append(f"{label}: the error does not name the argument: {lines[0][:300]}")
        if case["seconds"] > MAX_CASE_S:
            bad.append(f"{label}: {case['seconds']:.1f} s")
        if case["written"]:
            bad.append(f"{label}: wrote {case['written']}")
    return bad


def _names(line: str, argument: str) -> bool:
    return argument in line


@pytest.mark.parametrize("command", sorted(hostile.BASE) + ["methods", "robots"])
def test_hostile_values_are_refused_in_one_line(results, kinds, command):
    bad = _failures(results, kinds, command)
    assert not bad, f"{len(bad)} failing cases:\n" + "\n".join(bad[:40])


def test_memory_stays_within_the_limit(results):
    """The child ran every case under the limit; its own peak resident memory (``VmHWM``,
    libraries' code included) is below it too."""
    assert results["peak_rss_kib"] * 1024 < MEMORY_LIMIT_BYTES, (
        f"peak resident {results['peak_rss_kib'] / 2**20:.2f} GiB")
