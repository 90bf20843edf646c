"""The first call of a single-pose solver in a fresh process: import, set-up, first solve.

Steady-state times per call say nothing of what a user waits for before the first answer:
the library's import, building its model of the robot (and compiling: JAX for PyRoki,
numba's kernels for ours-lm, which load from numba's cache after the first run on a machine)
and the first solve. :func:`first_call` runs :func:`main` in a new Python process for one
method and one target and returns those three times [s]; ``ikbench ik`` measures it for every
method after its timed runs (so numba's cache is as the study left it: warm). ours-lm's
set-up is :func:`ikbench.solve_pose`'s (``prepare_first_call``: the first solve loads only
the kernel layout it needs), not the warm-up before its timed calls.
:func:`first_path_call` does the same for a path method (``ikbench cartesian``, ``ikbench
compare``): import, set-up on the robot (the method built with its settings, ``check_tasks``,
``prepare``) and the first task solved once through the study harness.
"""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
import tempfile
import time
from typing import Any

import numpy as np

#: The longest a first call may take before it is given up [s] (a compile from scratch is
#: minutes; beyond this the row says so).
FIRST_CALL_TIMEOUT_S = 600.0


def robot_spec(robot: Any) -> tuple[str, str]:
    """What loads ``robot`` again in another process: its config file, its package name
    (``example-robot-data:ur5``) or its URDF, and its end frame."""
    config = robot.config.config_path
    source = str(robot.config.source)
    if config:
        return str(config), robot.end_frame
    if ":" in source and not source.startswith("/"):
        return source, robot.end_frame
    return str(robot.urdf_path), robot.end_frame


def first_call(robot: Any, method: str, kind: str, tolerance: tuple[float, float],
               budget_s: float, T_target: np.ndarray, initials: np.ndarray,
               timeout_s: float = FIRST_CALL_TIMEOUT_S) -> dict[str, Any]:
    """``import_s``, ``setup_s``, ``solve_s`` and their sum ``first_call_s`` of ``method``
    solving one target (T_target (4, 4) [m]; ``initials`` (A, dof) [pose units]) in a fresh
    process; ``error`` instead when it fails or passes ``timeout_s``."""
    spec, end_frame = robot_spec(robot)
    job = {"robot": spec, "end_frame": end_frame, "method": method, "kind": kind,
           "tolerance": list(tolerance), "budget_s": budget_s,
           "T_target": np.asarray(T_target).tolist(), "initials": np.asarray(initials).tolist()}
    return _run_child([json.dumps(job)], timeout_s)


def first_path_call(robot: Any, method: str, settings: Any, task: Any,
                    timeout_s: float = FIRST_CALL_TIMEOUT_S) -> dict[str, Any]:
    """``import_s``, ``setup_s``, ``solve_s`` and their sum ``first_call_s`` of the path method
    ``method`` (with ``settings``, its Settings; None: its defaults) solving ``task`` once on
    ``robot`` in a fresh process; ``error`` instead when it fails or passes ``timeout_s``."""
    spec, end_frame = robot_spec(robot)
    job = {"robot": spec, "end_frame": end_frame, "method": method, "settings": settings,
           "task": task}
    handle, path = tempfile.mkstemp(suffix=".pickle", prefix="ikbench-first-call-")
    try:
        with os.fdopen(handle, "wb") as out:
            pickle.dump(job, out)
        return _run_child(["--path", path], timeout_s)
    finally:
        os.unlink(path)


#: The child's program: the clock starts before ``import ikbench`` (``python -m`` would import
#: the package, numpy among it, before :func:`main` could start it), and ``import_s`` holds
#: the package's import too.
CHILD = ("import sys, time; started = time.perf_counter(); "
         "from ikbench.studies.first_call import main; sys.exit(main(sys.argv[1:], started))")


def _run_child(args: list[str], timeout_s: float) -> dict[str, Any]:
    try:
        done = subprocess.run([sys.executable, "-c", CHILD, *args],
                              capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return {"error": f"no first answer within {timeout_s:g} s"}
    if done.returncode != 0 or not done.stdout.strip():
        lines = (done.stderr or "no output").strip().splitlines()
        return {"error": lines[-1] if lines else f"exit code {done.returncode}"}
    return json.loads(done.stdout.strip().splitlines()[-1])


def path_main(file: str, started: float | None = None) -> int:
    """In the fresh process, for a path method: time the import (the registry, the harness,
    the method's module), the set-up (the robot, the method, ``check_tasks``, ``prepare``)
    and the first solve of the task; print them as JSON."""
    with open(file, "rb") as source:
        data = source.read()  # unpickled (imports) within the clock
    started = time.perf_counter() if started is None else started
    from ikbench.core.robot import load_robot  # noqa: PLC0415 - what is timed
    from ikbench.methods.registry import get_method  # noqa: PLC0415 - what is timed
    from ikbench.runtime.harness import Progress, solve_tasks  # noqa: PLC0415

    job = pickle.loads(data)  # noqa: S301 - written by first_path_call just now
    cls = get_method(job["method"])
    imported = time.perf_counter()
    robot = load_robot(job["robot"], end_frame=job["end_frame"])
    method = cls(job["settings"])
    method.check_tasks(robot, [job["task"]])
    method.prepare(robot)
    ready = time.perf_counter()
    outcome = solve_tasks(method, robot, [job["task"]], Progress(job["method"], enabled=False))[0]
    solved = time.perf_counter()
    if not outcome.ok:
        print(f"first solve failed: {outcome.failure}", file=sys.stderr)
        return 1
    print(json.dumps({"import_s": imported - started, "setup_s": ready - imported,
                      "solve_s": solved - ready, "first_call_s": solved - started}))
    return 0


def main(argv: list[str], started: float | None = None) -> int:
    """In the fresh process: time the import of ikbench (from ``started``, the clock read
    before ``import ikbench`` by :data:`CHILD`; None: now), the registry and the method's
    module, the set-up (robot, solver, ``prepare``, or ``prepare_first_call`` where the solver
    has one: ours-lm's, which :func:`ikbench.solve_pose` runs, loads numba's kernels from its
    cache as the first solve needs them, compiled on a machine's first run) and the first
    solve; print them as JSON."""
    if argv[0] == "--path":
        return path_main(argv[1], started)
    job = json.loads(argv[0])
    started = time.perf_counter() if started is None else started
    from ikbench.core.robot import load_robot  # noqa: PLC0415 - what is timed
    from ikbench.methods.registry import solver_status  # noqa: PLC0415 - what is timed

    cls = solver_status()[job["method"]].cls
    imported = time.perf_counter()
    robot = load_robot(job["robot"], end_frame=job["end_frame"])
    solver = cls(robot, job["kind"], tuple(job["tolerance"]), job["budget_s"])
    # a solver with a cheaper first-use set-up (ours-lm: what ikbench.solve_pose runs) is
    # measured by it: the first answer a user waits for, not the timed table's warm-up
    getattr(solver, "prepare_first_call", solver.prepare)()
    ready = time.perf_counter()
    T = np.asarray(job["T_target"], dtype=float)
    initials = np.asarray(job["initials"], dtype=float)
    starts = initials if solver.pose_units else robot.to_urdf(initials)
    if solver.restarts_itself:
        solver.solve_within(np.ascontiguousarray(starts), T[:3, 3], T[:3, :3], job["budget_s"])
    else:
        solver.solve(np.ascontiguousarray(starts[0]), T[:3, 3], T[:3, :3])
    solved = time.perf_counter()
    print(json.dumps({"import_s": imported - started, "setup_s": ready - imported,
                      "solve_s": solved - ready, "first_call_s": solved - started}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
