"""A run folder on disk: written whole through :meth:`RunFolder.staged`, read back by the
viewer, the reports and later runs.

Trajectories pass through one serialiser, :class:`TrajectoryFile`: the CSV's text and the poses
read back from that text, so a study that judges a trajectory in memory judges exactly what a
reader of the written file recomputes.
"""

from __future__ import annotations

import io
import json
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import pandas as pd

from ikbench.core.errors import InputError
from ikbench.core.io import atomic_savefig, atomic_write_csv, atomic_write_text, staged_folder
from ikbench.core.robot import Robot
from ikbench.core.trajectory import (
    read_trajectory_csv,
    read_trajectory_poses,
    trajectory_csv_text,
)
from ikbench.runtime.record.files import (
    RECORD_FILE,
    RUN_FIGURES,
    RUN_FILES,
    TRAJECTORY_FILE,
    trajectory_file,
)
from ikbench.runtime.record.run_record import RunRecord

if TYPE_CHECKING:
    from matplotlib.figure import Figure


@dataclass(frozen=True)
class TrajectoryFile:
    """A trajectory CSV before (or instead of) writing it.

    Attributes:
        name: trajectory id (``"1"``, ``"P"``).
        text: the CSV's text (:func:`ikbench.core.trajectory.trajectory_csv_text`).
        poses: (n+1, dof) poses [pose units] read back from ``text``: what a reader of the
            written file gets.
    """

    name: str
    text: str
    poses: np.ndarray

    @classmethod
    def of(cls, robot: Robot, name: str, poses: npt.ArrayLike, duration_s: float,
           quaternion: bool = False) -> TrajectoryFile:
        """Serialise ``poses`` (n+1, dof) [pose units] of trajectory ``name`` over
        ``duration_s`` [s] (``quaternion``: a pose path's end-frame orientation too) and read
        them back."""
        text = trajectory_csv_text(robot, poses, duration_s, quaternion)
        read = read_trajectory_poses(io.StringIO(text), robot, trajectory_file(name))
        return cls(name, text, read)

    @property
    def file(self) -> str:
        """Its file name, ``trajectory_<id>.csv``."""
        return trajectory_file(self.name)


class RunStage:
    """A run folder's new content while it is written (:meth:`RunFolder.staged`): each
    writer puts one file and remembers its name (:attr:`files`)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.files: list[str] = []

    def _add(self, name: str) -> Path:
        self.files.append(name)
        return self.path / name

    def trajectory(self, trajectory: TrajectoryFile, folder: str = "") -> str:
        """Write a trajectory's CSV (into the subfolder ``folder``); return its name."""
        name = f"{folder}/{trajectory.file}" if folder else trajectory.file
        atomic_write_text(self._add(name), trajectory.text)
        return name

    def csv(self, name: str, frame: pd.DataFrame, float_format: str = "%.10g") -> None:
        """Write a table (no index)."""
        atomic_write_csv(self._add(name), frame, float_format=float_format)

    def figure(self, name: str, figure: Figure) -> None:
        """Write a figure as PNG (and close it)."""
        atomic_savefig(self._add(name), figure)

    def text(self, name: str, text: str) -> None:
        """Write a text file (report.md, ...)."""
        atomic_write_text(self._add(name), text)

    def record(self, record: RunRecord) -> None:
        """Write run.json."""
        self.text(RECORD_FILE, record.to_json())


def keep_nothing(rel: Path) -> bool:
    """For :meth:`RunFolder.staged`: carry no file of the old folder over (a study's folder
    that is all its own, such as ``compare/``)."""
    return False


class RunFolder:
    """A run folder: ``run.json`` and the files it names (trajectory CSVs, tables, figures,
    report)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    @property
    def record_path(self) -> Path:
        """Its run.json."""
        return self.path / RECORD_FILE

    @property
    def has_record(self) -> bool:
        """Whether it holds a run.json."""
        return self.record_path.is_file()

    def read_record(self, who: str = "ikbench") -> RunRecord:
        """Its run.json.

        Raises:
            InputError: ``who: cannot read ...``: missing, unreadable or not a JSON object.
        """
        try:
            data = json.loads(self.record_path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise InputError(f"{who}: cannot read {self.record_path}: {exc}") from None
        if not isinstance(data, dict):
            raise InputError(f"{who}: {self.record_path} is not a JSON object")
        return RunRecord.from_dict(data)

    def files_written(self) -> set[str]:
        """The files (relative names) the run here wrote, from its run.json: the ``files``
        list, or for older runs the standard files and its trajectories' CSVs; none when the
        folder holds no readable run.json."""
        try:
            record = self.read_record()
        except InputError:
            return set()
        if record.files is not None:
            return {str(f) for f in record.files}
        return {*RUN_FILES, *RUN_FIGURES, *map(trajectory_file, record.trajectories or [])}

    def trajectory_path(self, trajectory: str) -> Path:
        """The CSV of a trajectory id."""
        return self.path / trajectory_file(trajectory)

    def has_trajectories(self) -> bool:
        """Whether it holds any trajectory CSV."""
        return any(TRAJECTORY_FILE.fullmatch(p.name) for p in self.path.glob("trajectory_*"))

    def read_trajectory(self, trajectory: str, robot: Robot) -> pd.DataFrame:
        """A trajectory's table (validated, :func:`ikbench.core.trajectory.read_trajectory_csv`)."""
        return read_trajectory_csv(self.trajectory_path(trajectory), robot)

    def read_poses(self, trajectory: str, robot: Robot) -> np.ndarray:
        """A trajectory's (n+1, dof) poses [pose units]."""
        return read_trajectory_poses(self.trajectory_path(trajectory), robot)

    def read_table(self, name: str = "table.csv") -> pd.DataFrame:
        """A table of the folder (``table.csv``, ``details.csv``), trajectory ids as text."""
        return pd.read_csv(self.path / name, dtype={"trajectory": str})

    @contextmanager
    def staged(self, keep: Callable[[Path], bool] | None = None) -> Iterator[RunStage]:
        """Write the folder whole or not at all (:func:`ikbench.core.io.staged_folder`).

        Args:
            keep: ``keep(relative_path)`` for files of the old folder to carry over; default:
                those the earlier run did not write (:meth:`files_written`: a user's notes,
                ``ikbench plan``'s files).
        """
        if keep is None:
            previous = self.files_written()

            def keep(rel: Path) -> bool:
                return str(rel) not in previous

        with staged_folder(self.path, keep=keep) as tmp:
            yield RunStage(tmp)


def files_written_by(folder: str | Path) -> set[str]:
    """:meth:`RunFolder.files_written` of ``folder``."""
    return RunFolder(folder).files_written()
