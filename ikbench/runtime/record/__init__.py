"""A run folder and its ``run.json``: one record type, one writer, one reader.

- :class:`RunRecord` (:mod:`.run_record`): run.json, typed; its keys as every version wrote
  them (:data:`LAYOUTS`), read back from old files too;
- :class:`RunFolder` (:mod:`.folder`): the folder, written whole (:meth:`RunFolder.staged`
  yields a :class:`RunStage`) and read back (record, trajectories, tables);
- :class:`TrajectoryFile`: a trajectory CSV's text and the poses read back from it, so what a
  study judges in memory is what its files recompute to;
- the files' names (:mod:`.files`).
"""

from ikbench.runtime.record.files import (
    ANIMATION_FILE,
    RECORD_FILE,
    RUN_FIGURES,
    RUN_FILES,
    TRAJECTORY_FILE,
    trajectory_file,
)
from ikbench.runtime.record.folder import (
    RunFolder,
    RunStage,
    TrajectoryFile,
    files_written_by,
    keep_nothing,
)
from ikbench.runtime.record.run_record import (
    LAYOUTS,
    RunRecord,
    jsonable,
    obstacles_entry,
    robot_entry,
    robot_from_record,
)

__all__ = ["ANIMATION_FILE", "LAYOUTS", "RECORD_FILE", "RUN_FIGURES", "RUN_FILES",
           "TRAJECTORY_FILE", "RunFolder", "RunRecord", "RunStage", "TrajectoryFile",
           "files_written_by", "jsonable", "keep_nothing", "obstacles_entry", "robot_entry",
           "robot_from_record", "trajectory_file"]
