"""The figure of a trajectory's timings: joint speeds and fingertip speed against time.

One row per timing (``constant``, ``min-jerk``, ``topp``), on a shared time axis so their
durations compare at a glance: on the left every joint's velocity [pose units/s] with the
velocity limits dashed, on the right the fingertip's speed [mm/s] (finite differences of FK
at :data:`SAMPLES` instants; the solved poses marked).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ikbench.core.timing import Limits, TimedPath, retime
from ikbench.render.arm_plots import matplotlib_pyplot

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ikbench.core.robot import Robot

#: Instants per timing at which speeds are drawn.
SAMPLES = 1500


def timings_of(robot: Robot, poses: np.ndarray, duration_s: float, limits: Limits | None,
               topp: bool = True) -> dict[str, TimedPath]:
    """The three timings of ``poses`` (``topp`` only when ``topp`` and ``limits``)."""
    timings = {name: retime(robot, poses, name, duration_s=duration_s)
               for name in ("constant", "min-jerk")}
    if topp and limits is not None:
        timings["topp"] = retime(robot, poses, "topp", limits=limits)
    return timings


def fingertip_speed(robot: Robot, timed: TimedPath, samples: int = SAMPLES
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(t_mid_s (m-1,), speed_mm_s (m-1,)): the fingertip's speed by finite differences of FK at
    ``samples`` instants evenly over the timing."""
    t = np.linspace(0.0, timed.duration_s, samples)
    q = timed.sample(t)[0]
    tip = np.asarray(robot.fk(q).point_mm, dtype=float)
    speed = np.linalg.norm(np.diff(tip, axis=0), axis=1) / np.diff(t)
    return 0.5 * (t[1:] + t[:-1]), speed


def plot_timings(robot: Robot, timings: dict[str, TimedPath], limits: Limits | None,
                 title: str = "") -> Figure:
    """The figure (see the module doc); returns the matplotlib Figure."""
    plt = matplotlib_pyplot()
    rows = len(timings)
    fig, axes = plt.subplots(rows, 2, figsize=(11, 2.6 * rows + 0.6), sharex=True,
                             squeeze=False)
    unit = robot.unit(0) if robot.dof else "deg"
    colors = plt.get_cmap("tab10")
    for row, (name, timed) in enumerate(timings.items()):
        t = np.linspace(0.0, timed.duration_s, SAMPLES)
        qd = timed.sample(t)[1]
        left, right = axes[row]
        for j, joint in enumerate(robot.joint_names):
            left.plot(t, qd[:, j], color=colors(j % 10), lw=1.2, label=joint)
        if limits is not None:
            for j, v in enumerate(limits.velocity):
                for sign in (-1, 1):
                    left.axhline(sign * v, color=colors(j % 10), lw=0.6, ls="--", alpha=0.6)
        left.set_ylabel(f"{name}\njoint velocity [{unit}/s]")
        t_mid, speed = fingertip_speed(robot, timed)
        right.plot(t_mid, speed, color="k", lw=1.4)
        knots = np.interp(timed.times_s, t_mid, speed)
        right.plot(timed.times_s, knots, "o", ms=2.2, color="tab:red", label="solved poses")
        right.set_ylabel("fingertip speed [mm/s]")
        right.set_ylim(bottom=0.0)
        extra = f", T = {timed.duration_s:.3g} s"
        right.set_title(f"{name}{extra}", fontsize=9, loc="left")
        left.set_title(f"{name}: joint velocities (dashed: limits)", fontsize=9, loc="left")
        for ax in (left, right):
            ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=6, ncol=2, loc="upper right")
    axes[0, 1].legend(fontsize=7, loc="upper right")
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    source = f"limits: {limits.source}" if limits is not None else "no limits"
    fig.suptitle(f"{title}: timings of the same path; {source}", fontsize=8, x=0.01,
                 ha="left", y=0.995)
    fig.tight_layout(rect=(0, 0, 1, 0.975))
    return fig
