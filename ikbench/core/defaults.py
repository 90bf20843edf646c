"""The defaults that several layers share, each defined once here.

This module imports nothing, so the command line can take its defaults from it at ``--help``
time without loading numpy or a kinematics library.
"""

#: The robot every command and function uses when none is named (NICO's right arm).
DEFAULT_ROBOT = "nico_right_arm"
#: Default duration T of a movement [s] (the paper's): the time of a trajectory CSV's last
#: row, the contract's speed limits, the motion plans of ``ikbench plan`` / ``execute``.
DEFAULT_DURATION_S = 2.0
