"""The browser viewer and the exports to other tools.

- :mod:`ikbench.viewer.export`: ``trajectory_msgs/JointTrajectory`` (JSON, YAML) and CSV in
  URDF units, for ROS controllers and MoveIt (``ikbench export``);
- :mod:`ikbench.viewer.folders`: run folders read back for the viewer;
- :mod:`ikbench.viewer.server` (scene, playback) and :mod:`ikbench.viewer.gui` (panel): the
  3-D viewer on viser (``ikbench view``; the ``[viewer]`` extra);
- :mod:`ikbench.viewer.scene`: the viewer's geometry (URDF model, configurations, frames);
- :mod:`ikbench.viewer.browser`: headless Chromium screenshots (the viewer's browser test).

Import the submodules directly; this package imports nothing heavy.
"""
