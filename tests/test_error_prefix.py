"""One error prefix on every command (issue 64): a refusal while parsing (argparse's) and
one after it (an :class:`~ikbench.core.errors.IkbenchError`) both start ``ikbench: error:``,
on every subcommand and on the nested ones (``experiment design``)."""

from __future__ import annotations

import pytest

from ikbench.cli import command_modules
from tests.conftest import one_line_error

COMMANDS = sorted(command_modules())


@pytest.mark.parametrize("command", COMMANDS)
def test_a_parsing_error_has_the_one_prefix_and_names_the_command_help(command, capsys):
    err = one_line_error(capsys, [command, "--no-such-option"])
    assert err.startswith("ikbench: error: "), err
    assert f"(see ikbench {command} --help)" in err, err


def test_a_nested_command_names_its_own_help(capsys):
    err = one_line_error(capsys, ["experiment", "design", "--no-such-option"])
    assert err.startswith("ikbench: error: "), err
    assert "(see ikbench experiment design --help)" in err, err


@pytest.mark.parametrize("argv", [["fk", "--robot", "no-such-robot"],
                                  ["ik", "--robot", "no-such-robot", "--count", "1"]])
def test_an_error_after_parsing_has_the_same_prefix(argv, capsys):
    err = one_line_error(capsys, argv)
    assert err.startswith("ikbench: error: "), err
    assert "no-such-robot" in err, err
