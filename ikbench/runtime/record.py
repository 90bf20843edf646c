"""A run folder's record: the files a run writes and its ``run.json``.

Every study that writes a run folder (``ikbench run``, ``compare``'s per-method folders,
``cartesian``) names its files here, so a later run into the same folder knows which files
the earlier one left (and removes only those).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

#: A trajectory CSV that a run writes (``trajectory_<id>.csv``).
TRAJECTORY_FILE = re.compile(r"trajectory_(.+)\.csv")
#: The animation a run may write.
ANIMATION_FILE = "animation.gif"
#: The files every run folder holds besides its trajectories and figures.
RUN_FILES = ("table.csv", "details.csv", "run.json", "report.md")
#: Figures a run may write (older runs' too).
RUN_FIGURES = ("trajectories_3d.png", "pointing_error.png", "shapes.png", ANIMATION_FILE)


def files_written_by(folder: Path) -> set[str]:
    """The files (relative names) the run in ``folder`` wrote, from its run.json: the
    ``files`` list, or for older runs the standard files and its trajectories' CSVs."""
    try:
        record = json.loads((Path(folder) / "run.json").read_text())
    except (OSError, ValueError):
        return set()
    if not isinstance(record, dict):
        return set()
    if isinstance(record.get("files"), list):
        return {str(f) for f in record["files"]}
    ids = record.get("trajectories") or []
    return {*RUN_FILES, *RUN_FIGURES, *(f"trajectory_{i}.csv" for i in ids)}
