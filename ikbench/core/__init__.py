"""The core model: robot, kinematics backends, tasks, shapes, letters, losses, metrics,
targets, trajectory files, and the file and error utilities everything else uses."""
