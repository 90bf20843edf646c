"""Saving a design: its targets file (or problem file) and the run folder ``ikbench run`` writes.

The design is written as the input ``ikbench run`` takes, and the run folder is then written
by ``ikbench run``'s own function (:func:`ikbench.studies.run.run`) on that file: the same
tasks, the same solve through the study harness, the same tables, run.json, figures and
report. So the folder is exactly what the printed command (:attr:`Saved.command`) writes, and
goes on into ``ikbench plan``, ``export`` and ``execute``.

- lines and letters: ``OUTPUT/NAME.targets.json`` (:func:`targets_document`: the start pose,
  the touch pose under the trajectory's id, n, the obstacles), then
  ``ikbench run --targets OUTPUT/NAME.targets.json`` (letters with ``--shape letter:X --size``);
- 6-D pose paths: ``OUTPUT/NAME.yaml`` (the problem file with ``path_name: NAME``) and
  ``OUTPUT/NAME.csv`` (the moved path, CppFlow's ``time,x,y,z,qw,qx,qy,qz`` [m]), then
  ``ikbench run --problem OUTPUT/NAME.yaml``.
"""

from __future__ import annotations

import json
import shlex
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ikbench.core.io import atomic_write_text, check_folder_writable
from ikbench.core.obstacles import named_sets
from ikbench.core.problems import CartesianProblem
from ikbench.core.robot import Robot
from ikbench.core.targets import Targets
from ikbench.methods.base import Method
from ikbench.runtime.record import robot_entry
from ikbench.studies.run import check_name, run


@dataclass(frozen=True)
class Saved:
    """What :meth:`ikbench.viewer.design.designer.Designer.save` wrote.

    Attributes:
        files: the design's input files (the targets file; or the problem YAML and its CSV).
        folder: the run folder (``OUTPUT/NAME/``).
        table: the run's table (as ``ikbench run`` prints it).
        command: the ``ikbench run`` command line that writes the same folder.
        change_deg: the largest difference between the saved trajectory and the one shown
            before saving [pose units] (the saved one is solved from scratch, as
            ``ikbench run`` solves it; the designer's was warm-started).
    """

    files: tuple[Path, ...]
    folder: Path
    table: pd.DataFrame
    command: str
    change_deg: float = 0.0


def targets_document(robot: Robot, targets: Targets, description: str) -> dict[str, Any]:
    """A targets file's content (:mod:`ikbench.core.targets`) with every pose of ``targets``
    (floats written exactly: they read back bit-identical) and its obstacles (by their named
    set's name when they come from one, else as a list)."""
    doc: dict[str, Any] = {
        "joint_names": list(robot.joint_names),
        "start_pose": [float(v) for v in targets.start_pose],
        "targets": {key: [float(v) for v in pose]
                    for key, pose in targets.touch_poses.items()},
        "steps": int(targets.steps), "description": description}
    if targets.obstacles:
        source = targets.obstacles_source
        doc["obstacles"] = (source if source in named_sets(robot) else
                            [o.to_dict() for o in targets.obstacles])
    return doc


def problem_document(problem: CartesianProblem, path_name: str) -> dict[str, Any]:
    """The problem file's YAML content with ``path_name`` replaced."""
    import yaml

    doc = yaml.safe_load(Path(problem.source).read_text(encoding="utf-8"))
    return {**doc, "path_name": path_name}


def path_csv(path_m: np.ndarray, quat_wxyz: np.ndarray) -> str:
    """A path CSV in CppFlow's format: ``time,x,y,z,qw,qx,qy,qz`` (time: the index)."""
    rows = ["time,x,y,z,qw,qx,qy,qz"]
    for k, (p, q) in enumerate(zip(path_m, quat_wxyz)):
        rows.append(",".join([str(k), *(repr(float(v)) for v in (*p, *q))]))
    return "\n".join(rows) + "\n"


def write_inputs(output: Path, name: str, robot: Robot, targets: Targets | None = None,
                 problem: CartesianProblem | None = None, path_m: np.ndarray | None = None,
                 description: str = "") -> tuple[Path, ...]:
    """Write the design's input files under ``output`` (see the module doc)."""
    import yaml

    output.mkdir(parents=True, exist_ok=True)
    if problem is not None:
        assert path_m is not None
        yaml_file, csv_file = output / f"{name}.yaml", output / f"{name}.csv"
        atomic_write_text(csv_file, path_csv(path_m, problem.path_quat_wxyz))
        atomic_write_text(yaml_file, yaml.safe_dump(problem_document(problem, name),
                                                    sort_keys=False))
        return yaml_file, csv_file
    assert targets is not None
    file = output / f"{name}.targets.json"
    atomic_write_text(file, json.dumps(targets_document(robot, targets, description),
                                       indent=2) + "\n")
    return (file,)


def run_arguments(robot: Robot, files: tuple[Path, ...], shape: str, steps: int | None,
                  size_mm: float | None) -> dict[str, Any]:
    """:func:`ikbench.studies.run.run`'s task arguments for the saved input files."""
    if files[0].suffix == ".yaml":
        return {"problem": files[0]}
    return {"robot": robot, "targets": files[0], "steps": steps, "shape": shape,
            "size_mm": size_mm}


def command_line(method: Method, robot: Robot, arguments: dict[str, Any], output: Path,
                 name: str, duration_s: float, timing: str) -> str:
    """The ``ikbench run`` command that writes the same run folder."""
    words = ["ikbench", "run", "--method", method.name]
    if "problem" in arguments:
        words += ["--problem", str(arguments["problem"])]
    else:
        spec = robot_entry(robot)["spec"]
        words += ["--robot", spec]
        if str(spec).endswith(".urdf"):
            words += ["--end-frame", robot.end_frame]
        words += ["--targets", str(arguments["targets"]), "--steps", str(arguments["steps"])]
        if arguments["shape"] != "line":
            words += ["--shape", arguments["shape"], "--size", f"{arguments['size_mm']:g}"]
    words += ["--duration", f"{duration_s:g}", "--timing", timing, "--output", str(output),
              "--name", name]
    return shlex.join(words)


def save_run(method: Method, arguments: dict[str, Any], output: Path, name: str,
             duration_s: float, timing: str) -> pd.DataFrame:
    """``ikbench run``'s function on the saved input files: writes ``output/name/``."""
    return run(method, output=output, name=name, duration_s=duration_s, timing=timing,
               progress=False, **arguments)


def check_output(output: Path, name: str) -> Path:
    """The run folder ``output/name``, checked before anything is written."""
    check_name(name)
    check_folder_writable(output / name)
    return output / name
