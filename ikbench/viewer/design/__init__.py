"""Designing a trajectory by hand (``ikbench design``): drag a point, see it re-solved and judged.

- :mod:`.designer`: :class:`~.designer.Designer`, the design re-solved (warm-started), timed
  and judged on every change; no viser, the tests drive it;
- :mod:`.kinds`: what is designed (a line, a letter, a 6-D pose path) and its points;
- :mod:`.reach`: the IK of a dragged point (reachability);
- :mod:`.criteria`: the live judgement (the task contract's criteria);
- :mod:`.save`: the targets or problem file and the run folder, as ``ikbench run`` writes them;
- :mod:`.view`: the designer in the browser (viser: gizmos, the arm, the panel).
"""
