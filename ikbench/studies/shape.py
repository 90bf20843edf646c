"""One study shape: a :class:`Spec` that validates itself, ``run(spec) -> Result`` and
:meth:`Result.write`.

Every study follows it: the CLI command parses its arguments into the study's spec, calls
``spec.validate()`` (the one place the spec's values are checked; it raises
:class:`ikbench.core.errors.InputError` with the one-line message the command prints), runs
the study (``run(spec)``: measured in memory, nothing written) and writes the result
(``result.write(folder)``: returns the folder it wrote, e.g. ``folder/compare``), then prints.
The Python API does the same; the study's keyword function (``compare(...)``, ...) builds the
spec for you.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar, Protocol, TypeVar

from ikbench.core.io import write_study_files

if TYPE_CHECKING:
    import pandas as pd


class Spec(Protocol):
    """What a study is asked to do: a frozen dataclass of resolved values."""

    def validate(self) -> None:
        """Raise InputError (one line, the CLI's message) when a value is not acceptable."""


class Result(Protocol):
    """What a study measured, in memory."""

    def write(self, folder: Path) -> Path:
        """Write the study's files under ``folder``; return the folder written."""


@dataclass
class TimedResult(ABC):
    """A timing study's result: one summary row per case, every timed round, and the record.
    :meth:`write` writes ``<STEM>.csv``, ``<STEM>_runs.csv``, ``<STEM>.json`` and
    ``<STEM>.md`` (:meth:`markdown`)."""

    STEM: ClassVar[str]

    summary: pd.DataFrame
    runs: pd.DataFrame
    record: dict

    @abstractmethod
    def markdown(self) -> str:
        """``<STEM>.md``'s text."""

    def write(self, folder: str | Path) -> Path:
        """Write the four files into ``folder``; return ``<STEM>.csv``'s path."""
        return write_study_files(folder, self.STEM,
                                 {f"{self.STEM}.csv": (self.summary, "%.6g"),
                                  f"{self.STEM}_runs.csv": (self.runs, "%.6g")},
                                 self.record, self.markdown)


S = TypeVar("S", bound=Spec)
R = TypeVar("R", bound=Result)


def run_and_write(spec: S, run: Callable[[S], R], folder: Path | None) -> R:
    """``spec.validate()``, ``run(spec)``, then ``result.write(folder)`` unless ``folder`` is
    None: the shape every study's keyword function and CLI command follows."""
    spec.validate()
    result = run(spec)
    if folder is not None:
        result.write(folder)
    return result
