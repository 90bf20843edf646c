"""Option values that validate themselves (ikbench.cli.values), the up-front budgets
(ikbench.core.budget) and how the CLI names the option of a library error."""

from __future__ import annotations

import argparse

import pytest

from ikbench.cli import build_parser, shorten, with_flags
from ikbench.cli.values import (
    FINITE,
    INTEGER,
    STEPS,
    Number,
    PathValue,
    Text,
    count,
    duration_s,
    harden,
    rate_hz,
)
from ikbench.core import budget
from ikbench.core.errors import InputError
from ikbench.core.targets import MAX_STEPS, MIN_STEPS


def _refusal(kind, text: str) -> str:
    with pytest.raises(argparse.ArgumentTypeError) as caught:
        kind(text)
    return str(caught.value)


def test_numbers_are_finite_and_in_range():
    assert duration_s()("2.5") == 2.5 and duration_s()(" 0.001 ") == 0.001
    assert _refusal(duration_s(), "nan") == ("nan is not a finite number; give a duration [s] "
                                             "from 0.001 to 3600")
    assert _refusal(duration_s(), "1e-300").startswith("1e-300 is out of range")
    assert _refusal(duration_s(), "two") == ("two is not a number; give a duration [s] from "
                                             "0.001 to 3600")
    assert _refusal(duration_s(), "").startswith("'' is empty; give a duration")


def test_integers_take_exponent_notation_and_refuse_fractions():
    kind = count("segments", 2, 5000)
    assert kind("1e3") == 1000 and isinstance(kind("1e3"), int) and kind("42") == 42
    assert _refusal(kind, "2.5") == "2.5 is not an integer; give a number of segments from 2 "\
                                    "to 5000"
    assert _refusal(kind, "1e12") == ("1e12 is out of range; give a number of segments from 2 "
                                      "to 5000")
    assert INTEGER(str(2**63 - 1)) == 2**63 - 1  # exact, not through a float


def test_zero_hint_and_shown_range():
    rate = rate_hz(10_000.0, zero="one point per pose")
    assert rate("0") == 0 and rate("250") == 250.0
    assert _refusal(rate, "-1") == ("-1 is out of range; give a rate [Hz] more than 0 to "
                                    "10,000 (or 0: one point per pose)")
    hinted = count("touch poses", 1, 100_000, "in one batch")
    assert _refusal(hinted, "0").endswith("from 1 to 100,000 (in one batch)")
    assert _refusal(Number("a port", 0, 65535, integer=True, shown="from 0 to 65535"),
                    "-5") == "-5 is out of range; give a port from 0 to 65535"


def test_text_is_bounded_and_one_line():
    assert Text()("ours-lm") == "ours-lm"
    assert _refusal(Text("a name"), "  ") == "'  ' is empty; give a name"
    long = _refusal(Text(), "x" * 10_000)
    assert "(10,000 characters) is longer than 1,000 characters" in long and len(long) < 400
    assert "line break" in _refusal(Text(), "a\nb")


def test_paths_to_read_must_exist_and_paths_to_write_fit_the_system(tmp_path):
    existing = tmp_path / "t.csv"
    existing.write_text("x")
    read = PathValue("a trajectory CSV", must_exist="file")
    assert read(str(existing)) == str(existing)
    assert _refusal(read, str(tmp_path)).endswith("is a directory; give a trajectory CSV")
    assert _refusal(read, str(tmp_path / "no.csv")).endswith("not found; give a trajectory CSV")
    assert "longer than a path may be" in _refusal(PathValue(), "a/" + "b" * 300)


def test_steps_match_what_the_targets_allow():
    assert (STEPS.low, STEPS.high) == (MIN_STEPS, MAX_STEPS)


def test_harden_gives_every_option_without_a_kind_a_default_one():
    parser = argparse.ArgumentParser()
    parser.add_argument("--gain", type=float)
    parser.add_argument("--count", type=int)
    parser.add_argument("--name")
    parser.add_argument("--flag", action="store_true")
    parser.add_argument("--steps", type=STEPS)
    harden(parser)
    kinds = {a.dest: a.type for a in parser._actions}
    assert kinds["gain"] is FINITE and kinds["count"] is INTEGER
    assert isinstance(kinds["name"], Text) and kinds["flag"] is None and kinds["steps"] is STEPS


def test_library_errors_name_the_option_of_the_command():
    run = _sub(build_parser(None), "run")
    cartesian = _sub(build_parser(None), "cartesian")
    view = _sub(build_parser(None), "view")
    assert with_flags("duration_s: inf must be ...", run) == "--duration: inf must be ..."
    assert with_flags("method: unknown method 'x'", run) == "--method: unknown method 'x'"
    assert with_flags("method: unknown method 'x'", cartesian) == "--methods: unknown method 'x'"
    assert with_flags("weights: bad", run) == "--weights: bad"  # a method's option
    assert with_flags("folders: 'x' has no run.json", view) == "RUN_DIR: 'x' has no run.json"
    assert with_flags("cannot write x: denied", run) == "cannot write x: denied"
    assert shorten(f"--only: {'y' * 500!r} unknown") == (
        f"--only: {'y' * 200!r}... (500 characters) unknown")


def _sub(parser, name):
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)
                ).choices[name]


def test_the_memory_budget_gives_the_estimate_and_the_maximum(monkeypatch):
    monkeypatch.setattr(budget, "available_memory_bytes", lambda: 8 * 2**30)
    budget.check_memory("rate_hz", 1000, "points", 4000)  # 4 MB: fine
    with pytest.raises(InputError) as caught:
        budget.check_memory("rate_hz", 36_000_001, "points", 4000)
    assert str(caught.value) == ("rate_hz: 36,000,001 points need about 134 GiB of memory; "
                                 "8 GiB are available here: at most 1,073,741 points")
