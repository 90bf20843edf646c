"""Play on the emulated bus: a trajectory solved by ours-lm, planned and sent to emulated
Dynamixel servos, as ``ikbench execute --port emulator`` does, with no robot attached.

Shows the hardware layer (docs/hardware.md): ``make_plan`` turns the poses [motor deg] into
one SYNC WRITE per segment (goal position and moving speed registers, checked against the
motors' limits); ``Emulator`` serves emulated MX servos on a pseudo-terminal that the real
dynamixel-sdk opens like a serial port; ``execute`` pings the motors, checks the start pose,
sends the segments on time, waits for the arm to settle and reports. Needs dynamixel-sdk
(``pip install 'ikbench[hw]'``). On NICO, give ``execute`` the serial port instead
(``/dev/ttyUSB0``).

Run:  python examples/play_on_emulated_bus.py     (about 10 s on 2 busy cores: start-up, then
T = 2 s and settling)
"""

import numpy as np

import ikbench
from ikbench.hw.emulator import Emulator
from ikbench.hw.executor import execute
from ikbench.hw.motors import load_motor_config
from ikbench.hw.plan import make_plan

robot = ikbench.load_robot()  # NICO's right arm: poses in motor degrees
task = ikbench.build_tasks(robot, ikbench.load_targets(robot=robot))[0]  # trajectory 1
poses_deg = ikbench.get_method("ours-lm")().solve(robot, task).poses

config = load_motor_config()  # NICO's motor ids, orientations, limits (ikbench/data/)
plan = make_plan(poses_deg, config, duration_s=2.0)
with Emulator(config, poses_deg[0]) as emulator:  # the servos start at the first pose
    result = execute(plan, emulator.port, log=lambda line: print(f"  {line}"))
    final_deg = emulator.present_deg()
print(f"{result.segments_sent} of {plan.n_segments} segments sent in {result.duration_s:.2f} s "
      f"(T = 2 s), worst send delay {result.max_late_s * 1000:.1f} ms; "
      f"{len(emulator.violations)} limit violations")
print(f"servos off the last pose by at most {np.abs(final_deg - poses_deg[-1]).max():.2f} deg")
