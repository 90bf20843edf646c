"""The names of a run folder's files.

Every study that writes a run folder (``ikbench run``, ``compare``'s per-method folders,
``cartesian``) names its files here and in its run.json's ``files``, so a later run into the
same folder knows which files the earlier one left (and removes only those:
:meth:`ikbench.runtime.record.RunFolder.files_written`).
"""

from __future__ import annotations

import re

#: The record of a run folder.
RECORD_FILE = "run.json"
#: A trajectory CSV that a run writes (``trajectory_<id>.csv``).
TRAJECTORY_FILE = re.compile(r"trajectory_(.+)\.csv")
#: The animation a run may write.
ANIMATION_FILE = "animation.gif"
#: The files every run folder holds besides its trajectories and figures.
RUN_FILES = ("table.csv", "details.csv", RECORD_FILE, "report.md")
#: Figures a run may write (older runs' too).
RUN_FIGURES = ("trajectories_3d.png", "pointing_error.png", "shapes.png", ANIMATION_FILE)


def trajectory_file(trajectory: str) -> str:
    """The file name of a trajectory: ``trajectory_<id>.csv``."""
    return f"trajectory_{trajectory}.csv"
