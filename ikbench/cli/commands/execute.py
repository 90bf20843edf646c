"""``ikbench execute``: play a trajectory on the robot's Dynamixel bus (or an emulated one)."""

from __future__ import annotations

import argparse
import math
import os

from ikbench.cli.commands.plan import add_plan_arguments, check_timing_args, timing_from_args
from ikbench.cli.options import begin, robot_from_args
from ikbench.cli.values import OUTPUT
from ikbench.core.errors import InputError, OutputError

HELP = "play a trajectory on the arm's Dynamixel servos (Protocol 1.0) or an emulator"

EMULATOR_PORT = "emulator"


DESCRIPTION = (
    "Play a trajectory CSV on NICO's arm: ping every motor, read the present pose, "
    "refuse if it is far from the trajectory's first pose (unless --approach), then "
    "send one SYNC WRITE (goal position + moving speed for all motors) per segment, "
    "paced by a monotonic clock. Ctrl-C (also while settling after the last segment) "
    "or a failure on the bus stops the motion and holds the present position (exit "
    "code 130 or 3). --timing min-jerk or topp sends the same goals at their retimed "
    "times. See docs/hardware.md and docs/timing.md.")


def arguments(parser: argparse.ArgumentParser) -> None:
    add_plan_arguments(parser)
    parser.add_argument("--port", required=True,
                        help="serial port of the servo bus, e.g. /dev/ttyUSB0, or a port printed "
                        f"by `ikbench emulate`; '{EMULATOR_PORT}' plays on an in-process "
                        "emulator whose servos start at the first pose (no robot needed)")
    parser.add_argument("--dry-run", action="store_true",
                        help="ping the motors, read the present pose and check the start, but "
                        "write nothing to the bus")
    parser.add_argument("--record", metavar="OUT.csv", type=OUTPUT,
                        help="write the present poses read back (time_s, phase, joints in motor "
                        "deg) to this CSV")
    parser.add_argument("--record-rate", type=float, default=0.0, metavar="HZ",
                        help="also read the present pose during the move, at most HZ times a "
                        "second and only between segments (default 0: only after the move, "
                        "so the move has no per-motor round trips)")
    parser.add_argument("--approach", action="store_true",
                        help="if the arm is far from the first pose, move it there first at "
                        "--approach-speed instead of refusing")
    parser.add_argument("--approach-speed", type=float, default=20.0, metavar="DEG_S",
                        help="speed limit of the approach move [deg/s] (default: 20)")
    parser.add_argument("--start-tolerance", type=float, default=5.0, metavar="DEG",
                        help="largest distance per joint [motor deg] between the present and "
                        "the first pose that counts as 'at the start' (default: 5)")


def run(args: argparse.Namespace) -> int:
    import signal
    import threading

    import numpy as np

    from ikbench.core.io import check_writable
    from ikbench.hw.executor import ExecutionStopped, execute
    from ikbench.hw.motors import SPEED_RAW_MAX, SPEED_UNIT_DEG_S, load_motor_config
    from ikbench.hw.plan import plan_trajectory_file

    top = SPEED_RAW_MAX * SPEED_UNIT_DEG_S
    _check("--approach-speed", args.approach_speed, 0 < args.approach_speed <= top,
           f"(0, {top:.1f}] deg/s")
    _check("--start-tolerance", args.start_tolerance, 0 <= args.start_tolerance <= 360,
           "[0, 360] deg")
    _check("--record-rate", args.record_rate, 0 <= args.record_rate <= 1000, "[0, 1000] Hz")
    check_timing_args(args)
    robot = robot_from_args(args)
    config = load_motor_config(args.motors, robot)
    timing, limits = timing_from_args(args, robot, config)
    plan, note = plan_trajectory_file(args.trajectory, config, args.duration, robot=robot,
                                      timing=timing, limits=limits)
    if args.record:
        check_writable(args.record)  # before anything moves, not after the whole move
    if note:
        print(note)
    plan.check_executable()
    if args.port != EMULATOR_PORT and os.path.isdir(args.port):
        raise InputError(f"--port: {args.port!r} is a directory; give a serial port such as "
                         f"/dev/ttyUSB0 or '{EMULATOR_PORT}'")
    begin(args)
    emulator = None
    port = args.port
    if port == EMULATOR_PORT:
        from ikbench.hw.emulator import Emulator

        emulator = Emulator(config, plan.poses_motor_deg[0])
        port = emulator.start()
        print(f"emulator on {port}: {len(config.motors)} servos at the first pose")

    stop = threading.Event()
    previous = _install_sigint(stop)
    try:
        result = execute(plan, port, approach=args.approach,
                         approach_speed_deg_s=args.approach_speed,
                         start_tolerance_deg=args.start_tolerance, dry_run=args.dry_run,
                         record_rate_hz=args.record_rate, stop_event=stop,
                         log=lambda line: print(line, flush=True))
    except ExecutionStopped as exc:
        record = getattr(getattr(exc, "result", None), "record", None)
        if args.record and record is not None:
            try:
                _write_record(args.record, record)
            except OutputError as write_error:  # keep the report of the stop as the error
                print(f"warning: {write_error}", flush=True)
        raise
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
        if emulator is not None:
            emulator.close()
    _report(result, plan)
    if emulator is not None:
        off = np.abs(emulator.present_deg() - plan.poses_motor_deg[-1]).max()
        print(f"emulator: {len(emulator.sync_writes())} SYNC WRITEs received, "
              f"{len(emulator.violations)} limit violations"
              + ("" if result.dry_run else f"; servos off the final pose by <= {off:.2f} deg"))
        if plan.timed is not None and not result.dry_run:
            print(_goal_speeds(emulator, plan))
    if args.record and result.record is not None:
        _write_record(args.record, result.record)
    return 0


def _goal_speeds(emulator, plan) -> str:
    """The moving speeds the emulator received against the motors' limits, in words."""
    import numpy as np

    from ikbench.hw.motors import raw_to_speed

    writes = emulator.sync_writes()[-plan.n_segments:]  # the segments (after any approach)
    ids = plan.config.ids
    speeds = np.array([[raw_to_speed(w.word(i, 2)) for i in ids] for w in writes])
    use = speeds.max(axis=0) / plan.config.max_speed_deg_s
    j = int(use.argmax())
    motor = plan.config.motors[j]
    return (f"emulator: goal speeds up to {speeds.max(axis=0)[j]:.1f} deg/s ({motor.joint}, "
            f"{use[j]:.3f} of its {motor.max_speed_deg_s:g} deg/s limit; register units of "
            f"{raw_to_speed(1):.3f} deg/s, rounded up)")


def _report(result, plan) -> None:
    import numpy as np

    if result.dry_run:
        return
    error = np.abs(result.final_deg - plan.poses_motor_deg[-1])
    j = int(error.argmax())
    print(f"done: {result.segments_sent} SYNC WRITEs in {result.duration_s:.3f} s "
          f"(T = {plan.duration_s:g} s, worst send delay {result.max_late_s * 1000:.1f} ms); "
          f"final pose off by at most {error[j]:.2f} deg ({plan.config.joint_names[j]})")
    if not result.settled:
        print(f"warning: {plan.config.joint_names[j]} had not reached the final pose when "
              f"settling ended")


def _write_record(path, record) -> None:
    from ikbench.core.io import atomic_write_csv

    atomic_write_csv(path, record, float_format="%.6f")
    print(f"recorded {len(record)} present poses to {path}")


def _check(option: str, value: float, ok: bool, allowed: str) -> None:
    if not (math.isfinite(value) and ok):
        raise InputError(f"{option} {value:g}; allowed: {allowed}")


def _install_sigint(stop):
    """Make Ctrl-C set ``stop`` (the executor then holds and stops); return the previous
    handler, or None where none could be installed (not the main thread)."""
    import signal

    try:
        previous = signal.signal(signal.SIGINT, lambda *_: stop.set())
    except ValueError:
        return None
    return signal.SIG_DFL if previous is None else previous
