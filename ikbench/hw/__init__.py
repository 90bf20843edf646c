"""Playing trajectories on Dynamixel servos: motor config, motion plan, executor, bus emulator.

Typical use (the executor and emulator live in their own modules: they import
dynamixel-sdk and pyserial)::

    from ikbench.hw import load_motor_config, plan_trajectory_file
    from ikbench.hw.emulator import Emulator
    from ikbench.hw.executor import execute

    config = load_motor_config()
    plan, _ = plan_trajectory_file("traj.csv", config, duration_s=2.0)
    with Emulator(config, plan.poses_motor_deg[0]) as emulator:  # or a real port name
        result = execute(plan, emulator.port)
"""

from ikbench.hw.motors import Motor, MotorConfig, load_motor_config
from ikbench.hw.plan import MotionPlan, make_plan, plan_trajectory_file

__all__ = ["MotionPlan", "Motor", "MotorConfig", "load_motor_config", "make_plan",
           "plan_trajectory_file"]
