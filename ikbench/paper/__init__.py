"""The paper's own material: its printed values, its claims, and ``ikbench reproduce``.

Lucny et al., *Generating and Customizing Robotic Arm Trajectories using Neural Networks*.
This package is a client of the studies: the sections it adds to their reports (Table 1 beside
``ours`` on the paper's targets, Table 2 beside the baselines, the ablation claims) are named in
``ikbench/__init__.py`` (:func:`ikbench.render.sections.name_report_section`) and imported
when such a report is written.
"""
