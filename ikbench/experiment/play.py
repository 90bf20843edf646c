"""``ikbench experiment run``: play every participant's trial list and record the answers.

Back-ends, one record format (:data:`ikbench.experiment.records.RESPONSE_COLUMNS`):

- ``simulated``: model observers (:mod:`ikbench.experiment.observers`) answer at once;
- ``emulator`` / ``robot``: NICO's head and arm on the Dynamixel bus (:mod:`ikbench.hw`; the
  emulator is the bus emulator of ``ikbench emulate``): the head turns to its gaze angles
  (``gaze_lead_s``), the arm plays its trajectory forward to the trial's stop pose, holds while
  the answer comes (a responses file or the terminal), then returns along the same path while
  the head goes back to rest. The answer of a person comes from ``--answers FILE`` (CSV:
  participant, trial, answer_target, touch_x_px, touch_y_px, reaction_s; an empty answer is a
  timeout) or from the terminal.

Every response is appended and synced before the next trial starts
(:class:`ikbench.experiment.records.ResponseLog`), and the next trial is computed from what is
recorded (:func:`ikbench.experiment.records.next_trial`), so Ctrl-C loses nothing and a
second run resumes without repeating a trial.
"""

from __future__ import annotations

import contextlib
import math
import sys
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ikbench.core.errors import InputError
from ikbench.core.io import atomic_write_json
from ikbench.core.robot import Robot, load_robot
from ikbench.experiment import observers
from ikbench.experiment.design import DESIGN_FILE, read_design, read_trajectory, stop_of
from ikbench.experiment.head import Head, load_head, load_head_motors
from ikbench.experiment.layout import GoalSet, load_goals
from ikbench.experiment.records import ResponseLog, next_trial, now_utc, participants, read_trials

BACKENDS = ("simulated", "emulator", "robot")
#: Segments of a head turn and of the way back (each at least the plan's shortest segment).
HEAD_SEGMENTS = 10


@dataclass(frozen=True)
class PlaySpec:
    """What ``experiment run`` plays.

    Attributes:
        folder: the design folder.
        backend: one of :data:`BACKENDS`.
        model: the simulated participants' model (``simulated``).
        seed: the simulation's seed.
        port: the robot's serial port (``robot``).
        answers: a CSV of answers for the hardware back-ends (None: ask on the terminal).
        only: participant numbers to play (None: all).
        log: progress lines.
    """

    folder: Path
    backend: str = "simulated"
    model: observers.ObserverModel = field(default_factory=observers.ObserverModel)
    seed: int = 1
    port: str | None = None
    answers: Path | None = None
    only: tuple[int, ...] | None = None
    log: Callable[[str], object] = lambda line: print(line, file=sys.stderr)

    def validate(self) -> None:
        if self.backend not in BACKENDS:
            raise InputError(f"back-end {self.backend!r}: one of {', '.join(BACKENDS)}")
        read_design(self.folder)
        if self.backend == "simulated":
            self.model.validate()
        if self.backend == "robot" and not self.port:
            raise InputError("--robot-port: give the serial port of NICO's bus")
        if not 0 <= self.seed < 2**63:
            raise InputError(f"--seed {self.seed}: give an integer in [0, 2^63)")


@dataclass
class PlayResult:
    """Per participant: trials in the list, responses recorded now and before."""

    rows: list[dict]

    @property
    def table(self) -> pd.DataFrame:
        return pd.DataFrame(self.rows)


class Presenter:
    """Shows one trial and returns the response figures (answer_target, touch_px,
    reaction_s, timed_out)."""

    backend = "simulated"

    def present(self, trial: Mapping, attempt: int) -> dict:  # pragma: no cover - abstract
        raise NotImplementedError

    def close(self) -> None:
        """Release the bus (hardware back-ends)."""


class SimulatedPresenter(Presenter):
    """Model observers answer from the trial's cues."""

    backend = "simulated"

    def __init__(self, folder: Path, model: observers.ObserverModel, seed: int, robot: Robot,
                 head: Head, goals: GoalSet):
        self.folder, self.model, self.seed = folder, model, seed
        self.robot, self.head, self.goals = robot, head, goals
        self._poses: dict[str, np.ndarray] = {}
        self._cues: dict[tuple, dict[str, np.ndarray]] = {}

    def poses(self, relative: str) -> np.ndarray | None:
        if not isinstance(relative, str) or not relative:
            return None
        if relative not in self._poses:
            self._poses[relative] = read_trajectory(self.folder, relative, self.robot)
        return self._poses[relative]

    def present(self, trial: Mapping, attempt: int) -> dict:
        key = tuple(str(trial[c]) for c in ("condition", "fraction", "trajectory",
                                             "head_z_motor_deg", "head_y_motor_deg"))
        if key not in self._cues:      # a design has few distinct stimuli
            self._cues[key] = observers.cue_points(trial, self.robot, self.head, self.goals,
                                                   self.poses(trial["trajectory"]))
        return observers.answer(trial, self._cues[key], self.goals, self.model, self.seed,
                                attempt)


def bus_config():  # type: ignore[no-untyped-def]
    """The arm's and the head's motors in one :class:`ikbench.hw.MotorConfig` (arm joints
    first, then head_z, head_y)."""
    from ikbench.hw import MotorConfig, load_motor_config

    arm, head = load_motor_config(), load_head_motors()
    return MotorConfig(motors=(*arm.motors, *head.motors), baudrate=arm.baudrate,
                       source=f"{arm.source} + {head.source}")


class BusPresenter(Presenter):
    """Plays a trial on NICO's bus (a real port or the emulator) and takes the answer from
    ``answer`` (a file or the terminal)."""

    def __init__(self, folder: Path, port: str, backend: str, robot: Robot, head: Head,
                 answer: Callable[[Mapping, int], dict], log: Callable[[str], object]):
        self.folder, self.port, self.backend = folder, port, backend
        self.robot, self.head, self.answer, self.log = robot, head, answer, log
        self.config = bus_config()
        self.rest = np.asarray(head.rest_motor_deg, float)

    def _play(self, poses: np.ndarray, duration_s: float) -> None:
        from ikbench.hw import make_plan
        from ikbench.hw.executor import execute

        plan = make_plan(poses, self.config, duration_s=duration_s)
        execute(plan, self.port, log=lambda line: None)

    def present(self, trial: Mapping, attempt: int) -> dict:
        start_arm = np.asarray(load_goals().targets.start_pose, float)
        head_pose = np.array([trial["head_z_motor_deg"], trial["head_y_motor_deg"]], float)
        lead = max(float(trial["gaze_lead_s"]), 0.3)
        turn = np.linspace(0.0, 1.0, HEAD_SEGMENTS + 1)[:, None]
        self._play(np.hstack([np.repeat(start_arm[None], HEAD_SEGMENTS + 1, 0),
                              self.rest + turn * (head_pose - self.rest)]), lead)
        path = None
        if trial["condition"] != "G" and isinstance(trial["trajectory"], str):
            poses = read_trajectory(self.folder, trial["trajectory"], self.robot)
            stop, step, _ = stop_of(self.robot, poses, float(trial["fraction"]))
            path = np.vstack([poses[:step + 1], stop[None]])
            if len(path) >= 2:
                self._play(np.hstack([path, np.repeat(head_pose[None], len(path), 0)]),
                           max(float(trial["duration_s"]), 0.02 * (len(path) - 1)))
        response = self.answer(trial, attempt)
        back_arm = path[::-1] if path is not None else np.repeat(start_arm[None], 2, 0)
        back_head = head_pose + np.linspace(0.0, 1.0, len(back_arm))[:, None] * (
            self.rest - head_pose)
        self._play(np.hstack([back_arm, back_head]),
                   max(float(trial["duration_s"]), 0.02 * (len(back_arm) - 1), lead))
        return response


def file_answers(path: Path) -> Callable[[Mapping, int], dict]:
    """Answers from a CSV (participant, trial, answer_target, touch_x_px, touch_y_px,
    reaction_s), one row per attempt in order; an empty answer_target is a timeout."""
    try:
        table = pd.read_csv(path, dtype={"participant": str})
    except (OSError, UnicodeDecodeError, pd.errors.ParserError) as exc:
        raise InputError(f"--answers {path}: not a readable CSV: {exc}") from None
    need = ("participant", "trial", "answer_target", "touch_x_px", "touch_y_px", "reaction_s")
    missing = [c for c in need if c not in table.columns]
    if missing:
        raise InputError(f"--answers {path}: missing column(s) {', '.join(missing)}")
    table["participant"] = table["participant"].str.zfill(2)
    used: dict[tuple[str, int], int] = {}

    def answer(trial: Mapping, attempt: int) -> dict:
        key = (str(trial["participant"]), int(trial["trial"]))
        rows = table[(table["participant"] == key[0]) & (table["trial"] == key[1])]
        i = used.get(key, 0)
        if i >= len(rows):
            raise InputError(f"--answers {path}: no answer for participant {key[0]} trial "
                             f"{key[1]} (attempt {attempt})")
        used[key] = i + 1
        row = rows.iloc[i]
        if pd.isna(row["answer_target"]):
            return {"answer_target": None, "touch_px": None, "reaction_s": None,
                    "timed_out": True}
        return {"answer_target": int(row["answer_target"]),
                "touch_px": np.array([row["touch_x_px"], row["touch_y_px"]], float),
                "reaction_s": float(row["reaction_s"]), "timed_out": False}

    return answer


def terminal_answers(goals: GoalSet) -> Callable[[Mapping, int], dict]:
    """Answers typed on the terminal: a target id, or an empty line for a timeout."""
    import time

    def answer(trial: Mapping, attempt: int) -> dict:
        started = time.monotonic()
        text = input(f"trial {trial['trial']}: target touched ({', '.join(map(str, goals.ids))}"
                     ", empty = no answer)? ").strip()
        reaction = time.monotonic() - started
        if not text:
            return {"answer_target": None, "touch_px": None, "reaction_s": None,
                    "timed_out": True}
        target = int(text) if text.isdigit() else -1
        index = goals.index(target)
        return {"answer_target": target, "touch_px": goals.pixels[index],
                "reaction_s": round(reaction, 3), "timed_out": False}

    return answer


def response_row(trial: Mapping, attempt: int, figures: Mapping, goals: GoalSet,
                 backend: str, observer: str) -> dict:
    """The responses.csv row of one attempt."""
    timed_out = bool(figures["timed_out"])
    touch = figures["touch_px"]
    error_px = error_mm = None
    if not timed_out and touch is not None:
        true_px = np.array([trial["target_x_px"], trial["target_y_px"]], float)
        delta = np.asarray(touch, float) - true_px
        error_px = float(np.linalg.norm(delta))
        error_mm = float(np.linalg.norm(delta * goals.screen.mm_per_px))
    fraction = trial["fraction"]
    return {
        "participant": str(trial["participant"]).zfill(2), "trial": int(trial["trial"]),
        "attempt": attempt, "block": int(trial["block"]), "practice": bool(trial["practice"]),
        "condition": trial["condition"],
        "fraction": None if fraction is None or (isinstance(fraction, float)
                                                 and math.isnan(fraction)) else fraction,
        "cell": trial["cell"], "target": int(trial["target"]),
        "gaze_target": None if pd.isna(trial["gaze_target"]) else int(trial["gaze_target"]),
        "answer_target": figures["answer_target"],
        "touch_x_px": None if touch is None else round(float(touch[0]), 2),
        "touch_y_px": None if touch is None else round(float(touch[1]), 2),
        "touch_error_px": None if error_px is None else round(error_px, 3),
        "touch_error_mm": None if error_mm is None else round(error_mm, 3),
        "reaction_s": figures["reaction_s"], "timed_out": timed_out,
        "backend": backend, "simulated": backend == "simulated", "observer": observer,
        "timestamp_utc": now_utc(),
    }


def play_participant(folder: Path, presenter: Presenter, goals: GoalSet, observer: str,
                     log: Callable[[str], object]) -> dict:
    """Play one participant's remaining trials; returns counts."""
    trials = read_trials(folder)
    responses = ResponseLog(folder, trials, goals.ids)
    before = len(responses.responses)
    while (step := next_trial(trials, responses.responses)) is not None:
        figures = presenter.present(step.trial, step.attempt)
        responses.append(response_row(step.trial, step.attempt, figures, goals,
                                      presenter.backend, observer))
    recorded = len(responses.responses)
    log(f"{folder.name}: {len(trials)} trials, {recorded - before} responses recorded now, "
        f"{before} before")
    return {"participant": folder.name, "trials": len(trials), "recorded_now": recorded - before,
            "recorded_before": before}


def _presenter(spec: PlaySpec, robot: Robot, head: Head, goals: GoalSet,
               emulator_port: str | None) -> Presenter:
    if spec.backend == "simulated":
        return SimulatedPresenter(spec.folder, spec.model, spec.seed, robot, head, goals)
    answer = (file_answers(spec.answers) if spec.answers is not None
              else terminal_answers(goals))
    port = emulator_port if spec.backend == "emulator" else spec.port
    assert port is not None
    return BusPresenter(spec.folder, port, spec.backend, robot, head, answer, spec.log)


def run(spec: PlaySpec, emulator_port: str | None = None,
        presenter: Presenter | None = None) -> PlayResult:
    """Play every participant (or ``spec.only``); simulated runs record their model in
    design.json. ``presenter``: one made by the caller (the touchscreen page's), instead of
    the back-end's own."""
    spec.validate()
    record = read_design(spec.folder)
    robot, head = load_robot(), load_head()
    goals = load_goals()
    if [int(i) for i in record["goals"]["ids"]] != list(goals.ids):
        goals = _goals_of(record, robot)
    folders = participants(spec.folder)
    if spec.only is not None:
        known = {int(p.name.split("_")[1]) for p in folders}
        unknown = [i for i in spec.only if i not in known]
        if unknown:
            raise InputError(f"--participant {unknown[0]}: not in {spec.folder} "
                             f"({min(known)}-{max(known)})")
        folders = [p for p in folders if int(p.name.split("_")[1]) in spec.only]
    if spec.backend == "simulated":
        simulated = {**record, "simulated": True, "simulation": {
            **spec.model.record(), "seed": spec.seed,
            "viewpoint_mm": goals.viewpoint_mm.tolist()}}
        if record.get("simulation") not in (None, simulated["simulation"]):
            raise InputError(f"{spec.folder}: was simulated with other settings "
                             f"({record['simulation']['label']}, seed "
                             f"{record['simulation']['seed']}); give a fresh design folder")
        atomic_write_json(spec.folder / DESIGN_FILE, simulated)
    presenter = presenter or _presenter(spec, robot, head, goals, emulator_port)
    observer = spec.model.label() if spec.backend == "simulated" else ""
    rows = [play_participant(p, presenter, goals, observer, spec.log) for p in folders]
    presenter.close()
    return PlayResult(rows)


def _goals_of(record: Mapping, robot: Robot) -> GoalSet:
    """The goal set a design was made with (its targets file)."""
    return load_goals(record["goals"]["targets_file"], robot)


@contextlib.contextmanager
def emulated() -> Iterator[str]:
    """NICO's arm and head on the bus emulator, at the start pose with the head at rest;
    yields the port."""
    from ikbench.hw.emulator import Emulator

    config = bus_config()
    start = np.concatenate([np.asarray(load_goals().targets.start_pose, float),
                            np.asarray(load_head().rest_motor_deg, float)])
    with Emulator(config, start) as emulator:
        assert emulator.port is not None
        yield emulator.port
