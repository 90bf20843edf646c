"""Published single-pose IK figures shown beside ``ikbench ik``'s own, labelled as published
with their source: other machines, other protocols, not comparable one to one.

Each entry names the robot folder it belongs to (``panda``, ``ur5``, ``fetch_arm``: the chains
ikbench's runs use), the solver, the published success and time, what that time is, the
protocol the source states, and the source itself.
"""

from __future__ import annotations

from typing import NamedTuple


class Published(NamedTuple):
    """One published figure (see the module docstring); ``success_pct`` [%], ``time_ms``
    [ms]."""

    robot: str
    solver: str
    success_pct: float
    time_ms: float
    time_is: str
    protocol: str
    source: str


TRACIK_README_110 = ("TRAC-IK README at v1.1.0 (bitbucket.org/traclabs/trac_ik), table \"IK "
                     "success and average speed (for successful solves) as of v1.1.0\"")
TRACIK_README_146 = ("TRAC-IK README (bitbucket.org/traclabs/trac_ik; read from its GitHub "
                     "mirror aprotyas/trac_ik, commit 0722746), table \"as of TRAC-IK tag "
                     "v1.4.6\" (Speed mode; timings include unsuccessful runs)")
TRACIK_PROTOCOL = ("10,000 random reachable configurations, 6-D pose at 1e-5, 5 ms timeout, "
                   "every query seeded from the mid-limit pose; C++")
PICKNIK = ("PickNik ik_benchmarking, README figures (figures/success_rates.png, "
           "solve_times.png, commit 557f700)")
PICKNIK_PROTOCOL = "MoveIt 2 panda_arm, FK targets, random seeds; C++ through MoveIt"

PUBLISHED: tuple[Published, ...] = (
    Published("panda", "TRAC-IK", 100.0, 0.3, "median of the successful trials, read off "
              "the box plot (about)", PICKNIK_PROTOCOL, PICKNIK),
    Published("panda", "TRAC-IK (Speed)", 99.70, 0.38, "mean of all solves (failures "
              "included)", TRACIK_PROTOCOL, TRACIK_README_146),
    Published("ur5", "TRAC-IK", 99.8, 0.37, "mean of the successful solves",
              TRACIK_PROTOCOL, TRACIK_README_110),
    Published("fetch_arm", "TRAC-IK", 100.0, 0.23, "mean of the successful solves",
              TRACIK_PROTOCOL, TRACIK_README_110),
    Published("fetch_arm", "TRAC-IK (Speed)", 99.99, 0.26, "mean of all solves (failures "
              "included)", TRACIK_PROTOCOL, TRACIK_README_146),
)


def published_for(robot: str) -> list[Published]:
    """The published figures of the robot folder ``robot`` (none: an empty list)."""
    return [p for p in PUBLISHED if p.robot == robot]
