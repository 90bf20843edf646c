"""``ikbench experiment run DIR --online``: the study in a browser, the robot drawn from the
participant's seat.

The page (``pages/online.html``) asks for the participant id (or takes ``?participant=01``),
shows the consent text (``DIR/consent.txt``, else a placeholder that says to replace it),
instructions, then each trial: the motion (:mod:`ikbench.experiment.scene`, projected here and
drawn on a 2-D canvas there), then waits ``response_window_s`` for a click on the virtual
screen. Routes:

- ``GET /`` the participant page, ``GET /preview?condition=GP&target=3&fraction=0.6``
  (``&gaze_target=`` for I) a researcher's view of that stop frame, ``GET /pages/NAME`` the
  shipped scripts;
- ``GET /api/study`` the study's settings; ``GET /api/next?participant=01`` the next trial
  (:func:`ikbench.experiment.records.next_trial`) with its frames, or ``done``;
- ``POST /api/response`` ``{participant, trial, attempt, touch_x_px, touch_y_px, reaction_s,
  timed_out}``: recorded through :class:`ikbench.experiment.records.ResponseLog` (appended and
  synced) when it answers the participant's next trial; 409 when it does not (a stale tab, a
  repeat), 404 for an unknown participant or trial, 400 for a malformed one.

Data safety: the server keeps no state a crash could lose (the next trial is recomputed from
responses.csv under a lock per participant), the page keeps an unsent response and posts it
again until the server answers, and a 409 to a repeated post means it was recorded already.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ikbench.core.errors import InputError
from ikbench.experiment.play import response_row
from ikbench.experiment.records import ResponseLog, next_trial, participants, read_trials
from ikbench.experiment.study_view import StudyView
from ikbench.experiment.web import Reply, page

CONSENT_FILE = "consent.txt"
DEFAULT_CONSENT = (
    "PLACEHOLDER CONSENT TEXT - replace it before running this study with people: put the "
    "consent text your ethics board approved in consent.txt in the experiment folder (plain "
    "text; blank lines separate paragraphs). This placeholder is shown because that file is "
    "missing.")
INSTRUCTIONS = (
    "NICO will move its head and its arm toward one of the round targets on the screen in "
    "front of it and stop before it gets there. Click the target you think NICO is going "
    "for, as quickly and accurately as you can. You have {window:g} seconds after the "
    "robot stops; a trial with no click comes again later. The first {practice} trial(s) "
    "are practice.")


class Participant:
    """One participant's trial list and response log, behind a lock."""

    def __init__(self, folder: Path, goal_ids: tuple[int, ...]):
        self.folder = folder
        self.trials = read_trials(folder)
        self.log = ResponseLog(folder, self.trials, goal_ids)
        self.lock = threading.Lock()


class OnlineStudy:
    """The online study's app (see the module doc).

    Args:
        folder: the design folder.
        view: the folder loaded for drawing (its viewpoint).
        only: participant numbers the page may run (None: all).
    """

    def __init__(self, folder: Path, view: StudyView, only: tuple[int, ...] | None = None):
        self.folder, self.view = Path(folder), view
        self.participants: dict[str, Participant] = {}
        for path in participants(self.folder):
            number = int(path.name.split("_")[1])
            if only is None or number in only:
                self.participants[f"{number:02d}"] = Participant(path, view.goals.ids)
        consent = self.folder / CONSENT_FILE
        self.consent = (consent.read_text(encoding="utf-8") if consent.is_file()
                        else DEFAULT_CONSENT)
        self.consent_is_placeholder = not consent.is_file()

    # ----- routes -----------------------------------------------------------------------
    def handle(self, method: str, path: str, query: Mapping[str, str], body: Any) -> Reply:
        if method == "GET":
            if path in ("/", "/index.html"):
                return page("online.html")
            if path == "/preview":
                return page("preview.html")
            if path.startswith("/pages/"):
                return page(path[len("/pages/"):])
            if path == "/api/study":
                return Reply.json(self.study())
            if path == "/api/next":
                return self.next(query.get("participant", ""))
            if path == "/api/preview":
                return self.preview(query)
            return Reply.error(404, f"no page {path!r}")
        if method == "POST" and path == "/api/response":
            return self.respond(body)
        return Reply.error(404 if method == "GET" else 405, f"{method} {path}: not served")

    def study(self) -> dict:
        practice = sum(int(p.trials["practice"].sum()) for p in self.participants.values())
        practice //= max(len(self.participants), 1)
        return {"participants": sorted(self.participants), "consent": self.consent,
                "consent_is_placeholder": self.consent_is_placeholder,
                "instructions": INSTRUCTIONS.format(window=self.view.response_window_s,
                                                    practice=practice),
                "response_window_s": self.view.response_window_s,
                "screen_px": list(self.view.goals.screen.size_px)}

    def _participant(self, text: str) -> Participant | None:
        key = text.strip().zfill(2) if text.strip().isdigit() else text.strip()
        return self.participants.get(key)

    def next(self, participant: str) -> Reply:
        who = self._participant(participant)
        if who is None:
            return Reply.error(404, f"participant {participant!r} is not in this study "
                                    f"({', '.join(sorted(self.participants))})")
        with who.lock:
            responses = who.log.responses
            step = next_trial(who.trials, responses)
        total = len(who.trials)
        answered = int(responses.loc[~responses["timed_out"], "trial"].nunique()) \
            if len(responses) else 0
        started = len(responses) > 0
        if step is None:
            return Reply.json({"done": True, "answered": answered, "total": total,
                               "started": started})
        trial = step.trial
        last_block = int(responses["block"].iloc[-1]) if started else None
        main_blocks = sorted(int(b) for b in who.trials.loc[~who.trials["practice"], "block"]
                             .unique())
        block = int(trial["block"])
        payload = {"done": False, "participant": str(trial["participant"]).zfill(2),
                   "trial": int(trial["trial"]), "attempt": step.attempt,
                   "practice": bool(trial["practice"]), "block": block,
                   "block_number": main_blocks.index(block) + 1 if block in main_blocks else 0,
                   "blocks": len(main_blocks), "answered": answered, "total": total,
                   "started": started,
                   "break_before": last_block is not None and last_block != block,
                   "practice_over": (last_block is not None and last_block in
                                     set(who.trials.loc[who.trials["practice"], "block"])
                                     and not bool(trial["practice"])),
                   "response_window_s": self.view.response_window_s,
                   **self.view.frames(self.view.trial_motion(trial))}
        return Reply.json(payload)

    def respond(self, body: Any) -> Reply:
        if not isinstance(body, dict):
            return Reply.error(400, "give a JSON object")
        who = self._participant(str(body.get("participant", "")))
        if who is None:
            return Reply.error(404, f"participant {body.get('participant')!r} is not in this "
                                    "study")
        try:
            trial_id, attempt = int(body["trial"]), int(body["attempt"])
        except (KeyError, TypeError, ValueError):
            return Reply.error(400, "give trial and attempt as integers")
        if trial_id not in set(who.trials["trial"].astype(int)):
            return Reply.error(404, f"trial {trial_id} is not in participant "
                                    f"{who.folder.name}'s trial list")
        try:
            figures = self._figures(body)
        except InputError as exc:
            return Reply.error(400, str(exc))
        with who.lock:
            step = next_trial(who.trials, who.log.responses)
            if step is None or int(step.trial["trial"]) != trial_id or step.attempt != attempt:
                now = ("the list is done" if step is None else
                       f"the next is trial {int(step.trial['trial'])} attempt {step.attempt}")
                return Reply.error(409, f"trial {trial_id} attempt {attempt} is not this "
                                        f"participant's next ({now}); nothing recorded")
            row = response_row(step.trial, attempt, figures, self.view.goals, "browser", "")
            who.log.append(row)
        return Reply.json({"recorded": True, "trial": trial_id, "attempt": attempt,
                           "answer_target": row["answer_target"],
                           "timed_out": row["timed_out"]})

    def _figures(self, body: Mapping) -> dict:
        """The response figures of a posted body (answer_target: the target nearest to the
        touch on the screen)."""
        if bool(body.get("timed_out", False)):
            return {"answer_target": None, "touch_px": None, "reaction_s": None,
                    "timed_out": True}
        try:
            px = np.array([float(body["touch_x_px"]), float(body["touch_y_px"])])
            reaction = float(body["reaction_s"])
        except (KeyError, TypeError, ValueError):
            raise InputError("give touch_x_px, touch_y_px and reaction_s as numbers") from None
        size = np.asarray(self.view.goals.screen.size_px, float)
        if not np.all(np.isfinite(px)) or np.any(px < 0) or np.any(px > size):
            raise InputError(f"touch ({px[0]:g}, {px[1]:g}) px is off the screen "
                             f"(0-{size[0]:g} x 0-{size[1]:g})")
        window = self.view.response_window_s
        if not (math.isfinite(reaction) and 0 <= reaction <= window + 0.25):
            raise InputError(f"reaction_s {reaction:g}: outside the response window "
                             f"(0-{window:g} s); a late answer is a timeout")
        return nearest_answer(self.view, px, reaction)

    def preview(self, query: Mapping[str, str]) -> Reply:
        def number(key: str, kind: type = float) -> Any:
            text = query.get(key, "")
            if text == "":
                return None
            try:
                return kind(text)
            except ValueError:
                raise InputError(f"{key}={text!r} is not a number") from None

        trial = self.view.preview_trial(query.get("condition", "GP"), number("target", int) or
                                        self.view.goals.ids[0], number("fraction"),
                                        number("gaze_target", int))
        played = self.view.trial_motion(trial)
        payload = self.view.frames(played)
        payload["frames"] = payload["frames"][-1:]
        payload["times_s"] = payload["times_s"][-1:]
        payload["targets"] = {str(t): self.view.scene.screen_px_to_view(p).round(1).tolist()
                              for t, p in zip(self.view.goals.ids, self.view.goals.pixels)}
        fraction = trial["fraction"]
        payload["caption"] = {"condition": trial["condition"], "target": trial["target"],
                              "fraction": None if pd.isna(fraction) else fraction,
                              "gaze_target": trial["gaze_target"],
                              "head_motor_deg": [round(trial["head_z_motor_deg"], 2),
                                                 round(trial["head_y_motor_deg"], 2)],
                              "method": self.view.method,
                              "viewpoint_mm": self.view.viewpoint_mm.tolist()}
        return Reply.json(payload)


def nearest_answer(view: StudyView, touch_px: np.ndarray, reaction_s: float) -> dict:
    """Response figures of a touch [px]: the answered target is the one nearest to it on the
    screen (in mm)."""
    goals = view.goals
    index = int(goals.nearest(goals.screen.px_to_mm(touch_px)))
    return {"answer_target": int(goals.ids[index]), "touch_px": touch_px,
            "reaction_s": round(float(reaction_s), 3), "timed_out": False}
