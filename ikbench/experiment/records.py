"""Trial lists read back, and the response log: appended and synced per trial, never rewritten.

A participant's play order is a pure function of the trial list and the responses so far
(:func:`next_trial`): blocks in order; within a block first the trials not yet shown, in the
list's order, then the trials whose every attempt timed out (the authors repeat a timed-out
trial at the end of its block), until each is answered or has had :data:`MAX_ATTEMPTS`. So an
interrupted run resumes where it stopped, loses no answer and repeats none.
"""

from __future__ import annotations

import csv
import datetime
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from ikbench.core.errors import InputError
from ikbench.experiment.design import TRIAL_COLUMNS, TRIALS_FILE

RESPONSES_FILE = "responses.csv"
#: The columns of responses.csv, in order.
RESPONSE_COLUMNS = ("participant", "trial", "attempt", "block", "practice", "condition",
                    "fraction", "cell", "target", "gaze_target", "answer_target", "touch_x_px",
                    "touch_y_px", "touch_error_px", "touch_error_mm", "reaction_s", "timed_out",
                    "backend", "simulated", "observer", "timestamp_utc")
BACKENDS = ("simulated", "emulator", "robot", "file", "stdin", "browser")
#: A trial whose attempts all time out is given up after this many.
MAX_ATTEMPTS = 3


def read_trials(folder: str | Path) -> pd.DataFrame:
    """A participant's trial list (``participant_XX/trials.csv``), checked.

    Raises:
        InputError: missing file or column, a malformed row (named by its line).
    """
    path = Path(folder) / TRIALS_FILE
    try:
        table = pd.read_csv(path, dtype={"participant": str})
    except FileNotFoundError:
        raise InputError(f"{path}: no trial list (ikbench experiment design writes it)") from None
    except (OSError, UnicodeDecodeError, pd.errors.ParserError) as exc:
        raise InputError(f"{path}: not a readable CSV: {exc}") from None
    missing = [c for c in TRIAL_COLUMNS if c not in table.columns]
    if missing:
        raise InputError(f"{path}: missing column(s) {', '.join(missing)}")
    for column in ("trial", "block", "target", "stop_step"):
        bad = pd.to_numeric(table[column], errors="coerce").isna()
        if bad.any():
            line = int(bad.idxmax()) + 2
            raise InputError(f"{path}, line {line}: {column} {table[column][bad.idxmax()]!r} "
                             "is not an integer")
    if table["trial"].duplicated().any():
        raise InputError(f"{path}: trial {int(table['trial'][table['trial'].duplicated()].iloc[0])}"
                         " appears twice")
    table["practice"] = table["practice"].astype(str).str.lower().eq("true")
    return table


@dataclass(frozen=True)
class Attempt:
    """The next thing to play: a trial row and its attempt number (1 = first showing)."""

    trial: Mapping
    attempt: int


def read_responses(folder: str | Path) -> pd.DataFrame:
    """The responses recorded so far (an empty table if none)."""
    path = Path(folder) / RESPONSES_FILE
    if not path.exists():
        return pd.DataFrame(columns=list(RESPONSE_COLUMNS))
    try:
        table = pd.read_csv(path, dtype={"participant": str, "observer": str})
    except (OSError, UnicodeDecodeError, pd.errors.ParserError) as exc:
        raise InputError(f"{path}: not a readable CSV: {exc}") from None
    if list(table.columns) != list(RESPONSE_COLUMNS):
        raise InputError(f"{path}: its columns are not responses.csv's "
                         f"({', '.join(RESPONSE_COLUMNS)})")
    table["timed_out"] = table["timed_out"].astype(str).str.lower().eq("true")
    return table


def next_trial(trials: pd.DataFrame, responses: pd.DataFrame) -> Attempt | None:
    """The next trial to play and its attempt number, or None when the list is done."""
    answered = set(responses.loc[~responses["timed_out"], "trial"].astype(int))
    attempts = responses.groupby("trial").size().to_dict() if len(responses) else {}
    last = (responses.reset_index().groupby("trial")["index"].max().to_dict()
            if len(responses) else {})
    for _, block in trials.groupby("block", sort=True):
        fresh = [r for _, r in block.iterrows() if int(r["trial"]) not in attempts]
        if fresh:
            return Attempt(fresh[0].to_dict(), 1)
        again = [r for _, r in block.iterrows() if int(r["trial"]) not in answered
                 and attempts.get(int(r["trial"]), 0) < MAX_ATTEMPTS]
        if again:
            row = min(again, key=lambda r: last[int(r["trial"])])
            return Attempt(row.to_dict(), attempts[int(row["trial"])] + 1)
    return None


def _cell(value: object) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    if isinstance(value, bool):
        return "True" if value else "False"
    if isinstance(value, float):
        return repr(round(value, 6))
    return str(value)


class ResponseLog:
    """The append-only responses.csv of one participant.

    Each :meth:`append` writes one line, flushes and fsyncs it before returning; a line that
    does not match the trial list (an unknown trial, an answer outside the goal set, a repeat
    of an answered trial) is refused and nothing is written.
    """

    def __init__(self, folder: str | Path, trials: pd.DataFrame, goal_ids: tuple[int, ...]):
        self.path = Path(folder) / RESPONSES_FILE
        self.trials = trials.set_index("trial", drop=False)
        self.goal_ids = tuple(int(g) for g in goal_ids)
        self.responses = read_responses(folder)

    def check(self, row: Mapping) -> None:
        """Refuse a response that does not fit the trial list (one line naming it)."""
        missing = [c for c in RESPONSE_COLUMNS if c not in row]
        if missing:
            raise InputError(f"a response lacks {', '.join(missing)}")
        trial = int(row["trial"])
        if trial not in self.trials.index:
            raise InputError(f"{self.path}: trial {trial} is not in the trial list "
                             f"(1-{len(self.trials)})")
        answered = self.responses.loc[~self.responses["timed_out"], "trial"].astype(int)
        if trial in set(answered):
            raise InputError(f"{self.path}: trial {trial} is answered already; a response is "
                             "never recorded twice")
        answer = row["answer_target"]
        if not row["timed_out"] and (answer is None or int(answer) not in self.goal_ids):
            raise InputError(f"{self.path}: answer {answer!r} of trial {trial} is not a target "
                             f"id ({', '.join(map(str, self.goal_ids))})")
        if row["backend"] not in BACKENDS:
            raise InputError(f"backend {row['backend']!r}: one of {', '.join(BACKENDS)}")

    def append(self, row: Mapping) -> None:
        """Check, append and sync one response."""
        self.check(row)
        new = not self.path.exists() or self.path.stat().st_size == 0
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with self.path.open("a", newline="", encoding="utf-8") as stream:
            writer = csv.writer(stream)
            if new:
                writer.writerow(RESPONSE_COLUMNS)
            writer.writerow([_cell(row[c]) for c in RESPONSE_COLUMNS])
            stream.flush()
            os.fsync(stream.fileno())
        frame = pd.DataFrame([{c: row[c] for c in RESPONSE_COLUMNS}])
        self.responses = frame if self.responses.empty else pd.concat(
            [self.responses, frame], ignore_index=True)


def now_utc() -> str:
    """The time now, ISO 8601 UTC, to the millisecond."""
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="milliseconds")


def participants(folder: str | Path) -> list[Path]:
    """The participant folders of a design folder, in order."""
    found = sorted(p for p in Path(folder).glob("participant_*") if p.is_dir())
    if not found:
        raise InputError(f"{folder}: no participant_XX folders (ikbench experiment design "
                         "writes them)")
    return found
