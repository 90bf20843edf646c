"""The pointing study in the browser (issue 60): the online page driven by headless Chromium
through a short study, with the server killed and restarted in the middle; the touchscreen
page answering trials played on the bus emulator; the server's refusals over HTTP; the
stimulus export.

The study: three of NICO's targets (1, 2, 3), conditions G and GP60, one practice trial, one
repeat (1 practice + 2 blocks of 3), the arm's motion 1.4 s over the whole path. Chromium tests
are skipped when no Chromium is installed (Debian: apt-get install -y chromium).
"""

from __future__ import annotations

import json
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ikbench.experiment.design import DesignSpec, build
from ikbench.experiment.layout import load_goals
from ikbench.experiment.records import RESPONSE_COLUMNS, read_responses, read_trials
from ikbench.viewer.browser import HeadlessPage, find_chromium

REPO = Path(__file__).resolve().parents[1]
needs_chromium = pytest.mark.skipif(find_chromium() is None, reason="no Chromium installed "
                                    "(Debian: apt-get install -y chromium)")


@pytest.fixture(scope="module")
def design(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("browser")
    spec = json.loads((REPO / "urdf" / "nico_right_arm.targets.json").read_text())
    spec["targets"] = {k: v for k, v in spec["targets"].items() if k in ("1", "2", "3")}
    targets = root / "three.targets.json"
    targets.write_text(json.dumps(spec))
    folder = root / "study"
    build(DesignSpec(participants=1, seed=2, conditions=("G", "GP"), fractions=(0.6,),
                     repeats=1, practice=1, goals=load_goals(targets), duration_s=1.4,
                     gaze_lead_s=0.3)).write(folder)
    return folder


def _copy(folder: Path, tmp_path: Path) -> Path:
    out = tmp_path / "study"
    shutil.copytree(folder, out)
    return out


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _wait(predicate, timeout_s: float = 60.0, what: str = "the page"):  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout_s
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


def _post(url: str, body: dict) -> tuple[int, dict]:
    request = urllib.request.Request(url, json.dumps(body).encode(),
                                     {"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(request, timeout=30) as reply:
            return reply.status, json.loads(reply.read())
    except urllib.error.HTTPError as exc:
        return exc.code, json.loads(exc.read())


def _get(url: str) -> tuple[int, dict]:
    try:
        with urllib.request.urlopen(url, timeout=30) as reply:
            return reply.status, json.loads(reply.read())
    except urllib.error.HTTPError as exc:
        return exc.code, json.loads(exc.read())


def _client_of(page: HeadlessPage, px: np.ndarray) -> tuple[int, int, np.ndarray]:
    """The integer client point over screen pixel ``px`` on the online page's canvas, and the
    screen pixel under that point (computed here from the trial's homography)."""
    t = page.evaluate("(() => { const r = document.getElementById('view')"
                      ".getBoundingClientRect(); return {h: study.current.homography, "
                      "view: study.current.view, r: [r.left, r.top, r.width, r.height]}; })()")
    h, (w, hh), (left, top, width, height) = np.array(t["h"]), t["view"], t["r"]
    v = h @ [px[0], px[1], 1.0]
    cx = round(left + v[0] / v[2] * width / w)
    cy = round(top + v[1] / v[2] * height / hh)
    back = np.linalg.inv(h) @ [(cx - left) * w / width, (cy - top) * hh / height, 1.0]
    return cx, cy, back[:2] / back[2]


def _click(page: HeadlessPage, x: float, y: float) -> None:
    for kind in ("mousePressed", "mouseReleased"):
        page.call("Input.dispatchMouseEvent", type=kind, x=x, y=y, button="left",
                  buttons=1 if kind == "mousePressed" else 0, clickCount=1)


class Server:
    """``ikbench experiment run DIR --online`` in a subprocess."""

    def __init__(self, folder: Path, port: int):
        self.folder, self.port, self.proc = folder, port, None

    def start(self) -> Server:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "ikbench", "experiment", "run", str(self.folder), "--online",
             "--port", str(self.port), "--no-browser"], stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True, cwd=REPO)
        line = self.proc.stdout.readline()
        assert line.startswith("serving http://127.0.0.1:"), (line, self.proc.stderr.read())
        return self

    def kill(self) -> None:
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(timeout=10)

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.kill()


@needs_chromium
def test_chromium_runs_a_short_study_with_a_crash_in_the_middle(design, tmp_path):
    """Practice + 2 blocks, scripted clicks (one trial left to time out, repeated at the end
    of its block); after the 3rd response the server is killed (SIGKILL), the page's next
    click is made while it is down and kept, the server restarts and gets it; later the page
    reloads. responses.csv equals the script, no trial twice; read_study reads the folder."""
    from ikbench.experiment.analysis import read_study

    folder = _copy(design, tmp_path)
    trials = read_trials(folder / "participant_01").set_index("trial")
    goals = load_goals(json.loads((folder / "design.json").read_text())["goals"]["targets_file"])
    port = _free_port()
    server = Server(folder, port).start()
    script: list[dict] = []
    handled: set[tuple[int, int]] = set()
    timeout_trial: int | None = None
    crashed = reloaded = False
    try:
        with HeadlessPage(f"http://127.0.0.1:{port}/?participant=01", width=1280,
                          height=800) as page:
            page.wait_for_text("Consent")
            assert "PLACEHOLDER CONSENT TEXT" in page.evaluate("document.body.innerText")
            page.evaluate("document.getElementById('consent-yes').click()")
            deadline = time.monotonic() + 150
            while time.monotonic() < deadline:
                state = page.evaluate("({phase: study.phase, trial: study.trial, "
                                      "attempt: study.attempt})")
                if state["phase"] == "done":
                    break
                if state["phase"] == "message":
                    page.evaluate("document.getElementById('message-go').click()")
                    time.sleep(0.1)
                    continue
                key = (state["trial"], state["attempt"])
                if state["phase"] != "awaiting" or key in handled:
                    time.sleep(0.03)
                    continue
                handled.add(key)
                trial = trials.loc[state["trial"]]
                if timeout_trial is None and not trial["practice"]:
                    timeout_trial = state["trial"]                  # let this one time out
                    script.append({"trial": key[0], "attempt": key[1], "answer": None})
                    continue
                ids = list(goals.ids)
                answer = ids[(ids.index(int(trial["target"])) + len(script)) % len(ids)]
                px = goals.pixels[goals.index(answer)] + [7.0, -5.0]
                cx, cy, expected = _client_of(page, px)
                if len(script) == 3 and not crashed:
                    server.kill()                                   # the server dies ...
                    crashed = True
                    _click(page, cx, cy)                            # ... a click meanwhile
                    _wait(lambda: page.evaluate("study.offline === true"), 20, "offline")
                    server = Server(folder, port).start()           # ... and it is back
                else:
                    _click(page, cx, cy)
                script.append({"trial": key[0], "attempt": key[1], "answer": answer,
                               "px": expected})
                if len(script) == 5 and not reloaded:
                    _wait(lambda: len(read_responses(folder / "participant_01")) >= 5, 20,
                          "the 5th response")
                    page.call("Page.reload")
                    reloaded = True
                    page.wait_for_text("Welcome back")
            assert page.evaluate("study.phase") == "done", "the page did not finish the study"
    finally:
        server.stop()

    responses = read_responses(folder / "participant_01")
    assert list(responses.columns) == list(RESPONSE_COLUMNS)
    assert crashed and reloaded and timeout_trial is not None
    assert len(responses) == len(script) == len(trials) + 1        # + the timed-out attempt
    for row, want in zip(responses.to_dict("records"), script):
        assert (row["trial"], row["attempt"]) == (want["trial"], want["attempt"])
        if want["answer"] is None:
            assert row["timed_out"] and pd.isna(row["answer_target"])
        else:
            assert not row["timed_out"] and int(row["answer_target"]) == want["answer"]
            assert abs(row["touch_x_px"] - want["px"][0]) <= 1.0
            assert abs(row["touch_y_px"] - want["px"][1]) <= 1.0
            assert 0 <= row["reaction_s"] <= 2.0
    assert (responses["backend"] == "browser").all() and not responses["simulated"].any()
    answered = responses[~responses["timed_out"]]
    assert not answered["trial"].duplicated().any()                 # none twice
    assert set(answered["trial"]) == set(trials.index)              # none lost
    retry = responses[responses["trial"] == timeout_trial]
    assert list(retry["attempt"]) == [1, 2]                         # repeated at block end
    block = trials.loc[timeout_trial, "block"]
    assert responses[responses["block"] == block]["trial"].iloc[-1] == timeout_trial
    study = read_study(folder)
    assert study is not None


def _online(folder: Path):  # type: ignore[no-untyped-def]
    from ikbench.experiment.online import OnlineStudy
    from ikbench.experiment.study_view import StudyView
    from ikbench.experiment.web import StudyServer

    return StudyServer(OnlineStudy(folder, StudyView(folder)))


def test_the_server_refuses_what_does_not_match_and_writes_nothing(design, tmp_path):
    """Unknown participant or trial -> 404, malformed -> 400, a stale second tab -> 409:
    nothing written by any of them; a second server on the folder is refused."""
    from ikbench.core.errors import InputError
    from ikbench.experiment.web import FolderLock

    folder = _copy(design, tmp_path)
    path = folder / "participant_01" / "responses.csv"
    with _online(folder) as server:
        assert server.host == "127.0.0.1"
        url = server.url
        status, tab_a = _get(url + "api/next?participant=01")
        _, tab_b = _get(url + "api/next?participant=1")
        assert status == 200 and tab_a["trial"] == tab_b["trial"] == 1
        answer = {"participant": "01", "trial": 1, "attempt": 1, "touch_x_px": 1200.0,
                  "touch_y_px": 841.0, "reaction_s": 0.8}
        for body, code in (({**answer, "trial": 999}, 404), ({**answer, "participant": "07"}, 404),
                           ({**answer, "touch_x_px": "left"}, 400),
                           ({**answer, "touch_x_px": 5000.0}, 400),
                           ({**answer, "reaction_s": 9.0}, 400), ({**answer, "trial": 2}, 409),
                           ({**answer, "attempt": 2}, 409)):
            assert _post(url + "api/response", body)[0] == code, body
        assert not path.exists()                                    # nothing written
        assert _get(url + "api/next?participant=42")[0] == 404
        assert _post(url + "api/response", answer) == (200, {
            "recorded": True, "trial": 1, "attempt": 1, "answer_target": 1,
            "timed_out": False})
        status, reply = _post(url + "api/response", answer)          # tab B, stale
        assert status == 409 and "nothing recorded" in reply["error"]
        assert _get(url + "api/next?participant=01")[1]["trial"] == 2
        status, preview = _get(url + "api/preview?condition=I&target=3&fraction=0.6")
        assert status == 200 and preview["caption"]["gaze_target"] in (1, 2)
        assert _get(url + "api/preview?condition=X&target=3")[0] == 400
        assert _get(url + "api/preview?condition=GP&target=9&fraction=0.6")[0] == 400
        assert _get(url + "pages/../web.py")[0] == 404
    assert len(read_responses(folder / "participant_01")) == 1
    with FolderLock(folder):
        result = subprocess.run([sys.executable, "-m", "ikbench", "experiment", "run",
                                 str(folder), "--online", "--port", "0", "--no-browser"],
                                capture_output=True, text=True, timeout=60, cwd=REPO)
        assert result.returncode == 2 and "another ikbench experiment run" in result.stderr
        with pytest.raises(InputError):
            FolderLock(folder).acquire()


def test_the_page_ships_every_file_it_loads_and_nothing_from_elsewhere():
    pages = REPO / "ikbench" / "experiment" / "pages"
    for page in pages.iterdir():
        text = page.read_text()
        assert "http://" not in text.replace("http://www.w3.org/2000/svg", "")
        assert "https://" not in text and "//cdn" not in text
    toml = (REPO / "pyproject.toml").read_text()
    assert '"ikbench.experiment" = ["pages/*"]' in toml


@needs_chromium
def test_the_touchscreen_page_answers_trials_on_the_emulator(design, tmp_path):
    """The touchscreen page in Chromium, the trials played on the bus emulator: the
    instructions and the break go on by a touch, each scripted touch ends its trial with its
    pixel and target, and the arm returns (the emulator's present_deg and sync_writes)."""
    from ikbench.core.robot import load_robot
    from ikbench.experiment.head import load_head
    from ikbench.experiment.play import BusPresenter, PlaySpec, bus_config, run
    from ikbench.experiment.study_view import design_goals
    from ikbench.experiment.touchscreen import (
        TouchscreenApp,
        TouchscreenPresenter,
        browser_answers,
    )
    from ikbench.experiment.web import StudyServer
    from ikbench.hw.emulator import Emulator

    folder = _copy(design, tmp_path)
    record = json.loads((folder / "design.json").read_text())
    goals = design_goals(record)
    robot, head = load_robot(), load_head()
    app = TouchscreenApp(goals, record["response_window_s"])
    start = np.concatenate([goals.targets.start_pose, head.rest_motor_deg])
    at_touch: dict[int, np.ndarray] = {}
    script: list[tuple[int, int, np.ndarray]] = []
    with StudyServer(app) as server, Emulator(bus_config(), start) as emulator:
        answers = browser_answers(app)

        def answer(trial, attempt):  # type: ignore[no-untyped-def]
            at_touch[int(trial["trial"])] = emulator.present_deg()
            return answers(trial, attempt)

        presenter = TouchscreenPresenter(
            BusPresenter(folder, emulator.port, "emulator", robot, head, answer,
                         lambda line: None), app)
        spec = PlaySpec(folder, backend="emulator", log=lambda line: None)
        done = threading.Event()
        thread = threading.Thread(target=lambda: (run(spec, emulator.port, presenter),
                                                  done.set()), daemon=True)
        thread.start()
        width, height = 1200, 675                  # half the screen's 2400 x 1350 px
        with HeadlessPage(server.url, width=width, height=height) as page:
            page.wait_for_text("Participant 01")
            seen = set()
            while not done.is_set():
                state = page.evaluate("touch.state")
                if state["phase"] in ("instructions", "break"):
                    page.evaluate("document.getElementById('go').click()")
                    _wait(lambda: page.evaluate("touch.state.phase") not in
                          ("instructions", "break"), 10, "the page to go on")
                elif state["phase"] == "awaiting" and state["trial"] not in seen:
                    seen.add(state["trial"])
                    target = goals.ids[len(script) % len(goals.ids)]
                    px = goals.pixels[goals.index(target)]
                    cx, cy = round(px[0] / 2), round(px[1] / 2)
                    _click(page, cx, cy)
                    script.append((state["trial"], target, np.array([cx, cy]) * 2.0))
                time.sleep(0.03)
            thread.join(timeout=30)
        final = emulator.present_deg()
        writes = emulator.sync_writes()
    responses = read_responses(folder / "participant_01")
    trials = read_trials(folder / "participant_01").set_index("trial")
    assert len(responses) == len(trials) == len(script)
    for row, (trial, target, px) in zip(responses.to_dict("records"), script):
        assert row["trial"] == trial and int(row["answer_target"]) == target
        assert abs(row["touch_x_px"] - px[0]) <= 1.0 and abs(row["touch_y_px"] - px[1]) <= 1.0
        assert row["backend"] == "emulator" and not row["timed_out"]
    moved = [t for t in at_touch if trials.loc[t, "condition"] == "GP"]
    assert moved, "no pointing trial"
    for t in moved:                                # the arm was away from the start ...
        assert np.abs(at_touch[t][:7] - start[:7]).max() > 10.0
    assert np.abs(final - start).max() < 0.2       # ... and came back
    assert len(writes) > 20 * len(moved)


def test_stimuli_writes_every_distinct_stimulus_with_its_manifest(design, tmp_path):
    from PIL import Image

    out = tmp_path / "stimuli"
    result = subprocess.run([sys.executable, "-m", "ikbench", "experiment", "stimuli",
                             str(design), "--hold", "0.2", "--output", str(out)],
                            capture_output=True, text=True, timeout=300, cwd=REPO)
    assert result.returncode == 0, result.stderr
    manifest = pd.read_csv(out / "manifest.csv")
    assert list(manifest.columns) == ["file", "condition", "fraction", "target", "gaze_target",
                                      "method", "frames", "duration_s", "viewpoint_mm"]
    trials = read_trials(design / "participant_01")
    distinct = trials[["condition", "fraction", "target", "gaze_target"]].drop_duplicates()
    assert len(manifest) == len(distinct)
    for row in manifest.to_dict("records"):
        with Image.open(out / row["file"]) as gif:       # Pillow merges repeated frames
            assert gif.size == (1200, 800) and 2 <= gif.n_frames <= row["frames"]
            shown_ms = 0
            for k in range(gif.n_frames):
                gif.seek(k)
                shown_ms += gif.info["duration"]
        assert abs(shown_ms - row["frames"] * 40) <= 40      # 25 fps
        assert abs(row["frames"] / 25 - row["duration_s"] - 0.2) <= 0.09    # + the last frame
    assert set(manifest["method"]) == {"ours-exact"}
    assert manifest["viewpoint_mm"].iloc[0] == "-1000 30 450"
    bad = subprocess.run([sys.executable, "-m", "ikbench", "experiment", "stimuli",
                          str(design), "--viewpoint-mm", "1,2", "--output", str(tmp_path / "x")],
                         capture_output=True, text=True, timeout=60, cwd=REPO)
    assert bad.returncode == 2 and "--viewpoint-mm" in bad.stderr
    assert not (tmp_path / "x").exists()
