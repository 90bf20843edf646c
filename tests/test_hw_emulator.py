"""The Protocol 1.0 servo emulator, driven by the real dynamixel-sdk over its pseudo-terminal."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import dynamixel_sdk as sdk
import numpy as np
import pandas as pd
import pytest
import serial

from ikbench.cli import main
from ikbench.cli.commands.emulate import parse_fault
from ikbench.hw.emulator import Emulator, Fault
from ikbench.hw.motors import load_motor_config
from ikbench.hw.protocol import PacketReader, packet

START = [-24.92, 81.45, 46.55, 94.37, -59.03, 28.0, 45.67]


@pytest.fixture(autouse=True)
def tolerant_status_timeout(monkeypatch):
    """dynamixel-sdk waits 2 x LATENCY_TIMER + 2 ms (34 ms) for a status packet; a loaded test
    machine may not schedule the emulator thread that fast, so give it 200 ms here."""
    import dynamixel_sdk.port_handler

    monkeypatch.setattr(dynamixel_sdk.port_handler, "LATENCY_TIMER", 99)


def _checksum(body: bytes) -> int:
    # written out here, independent of ikbench.hw.protocol
    return 255 - (sum(body) % 256)


@pytest.fixture()
def config():
    return load_motor_config()


def _open(emulator):
    port = sdk.PortHandler(emulator.port)
    assert port.openPort() is True
    return port, sdk.PacketHandler(1.0)


def test_sdk_pings_reads_and_writes(config):
    with Emulator(config, START) as emulator:
        port, ph = _open(emulator)
        for motor_id in config.ids:
            model, result, error = ph.ping(port, motor_id)
            assert (result, error, model) == (sdk.COMM_SUCCESS, 0, 29)
        present, result, _ = ph.read2ByteTxRx(port, 5, 36)
        assert result == sdk.COMM_SUCCESS
        assert present == round(2048 + 94.37 * 4096 / 360)
        assert ph.read2ByteTxRx(port, 5, 8)[0] == 4095  # CCW angle limit = 180 deg
        assert ph.read2ByteTxRx(port, 5, 6)[0] == round(2048 + 50 * 4096 / 360)
        assert ph.write2ByteTxRx(port, 5, 32, 100) == (sdk.COMM_SUCCESS, 0)
        assert ph.read2ByteTxRx(port, 5, 32)[0] == 100
        # an id nobody has: no status packet
        assert ph.ping(port, 7)[1] == sdk.COMM_RX_TIMEOUT
        port.closePort()
    names = [(e.direction, e.motor_id, e.name) for e in emulator.log]
    assert names[:2] == [("rx", 21, "PING"), ("tx", 21, "STATUS")]
    assert all(b.t >= a.t for a, b in zip(emulator.log, emulator.log[1:]))


def test_status_packet_bytes_are_protocol_1(config):
    with Emulator(config, START) as emulator:
        link = serial.Serial(emulator.port, 1_000_000, timeout=0.5)
        body = bytes([3, 4, 2, 36, 2])  # READ id 3, address 36, 2 bytes
        link.write(b"\xff\xff" + body + bytes([_checksum(body)]))
        reply = link.read(8)
        raw = round(2048 + 46.55 * 4096 / 360)
        status = bytes([3, 4, 0, raw & 0xFF, raw >> 8])
        assert reply == b"\xff\xff" + status + bytes([_checksum(status)])
        # a wrong instruction checksum gets a status with the checksum error bit (0x10)
        link.write(b"\xff\xff" + body + bytes([_checksum(body) ^ 1]))
        assert link.read(6) == b"\xff\xff" + bytes([3, 2, 0x10, _checksum(bytes([3, 2, 0x10]))])
        link.close()


def test_moves_towards_goal_at_moving_speed(config):
    # the emulator's servos move on a clock the test sets (a wall clock let a loaded machine
    # read "moving" after the servo had arrived)
    clock = [100.0]
    with Emulator(config, START, clock=lambda: clock[0]) as emulator:
        port, ph = _open(emulator)
        start_raw = ph.read2ByteTxRx(port, 21, 36)[0]
        speed_raw = 73  # 73 * 0.684 = 49.9 deg/s
        group = sdk.GroupSyncWrite(port, ph, 30, 4)
        group.addParam(21, [0x00, 0x08, speed_raw, 0])  # goal 2048 = 0 deg
        assert group.txPacket() == sdk.COMM_SUCCESS
        deadline = time.monotonic() + 10
        while not emulator.sync_writes() and time.monotonic() < deadline:
            time.sleep(0.001)  # the write stamped at 100 s before time moves on
        clock[0] += 0.2
        raw, _, _ = ph.read2ByteTxRx(port, 21, 36)
        # timed by the emulator's own clock: when the packets arrived, not when we saw them
        t_sync, t_read = [e.t for e in emulator.log if e.direction == "rx"][-2:]
        assert t_read - t_sync == pytest.approx(0.2)
        moved_deg = (raw - start_raw) * 360 / 4096
        assert moved_deg == pytest.approx(speed_raw * 0.684 * (t_read - t_sync), abs=0.1)
        assert ph.read1ByteTxRx(port, 21, 46)[0] == 1  # moving
        clock[0] += 0.35  # 24.92 deg at 49.9 deg/s: there after 0.5 s
        assert ph.read2ByteTxRx(port, 21, 36)[0] == 2048
        assert ph.read1ByteTxRx(port, 21, 46)[0] == 0
        port.closePort()
    (write,) = emulator.sync_writes()
    assert write.address == 30 and write.word(21) == 2048 and write.word(21, 2) == speed_raw
    assert write.present_before[21] == start_raw


def test_goal_outside_angle_limits_is_recorded_and_refused(config):
    with Emulator(config, START) as emulator:
        port, ph = _open(emulator)
        below = round(2048 + 40 * 4096 / 360)  # r_elbow_y limit is [50, 180]
        assert ph.write2ByteTxRx(port, 5, 30, below) == (sdk.COMM_SUCCESS, 0x02)
        port.closePort()
    assert len(emulator.violations) == 1 and "id 5" in emulator.violations[0]
    assert emulator.servos[5].word(30) == round(2048 + 50 * 4096 / 360)


@pytest.mark.parametrize("fault, expected", [
    (Fault("drop", 3, 0x02), (sdk.COMM_RX_TIMEOUT, 0)),
    (Fault("corrupt", 3, 0x02), (sdk.COMM_RX_CORRUPT, 0)),
    (Fault("error", 3, 0x02, error_bits=0x20), (sdk.COMM_SUCCESS, 0x20)),
])
def test_faults_as_the_sdk_sees_them(config, fault, expected):
    with Emulator(config, START, faults=[fault]) as emulator:
        port, ph = _open(emulator)
        assert ph.write1ByteTxRx(port, 3, 25, 1) == (sdk.COMM_SUCCESS, 0)  # WRITE: untouched
        _, result, error = ph.read2ByteTxRx(port, 3, 36)
        assert (result, error) == expected
        assert ph.read2ByteTxRx(port, 1, 36)[1] == sdk.COMM_SUCCESS  # other ids unaffected
        port.closePort()
    assert any(e.note.startswith("fault") for e in emulator.log)


def test_fault_after_and_count(config):
    fault = Fault("drop", 21, 0x02, after=2, count=1)
    with Emulator(config, START, faults=[fault], missing_ids={33}) as emulator:
        port, ph = _open(emulator)
        results = [ph.read2ByteTxRx(port, 21, 36)[1] for _ in range(4)]
        assert results == [0, 0, sdk.COMM_RX_TIMEOUT, 0]
        assert ph.ping(port, 33)[1] == sdk.COMM_RX_TIMEOUT
        port.closePort()


def test_packet_reader_splits_skips_noise_and_checks_checksums():
    ping = packet(5, 0x01)
    read = packet(3, 0x02, bytes([36, 2]))
    bad = bytearray(packet(7, 0x03, bytes([24, 1])))
    bad[-1] ^= 0xFF
    reader = PacketReader()
    stream = b"\x00\xff" + ping + read[:4]
    first = reader.feed(stream)
    assert [(p.motor_id, p.code, p.checksum_ok) for p in first] == [(5, 1, True)]
    rest = reader.feed(read[4:] + bytes(bad))
    assert [(p.motor_id, p.params, p.checksum_ok) for p in rest] == [
        (3, bytes([36, 2]), True), (7, bytes([24, 1]), False)]
    assert ping == b"\xff\xff" + bytes([5, 2, 1]) + bytes([_checksum(bytes([5, 2, 1]))])


def test_log_frame_and_present_pose(config):
    with Emulator(config, START) as emulator:
        port, ph = _open(emulator)
        ph.ping(port, 21)
        port.closePort()
        frame = emulator.log_frame()
        pose = emulator.present_deg()
    assert list(frame.columns) == ["t_s", "direction", "id", "instruction", "bytes", "note"]
    assert frame["instruction"].tolist()[:2] == ["PING", "STATUS"]
    assert frame["bytes"].iloc[0] == "ff ff 15 02 01 e7"
    assert np.abs(pose - START).max() <= 360 / 4096 / 2 + 1e-9


def test_emulate_cli_prints_port_serves_and_stops_on_ctrl_c(tmp_path):
    log = tmp_path / "bus.csv"
    exe = Path(sys.executable).with_name("ikbench")
    proc = subprocess.Popen([str(exe), "emulate", "--for", "30", "--missing", "33",
                             "--pose=0,0,10,90,0,0,0", "--log", str(log)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        port_name = proc.stdout.readline().strip()
        assert port_name.startswith("/dev/")
        port = sdk.PortHandler(port_name)
        assert port.openPort()
        ph = sdk.PacketHandler(1.0)
        assert ph.ping(port, 21)[1] == sdk.COMM_SUCCESS
        assert ph.ping(port, 33)[1] == sdk.COMM_RX_TIMEOUT
        assert ph.read2ByteTxRx(port, 3, 36)[0] == round(2048 + 10 * 4096 / 360)
        port.closePort()
        proc.send_signal(signal.SIGINT)  # Ctrl-C is the normal way to stop it
        out, err = proc.communicate(timeout=10)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert "limit violations" in out
    frame = pd.read_csv(log)
    assert frame["instruction"].tolist()[:4] == ["PING", "STATUS", "READ", "STATUS"]


@pytest.mark.parametrize("args, message", [
    (["--fault", "explode:5"], "--fault 'explode:5': give KIND[:ID[:INSTRUCTION[:AFTER]]]"),
    (["--fault", "drop:5:jump"], "instruction 'jump'; allowed: ping, read, write, *"),
    (["--missing", "99"], "--missing 99 is not a motor id"),
    (["--pose=1,2,3"], "--pose: expected 7 angles"),
])
def test_emulate_cli_bad_options(capsys, args, message):
    assert main(["emulate", *args, "--for", "0.1"]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_parse_fault_spec():
    fault = parse_fault("error:31:write:2")
    assert (fault.kind, fault.motor_id, fault.instruction, fault.after) == ("error", 31, 3, 2)
    fault = parse_fault("drop")
    assert (fault.motor_id, fault.instruction, fault.after) == (None, None, 0)


def test_emulate_cli_unwritable_log_is_refused_before_serving(tmp_path, capsys):
    blocker = tmp_path / "blocker"
    blocker.write_text("not a folder")
    log = blocker / "bus.csv"
    assert main(["emulate", "--log", str(log), "--for", "0.1"]) == 2
    out, err = capsys.readouterr()
    assert out == ""  # no port printed: nothing was started
    assert err == (f"ikbench: error: --log: cannot write {log}: {blocker} is a file, not a "
                   "directory\n")


def test_the_bus_waits_longer_only_on_a_port_the_emulator_serves(config):
    """A status packet from the in-process emulator may come late on a loaded machine: the Bus
    waits at least EMULATED_STATUS_TIMEOUT_MS there, and the SDK's own wait on any other port."""
    from ikbench.hw.bus import EMULATED_STATUS_TIMEOUT_MS, Bus

    with Emulator(config, START) as emulator:
        bus = Bus(emulator.port, config)
        bus.port.setPacketTimeout(8)
        assert bus.port.packet_timeout == EMULATED_STATUS_TIMEOUT_MS
        served = emulator.port
    plain = Bus(served, config)  # the emulator has stopped: an ordinary port name again
    plain.port.setPacketTimeout(8)
    assert plain.port.packet_timeout < EMULATED_STATUS_TIMEOUT_MS
