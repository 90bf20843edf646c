"""``ikbench execute`` end to end against the emulated bus, through the real dynamixel-sdk.

What went over the bus is decoded here from the emulator's raw packet log (not through
ikbench.hw), and the expected register values are computed here from the issue's formulas.
Timing is checked on a :class:`FakeClock` shared by the executor and the emulator (time moves
only when the executor waits), never against the wall clock of a possibly loaded machine.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ikbench.cli import main
from ikbench.core.trajectory import write_trajectory_csv
from ikbench.hw import executor as executor_module
from ikbench.hw.bus import Bus
from ikbench.hw.emulator import Emulator, Fault
from ikbench.hw.executor import Clock, ExecutionInterrupted, execute
from ikbench.hw.motors import default_config_path, load_motor_config
from ikbench.hw.plan import make_plan
from tests.conftest import blocked_output

START = np.array([-24.92, 81.45, 46.55, 94.37, -59.03, 28.0, 45.67])
TOUCH_1 = np.array([33, 39, 25, 134, 102, 77, -168.0])
IDS = [21, 1, 3, 5, 31, 33, 36]
STEP_DEG = 360 / 4096
LIMITS_DEG = {21: (-30, 80), 1: (-30, 180), 3: (0, 70), 5: (50, 180), 31: (-180, 180),
              33: (-180, 180), 36: (-180, 180)}


@pytest.fixture(autouse=True)
def tolerant_status_timeout(monkeypatch):
    """dynamixel-sdk waits 2 x LATENCY_TIMER + 2 ms (34 ms) for a status packet; a loaded test
    machine may not schedule the emulator thread that fast, so give it 200 ms here."""
    import dynamixel_sdk.port_handler

    monkeypatch.setattr(dynamixel_sdk.port_handler, "LATENCY_TIMER", 99)


class FakeClock(Clock):
    """Time [s] that moves only when the executor waits: a wait returns at once with its
    timeout added to the time, once the emulator (:meth:`emulator`) has received every SYNC
    WRITE sent so far, so that each is stamped and acted on at the time it was sent.
    ``ctrl_c_at``: the time at which the stop event is set (a Ctrl-C at a known instant).
    ``sends``: the time of every SYNC WRITE the executor sent (see the ``fake_clock``
    fixture)."""

    def __init__(self, start_s: float = 100.0):
        self.t = start_s
        #: fake time a SYNC WRITE takes (0: none); a test that orders events by time around a
        #: send sets it, else a send and what follows it share one instant
        self.send_tick_s = 0.0
        self.ctrl_c_at: float | None = None
        self.sends: list[float] = []
        self._emulator: Emulator | None = None

    def emulator(self, *args, **kwargs) -> Emulator:
        """An :class:`Emulator` on this clock."""
        self._emulator = Emulator(*args, clock=self.now, **kwargs)
        return self._emulator

    def now(self) -> float:
        return self.t

    def wait(self, event: threading.Event, timeout_s: float) -> bool:
        self._caught_up()
        if self.ctrl_c_at is not None and self.t + timeout_s >= self.ctrl_c_at:
            self.t = max(self.t, self.ctrl_c_at)
            event.set()
        elif not event.is_set():
            self.t += timeout_s
        return event.is_set()

    def _caught_up(self) -> None:
        """Wait (really, at most 10 s) until the emulator received every SYNC WRITE sent."""
        deadline = time.monotonic() + 10
        while (self._emulator is not None and time.monotonic() < deadline
               and len(self._emulator.sync_writes()) < len(self.sends)):
            time.sleep(0.0002)


@pytest.fixture()
def fake_clock(monkeypatch):
    """A :class:`FakeClock` that ``execute`` uses when given none (so also through the CLI),
    recording the time of each SYNC WRITE sent."""
    clock = FakeClock()
    monkeypatch.setattr(executor_module, "DEFAULT_CLOCK", clock)
    original = Bus.sync_write

    def sync_write(bus, goals_raw, speeds_raw):
        sent_at = clock.now()
        original(bus, goals_raw, speeds_raw)
        clock.sends.append(sent_at)
        if clock.send_tick_s:  # once the emulator stamped the write, time moves on
            clock._caught_up()
            clock.t += clock.send_tick_s

    monkeypatch.setattr(Bus, "sync_write", sync_write)
    return clock


def line_poses(n: int = 50, fraction: float = 1.0) -> np.ndarray:
    """Joint-space interpolation from the start pose towards touch pose 1, (n+1, 7)."""
    return START + np.linspace(0.0, fraction, n + 1)[:, None] * (TOUCH_1 - START)


def goal_raw(deg) -> list[int]:
    return [min(4095, round(2048 + q * 4096 / 360)) for q in deg]


def speed_raw(delta_deg, segment_s) -> list[int]:
    return [min(1023, max(1, math.ceil(abs(d) / segment_s / 0.684 - 1e-9))) for d in delta_deg]


def sync_writes(emulator) -> list[tuple[float, dict[int, tuple[int, int]]]]:
    """(t, {id: (goal, speed)}) of every SYNC WRITE, decoded from the raw log."""
    writes = []
    for entry in emulator.log:
        data = entry.data
        if entry.direction != "rx" or len(data) < 7 or data[2] != 0xFE or data[4] != 0x83:
            continue
        assert (data[5], data[6]) == (30, 4), "goal position + moving speed at address 30"
        assert data[-1] == 255 - sum(data[2:-1]) % 256
        chunks = [data[i:i + 5] for i in range(7, len(data) - 1, 5)]
        writes.append((entry.t, {c[0]: (c[1] | c[2] << 8, c[3] | c[4] << 8) for c in chunks}))
    return writes


def motion_commands(emulator, after: float = -1.0) -> list:
    """SYNC WRITEs, and WRITEs touching torque enable (24) .. moving speed (33), after ``after``."""
    found = []
    for entry in emulator.log:
        data = entry.data
        if entry.direction != "rx" or entry.t <= after or len(data) < 7:
            continue
        is_write = data[4] == 0x03 and data[5] <= 33 and data[5] + len(data) - 7 > 24
        if data[4] == 0x83 or is_write:
            found.append(entry)
    return found


def segments_sent(emulator) -> list:
    """The emulator's SYNC WRITEs that carry every motor (trajectory segments, approach)."""
    return [w for w in emulator.sync_writes() if set(w.data) == set(IDS)]


def assert_is_a_hold(emulator) -> list:
    """After the last segment, the only motion commands are the hold: one SYNC WRITE per
    motor, in joint order, each commanding nothing new: a goal the servo passed on its way to
    the goal of the last segment (its present position when read, or that goal itself), at a
    slow speed. Returns the hold's SYNC WRITEs."""
    segment = segments_sent(emulator)[-1]
    holds = [w for w in emulator.sync_writes() if w.t > segment.t]
    assert [list(w.data) for w in holds] == [[motor_id] for motor_id in IDS]
    assert len(motion_commands(emulator, after=segment.t)) == len(IDS)  # nothing but the hold
    for motor_id, hold in zip(IDS, holds):
        ends = (segment.present_before[motor_id], segment.word(motor_id))
        assert min(ends) - 1 <= hold.word(motor_id) <= max(ends) + 1
        assert hold.word(motor_id, 2) <= math.ceil(10 / 0.684)
    return holds


def first_fault_time(emulator) -> float:
    return next(e.t for e in emulator.log if e.note.startswith("fault"))


def writes_before_motion(emulator) -> list[tuple[int, int, list[int]]]:
    """(id, address, data) of every WRITE before the first SYNC WRITE, decoded from the raw
    log, each checked to have been answered by a status packet without error bits."""
    found, log = [], emulator.log
    for i, entry in enumerate(log):
        data = entry.data
        if entry.direction != "rx" or len(data) < 6:
            continue
        if data[4] == 0x83:
            break
        if data[4] == 0x03:
            status = log[i + 1].data
            assert log[i + 1].direction == "tx" and status[2] == data[2] and status[4] == 0
            found.append((data[2], data[5], list(data[6:-1])))
    return found


@pytest.fixture()
def traj(tmp_path, robot):
    return write_trajectory_csv(tmp_path / "line.csv", robot, line_poses())


@pytest.fixture()
def short_traj(tmp_path, robot):
    """10 segments, a fifth of the way to the touch pose: fine at T = 0.3 s."""
    return write_trajectory_csv(tmp_path / "short.csv", robot, line_poses(10, 0.2), 0.3)


def test_end_to_end_two_seconds(traj, tmp_path, capsys, fake_clock):
    record = tmp_path / "rec.csv"
    poses = line_poses()
    with fake_clock.emulator(load_motor_config(), START) as emulator:
        code = main(["execute", str(traj), "--port", emulator.port, "--record", str(record)])
        final = emulator.present_deg()
    out = capsys.readouterr().out
    assert code == 0, out
    writes = sync_writes(emulator)
    assert len(writes) == 50
    for k, (_, goals) in enumerate(writes):
        assert list(goals) == IDS  # every motor, in joint order, in one packet
        assert [g for g, _ in goals.values()] == goal_raw(poses[k + 1])
        assert [s for _, s in goals.values()] == speed_raw(poses[k + 1] - poses[k], 0.04)
        for motor_id, (goal, _) in goals.items():
            low, high = LIMITS_DEG[motor_id]
            assert goal_raw([low])[0] <= goal <= goal_raw([high])[0]
    # no per-motor round trips while the segments go out (the log's order, not its times)
    names = [e.name for e in emulator.log if e.direction == "rx"]
    first, last = names.index("SYNC_WRITE"), len(names) - names[::-1].index("SYNC_WRITE")
    assert set(names[first:last]) == {"SYNC_WRITE"}
    assert not emulator.violations
    np.testing.assert_allclose(final, TOUCH_1, atol=STEP_DEG)
    # one segment every T/n = 40 ms from the first, on time, then settling (at most 0.5 s)
    t0 = fake_clock.sends[0]
    np.testing.assert_allclose(np.subtract(fake_clock.sends, t0), 0.04 * np.arange(50),
                               atol=1e-9)
    done = re.search(r"done: 50 SYNC WRITEs in ([\d.]+) s \(T = 2 s, worst send delay "
                     r"0\.0 ms\)", out)
    assert done, out
    assert 2.0 <= float(done[1]) <= 2.0 + executor_module.SETTLE_S
    rows = pd.read_csv(record)
    assert rows["phase"].iloc[0] == "start" and rows["phase"].iloc[-1] == "settle"
    np.testing.assert_allclose(rows.iloc[-1][2:].to_numpy(float), TOUCH_1, atol=0.2)


def test_record_rate_reads_between_segments(tmp_path, robot, fake_clock):
    path = write_trajectory_csv(tmp_path / "t.csv", robot, line_poses(20, 0.3), 1.0)
    record = tmp_path / "rec.csv"
    with fake_clock.emulator(load_motor_config(), START) as emulator:
        assert main(["execute", str(path), "--port", emulator.port, "--duration", "1",
                     "--record", str(record), "--record-rate", "20"]) == 0
    assert len(sync_writes(emulator)) == 20
    rows = pd.read_csv(record)
    moving = rows[rows["phase"] == "move"]
    # 20 Hz over 1 s: one read after each 50 ms segment (reads take no time on this clock)
    np.testing.assert_allclose(moving["time_s"], 0.05 * np.arange(20), atol=1e-9)
    # the recorded finger moves steadily from the first towards the last pose
    finger = moving["r_indexfinger_x"].to_numpy()
    last = START[6] + 0.3 * (TOUCH_1[6] - START[6])
    assert np.all(np.diff(finger) <= 0)
    assert np.all((finger <= START[6] + 0.1) & (finger >= last - 0.1))


def test_far_start_is_refused_without_motion(short_traj, capsys):
    away = START + [0, 0, 0, 20, 0, 0, 0]
    with Emulator(load_motor_config(), away) as emulator:
        code = main(["execute", str(short_traj), "--port", emulator.port, "--duration", "0.3"])
    err = capsys.readouterr().err
    assert code == 3
    assert err == ("ikbench: error: r_elbow_y is at 114.35 motor deg, 19.98 deg from the first "
                   "pose (94.37); tolerance 5 deg; move the arm there or pass --approach\n")
    assert motion_commands(emulator) == []


def test_approach_moves_slowly_to_the_first_pose(short_traj, capsys):
    away = START + [0, 0, 0, 20, 0, 0, -10]
    with Emulator(load_motor_config(), away) as emulator:
        code = main(["execute", str(short_traj), "--port", emulator.port, "--duration", "0.3",
                     "--approach", "--approach-speed", "100"])
        final = emulator.present_deg()
    assert code == 0, capsys.readouterr()
    writes = sync_writes(emulator)
    assert len(writes) == 1 + 10
    approach = writes[0][1]
    assert [g for g, _ in approach.values()] == goal_raw(START)
    assert max(s for _, s in approach.values()) <= math.ceil(100 / 0.684)
    assert writes[1][0] - writes[0][0] >= 20 / 100  # waited for the arm to get there
    np.testing.assert_allclose(final, line_poses(10, 0.2)[-1], atol=STEP_DEG)


def test_missing_motors_are_named(short_traj, capsys):
    with Emulator(load_motor_config(), START, missing_ids={5, 33}) as emulator:
        code = main(["execute", str(short_traj), "--port", emulator.port, "--duration", "0.3"])
    err = capsys.readouterr().err
    assert code == 3
    assert "no answer from motor(s) id 5 (r_elbow_y), id 33 (r_wrist_x) on /dev/" in err
    assert err.count("\n") == 1
    assert motion_commands(emulator) == []


@pytest.mark.parametrize("fault, message", [
    (Fault("drop", 31, 0x02, after=1),
     "read present position on motor id 31 (r_wrist_z): no status packet (timeout)"),
    (Fault("corrupt", 3, 0x02, after=1),
     "read present position on motor id 3 (r_arm_x): corrupted status packet"),
    (Fault("error", 36, 0x03, error_bits=0x20),
     ("write goal position: motor id 36 (r_indexfinger_x) reports error overload (status "
      "error byte 0x20)")),
    (Fault("error", 1, 0x03, after=1, error_bits=0x04),
     "enable torque: motor id 1 (r_shoulder_y) reports error overheating"),
])
def test_faults_before_the_move(short_traj, capsys, fault, message):
    with Emulator(load_motor_config(), START, faults=[fault]) as emulator:
        code = main(["execute", str(short_traj), "--port", emulator.port, "--duration", "0.3"])
    err = capsys.readouterr().err
    assert code == 3
    assert err.startswith(f"ikbench: error: {message}")
    assert err.rstrip().endswith("nothing moved")
    assert sync_writes(emulator) == []
    assert motion_commands(emulator, after=first_fault_time(emulator)) == []


@pytest.mark.parametrize("kind, message", [
    ("corrupt", ("read present position on motor id 5 (r_elbow_y): corrupted status packet "
                 "(bad checksum or length)")),
    ("drop", "read present position on motor id 5 (r_elbow_y): no status packet (timeout)"),
    ("error", ("read present position: motor id 5 (r_elbow_y) reports error overload (status "
               "error byte 0x20)")),
])
def test_fault_during_the_move_stops_and_holds(short_traj, tmp_path, capsys, kind, message,
                                               fake_clock):
    # reads of id 5: model number at ping, start pose, then one per recorded sample; the fault
    # hits the second sample of the move; on the fake clock (a send takes 1 us, so the
    # failing read comes after the segment sent before it)
    fake_clock.send_tick_s = 1e-6
    fault = Fault(kind, 5, 0x02, after=2 + 1, count=1)
    record = tmp_path / "rec.csv"
    with fake_clock.emulator(load_motor_config(), START, faults=[fault]) as emulator:
        code = main(["execute", str(short_traj), "--port", emulator.port, "--duration", "0.6",
                     "--record-rate", "100", "--record", str(record)])
        fake_clock.t += 0.1  # the hold settles
        settled = emulator.present_deg()
    err = capsys.readouterr().err
    assert code == 3
    writes = sync_writes(emulator)
    t_fault = first_fault_time(emulator)
    before = [w for w in writes if w[0] < t_fault]
    after = [w for w in writes if w[0] >= t_fault]    # the hold follows at the fault's instant
    assert 1 <= len(before) < 10
    assert err == (f"ikbench: error: {message}; sent {len(before)} of 10 segments (last: "
                   f"segment {len(before) - 1}); holding present position\n")
    # no motion command after the failure but the hold: goal = present, at a slow speed
    assert len(after) == 7 and all(len(goals) == 1 for _, goals in after)
    assert_is_a_hold(emulator)
    # the arm stopped part-way instead of finishing the trajectory
    assert np.abs(settled - line_poses(10, 0.2)[-1]).max() > 1.0
    assert pd.read_csv(record)["phase"].iloc[-1] == "move"


def test_ctrl_c_stops_and_holds(short_traj, fake_clock):
    config = load_motor_config()
    poses = line_poses(10, 0.2)
    plan = make_plan(poses, config, duration_s=0.6)
    clock = fake_clock
    clock.ctrl_c_at = clock.now() + 0.15  # between the 3rd and the 4th segment
    stop = threading.Event()
    with clock.emulator(config, START) as emulator:
        with pytest.raises(ExecutionInterrupted) as info:
            execute(plan, emulator.port, stop_event=stop, log=lambda line: None, clock=clock)
    writes = sync_writes(emulator)
    sent = info.value.result.segments_sent
    assert sent == 3  # 60 ms segments sent at 0, 60 and 120 ms
    assert str(info.value) == ("interrupted; sent 3 of 10 segments (last: segment 2); holding "
                               "present position")
    assert info.value.exit_code == 130
    assert len(segments_sent(emulator)) == sent
    assert len(writes) == sent + 7  # the segments, then the hold, one motor at a time
    assert_is_a_hold(emulator)
    assert clock.now() == clock.ctrl_c_at  # it held at once: no wait after the Ctrl-C
    assert np.subtract(clock.sends[:3], clock.sends[0]) == pytest.approx([0, 0.06, 0.12])


def test_ctrl_c_from_the_terminal(traj):
    exe = Path(sys.executable).with_name("ikbench")
    with Emulator(load_motor_config(), START) as emulator:
        # T = 10 s (200 ms segments): the SIGINT after 5 segments comes long before the end
        proc = subprocess.Popen([str(exe), "execute", str(traj), "--port", emulator.port,
                                 "--duration", "10"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            deadline = time.monotonic() + 20
            while len(emulator.sync_writes()) < 5 and time.monotonic() < deadline:
                time.sleep(0.01)
            proc.send_signal(signal.SIGINT)
            _, err = proc.communicate(timeout=10)
        finally:
            proc.kill()
        final = emulator.present_deg()
    assert proc.returncode == 130
    sent = len(segments_sent(emulator))
    assert len(sync_writes(emulator)) == sent + 7
    assert err == (f"ikbench: error: interrupted; sent {sent} of 50 segments (last: segment "
                   f"{sent - 1}); holding present position\n")
    assert sent < 30
    assert np.abs(final - TOUCH_1).max() > 50  # nowhere near the end


def test_port_emulator_shortcut(short_traj, capsys):
    assert main(["execute", str(short_traj), "--port", "emulator", "--duration", "0.3"]) == 0
    out = capsys.readouterr().out
    assert "emulator: 10 SYNC WRITEs received, 0 limit violations" in out
    assert "done: 10 SYNC WRITEs in " in out and "(T = 0.3 s" in out


def test_dry_run_writes_nothing(short_traj, tmp_path, capsys):
    record = tmp_path / "rec.csv"
    with Emulator(load_motor_config(), START) as emulator:
        code = main(["execute", str(short_traj), "--port", emulator.port, "--dry-run",
                     "--duration", "0.3", "--record", str(record)])
    out = capsys.readouterr().out
    assert code == 0
    assert "dry run: would send 10 SYNC WRITEs, one every 30 ms; nothing was written" in out
    assert {e.name for e in emulator.log if e.direction == "rx"} == {"PING", "READ"}
    assert pd.read_csv(record)["phase"].tolist() == ["start"]


@pytest.mark.parametrize("args, code, message", [
    (["--approach-speed", "0"], 2, "--approach-speed 0; allowed: (0, 699.7] deg/s"),
    (["--record-rate", "-1"], 2, "--record-rate -1; allowed: [0, 1000] Hz"),
    (["--duration", "0.04"], 2, "--duration 0.04 s gives segments of 4 ms"),
    (["--duration", "0.1"], 2, "segments are flagged; r_wrist_z"),
    (["--port", "/dev/does-not-exist"], 3, "cannot open port '/dev/does-not-exist'"),
])
def test_bad_options(short_traj, capsys, args, code, message):
    argv = ["execute", str(short_traj), "--port", "emulator", "--duration", "0.3", *args]
    assert main(argv) == code
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_model_number_is_checked(short_traj, tmp_path, capsys):
    spec = json.loads(default_config_path().read_text())
    spec["motors"]["r_shoulder_z"]["model"] = "MX-64"
    path = tmp_path / "mx64.json"
    path.write_text(json.dumps(spec))
    with Emulator(load_motor_config(), START) as emulator:  # reports MX-28's number, 29
        code = main(["execute", str(short_traj), "--port", emulator.port, "--motors", str(path),
                     "--duration", "0.3"])
    assert code == 3
    assert ("motor id 21 (r_shoulder_z) reports model number 29 (MX-28) but "
            f"{path} says MX-64") in capsys.readouterr().err
    assert motion_commands(emulator) == []


def test_bus_refuses_goals_outside_limits():
    config = load_motor_config()
    with Emulator(config, START) as emulator:
        bus = Bus(emulator.port, config)
        bus.open()
        with pytest.raises(Exception, match=r"refusing goal 4000 for motor id 3 \(r_arm_x\)"):
            bus.sync_write({i: 2048 for i in range(6)} | {2: 4000}, {i: 10 for i in range(7)})
        bus.close()
    assert sync_writes(emulator) == []


def test_torque_enabled_at_24_after_goal_equals_present_before_motion(short_traj):
    with Emulator(load_motor_config(), START) as emulator:
        assert main(["execute", str(short_traj), "--port", emulator.port, "--duration",
                     "0.3"]) == 0
    hold_speed = math.ceil(10 / 0.684)
    expected = []
    for motor_id, raw in zip(IDS, goal_raw(START)):
        # goal = present (2 bytes) + moving speed (2 bytes) at 30, then torque enable 1 at 24
        expected += [(motor_id, 30, [raw & 0xFF, raw >> 8, hold_speed & 0xFF, hold_speed >> 8]),
                     (motor_id, 24, [1])]
    assert writes_before_motion(emulator) == expected
    assert len(segments_sent(emulator)) == 10


def test_port_failure_during_the_move_stops_and_reports(short_traj, capsys):
    """The port goes away mid-move (the emulator's pty closes, as when a USB adapter is
    unplugged): dynamixel-sdk's flush raises termios.error, not an OSError; it must end as
    one line with the report and exit 3, not as a traceback."""
    emulator = Emulator(load_motor_config(), START)
    emulator.start()

    def unplug_after_five_segments():
        deadline = time.monotonic() + 10
        while len(emulator.sync_writes()) < 5 and time.monotonic() < deadline:
            time.sleep(0.001)
        emulator.close()

    unplug = threading.Thread(target=unplug_after_five_segments, daemon=True)
    unplug.start()
    try:
        code = main(["execute", str(short_traj), "--port", emulator.port, "--duration", "0.6"])
    finally:
        unplug.join(timeout=10)
        emulator.close()
    err = capsys.readouterr().err
    assert code == 3, err
    match = re.fullmatch(
        r"ikbench: error: sync write on the bus: port '(.+)' failed: (.+); sent (\d+) of 10 "
        r"segments \(last: segment (\d+)\); no motor could be held: no answer from any motor, "
        r"and the hold could not be sent; each motor stops at the last goal it received\n", err)
    assert match, err
    assert match[1] == emulator.port
    sent, received = int(match[3]), len(segments_sent(emulator))
    assert int(match[4]) == sent - 1
    assert 5 <= received <= sent <= received + 1 < 11  # it stopped when the port went away


def test_unexpected_sdk_exception_during_the_move_stops_and_holds(short_traj, capsys,
                                                                  monkeypatch):
    import dynamixel_sdk

    original = dynamixel_sdk.GroupSyncWrite.txPacket
    calls = []

    def fourth_fails(group):
        calls.append(group)
        if len(calls) == 4:
            raise ValueError("list index out of range")
        return original(group)

    monkeypatch.setattr(dynamixel_sdk.GroupSyncWrite, "txPacket", fourth_fails)
    with Emulator(load_motor_config(), START) as emulator:
        code = main(["execute", str(short_traj), "--port", emulator.port, "--duration", "0.6"])
    err = capsys.readouterr().err
    assert code == 3
    assert err == ("ikbench: error: sync write on the bus: dynamixel-sdk raised ValueError: list "
                   "index out of range; sent 3 of 10 segments (last: segment 2); holding "
                   "present position\n")
    assert len(segments_sent(emulator)) == 3
    assert_is_a_hold(emulator)


def test_hold_sends_its_last_goal_to_a_motor_that_does_not_answer(short_traj, capsys,
                                                                  fake_clock):
    # reads of id 5: model number at ping, start pose, 4 recorded samples; then none answered.
    # On the fake clock a read takes no time, so one sample follows each of the 60 ms
    # segments: the 5th read after the start fails (on the wall clock of a loaded machine
    # the reads fell behind and all 10 segments went out first: "assert 10 < 10")
    fault = Fault("drop", 5, 0x02, after=2 + 4)
    fake_clock.send_tick_s = 0.001  # the hold's writes come after the last segment's
    with fake_clock.emulator(load_motor_config(), START, faults=[fault]) as emulator:
        code = main(["execute", str(short_traj), "--port", emulator.port, "--duration", "0.6",
                     "--record-rate", "100"])
    err = capsys.readouterr().err
    assert code == 3
    sent = len(segments_sent(emulator))
    assert sent == 5, err
    assert err == (f"ikbench: error: read present position on motor id 5 (r_elbow_y): no status "
                   f"packet (timeout); sent {sent} of 10 segments (last: segment {sent - 1}); "
                   f"holding present position of 6 of 7 motors; no answer from id 5 "
                   f"(r_elbow_y): sent the last goal again at 10 deg/s; a motor not held stops "
                   f"at the last goal it received\n")
    holds = assert_is_a_hold(emulator)
    assert holds[IDS.index(5)].word(5) == segments_sent(emulator)[-1].word(5)


def test_ctrl_c_while_settling_is_reported_and_holds():
    config = load_motor_config()
    plan = make_plan(line_poses(10, 0.2), config, duration_s=0.3)
    speed = plan.speed_raw.copy()
    speed[-1, 6] = 1  # the finger lags in the last segment: settling takes its full 0.5 s
    plan = dataclasses.replace(plan, speed_raw=speed)
    stop = threading.Event()
    with Emulator(config, START) as emulator:

        def press_ctrl_c_while_settling():
            deadline = time.monotonic() + 10
            while time.monotonic() < deadline:
                writes = emulator.sync_writes()
                if len(writes) == 10 and any(e.direction == "rx" and e.name == "READ"
                                             and e.t > writes[-1].t for e in list(emulator.log)):
                    break  # every segment sent, and the settle reads have begun
                time.sleep(0.001)
            stop.set()

        threading.Thread(target=press_ctrl_c_while_settling, daemon=True).start()
        with pytest.raises(ExecutionInterrupted) as info:
            execute(plan, emulator.port, stop_event=stop, log=lambda line: None)
    assert str(info.value) == ("interrupted while settling after the last segment; sent 10 of "
                               "10 segments (last: segment 9); holding present position")
    assert info.value.exit_code == 130
    assert info.value.result.record["phase"].iloc[-1] == "settle"
    assert len(segments_sent(emulator)) == 10
    assert_is_a_hold(emulator)


@pytest.mark.parametrize("blocked_by", ["file", "directory"])
def test_unwritable_record_is_refused_before_anything_moves(short_traj, tmp_path, capsys,
                                                            blocked_by):
    record, reason = blocked_output(tmp_path, blocked_by, "rec.csv")
    with Emulator(load_motor_config(), START) as emulator:
        code = main(["execute", str(short_traj), "--port", emulator.port, "--duration", "0.3",
                     "--record", str(record)])
    err = capsys.readouterr().err
    assert code == 2
    assert err == f"ikbench: error: --record: cannot write {record}: {reason}\n"
    assert emulator.log == []  # the port was not even opened: no ping, no SYNC WRITE
