"""The paper's own material: its printed values, its claims, and ``ikbench reproduce``.

Lucny et al., *Generating and Customizing Robotic Arm Trajectories using Neural Networks*.
This package is a client of the studies: importing it registers the sections it adds to their
reports (Table 1 beside ``ours`` on the paper's targets, Table 2 beside the baselines, the
ablation claims), lazily, without importing anything heavy.
"""

from ikbench.render.sections import add_report_section


def _run_section(**context) -> list[str]:
    from ikbench.paper.report_tables import run_section

    return run_section(**context)


def _ablation_section(**context) -> list[str]:
    from ikbench.paper.ablation_claims import ablation_section

    return ablation_section(**context)


add_report_section("run", _run_section)
add_report_section("ablation", _ablation_section)
