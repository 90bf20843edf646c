"""``ikbench emulate``: an emulated Dynamixel bus on a pseudo-terminal, for use without a robot."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from ikbench.cli.options import add_robot_arguments, begin, robot_from_args
from ikbench.cli.values import INPUT_FILE, OUTPUT, Number
from ikbench.core.errors import InputError

if TYPE_CHECKING:
    from ikbench.hw.emulator import Fault

HELP = ("start emulated Dynamixel servos (Protocol 1.0) on a pseudo-terminal; prints its "
        "port")

INSTRUCTIONS = {"ping": 0x01, "read": 0x02, "write": 0x03, "*": None}


DESCRIPTION = (
    "Emulate the arm's Dynamixel MX servos (Protocol 1.0: ping, read, write, sync "
    "write; present position moving towards the goal at the moving speed) on a "
    "pseudo-terminal. Prints the port on the first line, then serves until Ctrl-C or "
    "--for seconds; pass the port to `ikbench execute --port`. "
    "Example: ikbench emulate --fault drop:5:read")


def arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--motors", metavar="FILE", type=INPUT_FILE,
                        help="motor config JSON (default: the robot's, NICO's right arm)")
    add_robot_arguments(parser)
    parser.add_argument("--pose", metavar="DEG,...",
                        help="start pose: 7 comma-separated motor angles (default: the paper's "
                        "start pose); write --pose=-24,... for a leading minus")
    parser.add_argument("--missing", type=Number("a motor id", 0, 253, integer=True),
                        action="append", default=[], metavar="ID",
                        help="a motor id that never answers, as if unplugged (repeatable)")
    parser.add_argument("--fault", action="append", default=[],
                        metavar="KIND[:ID[:INSTRUCTION[:AFTER]]]",
                        help="tamper with status packets (repeatable): KIND is drop, corrupt "
                        "(bad checksum) or error (overload bit set); ID a motor id or *; "
                        "INSTRUCTION ping, read, write or *; AFTER how many matching status "
                        "packets pass first (default 0). Example: error:31:write")
    parser.add_argument("--log", metavar="OUT.csv", type=OUTPUT,
                        help="write the packet log (t_s, direction, id, instruction, bytes, "
                        "note) when stopping")
    parser.add_argument("--for", dest="seconds", type=Number("a time [s]", 0, 7 * 86400.0,
                                                            low_open=True),
                        metavar="SECONDS",
                        help="stop after this many seconds (default: run until Ctrl-C)")


def parse_fault(text: str) -> Fault:
    """``"drop:5:read:2"`` -> :class:`ikbench.hw.emulator.Fault`."""
    from ikbench.hw.emulator import FAULT_KINDS, Fault

    parts = text.split(":")
    if parts[0] not in FAULT_KINDS or len(parts) > 4:
        raise InputError(f"--fault {text!r}: give KIND[:ID[:INSTRUCTION[:AFTER]]] with KIND one "
                         f"of {', '.join(FAULT_KINDS)}")
    kind, motor, instruction, after = parts + ["*", "*", "0"][len(parts) - 1:]
    if instruction.lower() not in INSTRUCTIONS:
        raise InputError(f"--fault {text!r}: instruction {instruction!r}; allowed: "
                         f"{', '.join(INSTRUCTIONS)}")
    try:
        motor_id = None if motor == "*" else int(motor)
        after_n = int(after)
    except ValueError:
        raise InputError(f"--fault {text!r}: ID must be an integer or *, AFTER an integer") \
            from None
    return Fault(kind, motor_id, INSTRUCTIONS[instruction.lower()], after=after_n)


def run(args: argparse.Namespace) -> int:
    import signal
    import threading

    from ikbench.core.io import atomic_write_csv, check_writable
    from ikbench.core.targets import load_targets, parse_pose
    from ikbench.hw.emulator import Emulator
    from ikbench.hw.motors import load_motor_config

    robot = robot_from_args(args)
    config = load_motor_config(args.motors, robot)
    pose = parse_pose(args.pose, robot, "--pose") if args.pose else \
        load_targets(None, robot).start_pose
    unknown = [i for i in args.missing if i not in config.ids]
    if unknown:
        raise InputError(f"--missing {unknown[0]} is not a motor id; ids: {list(config.ids)}")
    faults = [parse_fault(text) for text in args.fault]
    if args.log:
        check_writable(args.log)  # before serving, not when stopping
    begin(args)

    stop = threading.Event()
    handlers = {}
    for signum in (signal.SIGINT, signal.SIGTERM):
        try:
            handlers[signum] = signal.signal(signum, lambda *_: stop.set())
        except ValueError:
            pass
    emulator = Emulator(config, pose, missing_ids=args.missing, faults=faults)
    try:
        port = emulator.start()
        print(port, flush=True)
        print(f"emulating {len(config.motors)} servos (ids "
              f"{', '.join(str(i) for i in config.ids)}) at 1000000 baud on {port}; "
              f"run: ikbench execute TRAJ.csv --port {port}; Ctrl-C to stop", flush=True)
        stop.wait(args.seconds)
    finally:
        emulator.close()
        for signum, handler in handlers.items():
            signal.signal(signum, handler if handler is not None else signal.SIG_DFL)
    print(f"stopped: {len(emulator.log)} packets, {len(emulator.sync_writes())} SYNC WRITEs, "
          f"{len(emulator.violations)} limit violations")
    if args.log:
        atomic_write_csv(args.log, emulator.log_frame(), float_format="%.6f")
        print(f"packet log written to {args.log}")
    return 0
