"""What libraries print on their own is kept off the console (ikbench.core.chatter)."""

from __future__ import annotations

import ctypes
import logging

import pytest

from ikbench.core import chatter


@pytest.fixture(autouse=True)
def fresh():
    chatter.forget()
    yield
    chatter.forget()
    chatter.set_verbose(False)


def _c_printf(text: str) -> None:
    """Print as a C library does: libc's buffered stdout, not Python's."""
    ctypes.CDLL(None).printf(text.encode())


def test_c_level_output_and_log_records_are_captured(capfd):
    with chatter.quiet("kdl", loggers=("somelib",)):
        _c_printf("The root link %%s has an inertia\n")
        logging.getLogger("somelib").warning("tag ignored on joint 1")
        logging.getLogger("somelib").warning("tag ignored on joint 2")
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    assert chatter.heard() == {"kdl": ["The root link %s has an inertia",
                                       "warning: tag ignored on joint 1",
                                       "warning: tag ignored on joint 2"]}
    assert chatter.summary() == ["note: kdl printed 3 line(s) of its own (--verbose shows it): "
                                 "The root link %s has an inertia (and 2 more)"]


def test_verbose_passes_the_text_on_to_stderr(capfd):
    chatter.set_verbose(True)
    with chatter.quiet("kdl"):
        _c_printf("chain built\n")
    out, err = capfd.readouterr()
    assert out == "" and err == "[kdl] chain built\n"
    assert chatter.summary()[0].startswith("note: kdl printed 1 line(s) of its own (shown above)")


def test_output_after_the_block_is_not_captured(capfd):
    with chatter.quiet("kdl"):
        pass
    print("table", flush=True)
    assert capfd.readouterr().out == "table\n" and chatter.summary() == []
