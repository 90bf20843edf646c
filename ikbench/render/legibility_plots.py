"""Figures of the observers' inference over time (:mod:`ikbench.core.legibility`).

``legibility_<method>.png``: P(true goal) over time for each trajectory, the position observer
(left) and the pointing observer (right). ``legibility.png``: per method, the median over the
trajectories of P(true goal), the same two observers.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ikbench.core.legibility import POINTING_SIGMA_DEG, THRESHOLD
from ikbench.render.arm_plots import matplotlib_pyplot
from ikbench.render.palette import distinct_colors

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: Columns of the summary figure's legend (below the panels).
LEGEND_COLUMNS = 4
#: (key, panel title) of the two observers.
OBSERVERS = (("position", "position observer (fingertip path; Dragan et al. 2013)"),
             ("pointing", f"pointing observer (finger ray, sigma = {POINTING_SIGMA_DEG:g} deg)"))


def _axes_style(ax, goals: int, title: str) -> None:
    ax.axhline(THRESHOLD, color="0.4", ls="--", lw=0.8)
    ax.axhline(1.0 / goals, color="0.6", ls=":", lw=0.8)
    ax.text(0.99, 1.0 / goals, f"chance 1/{goals} ", va="bottom", ha="right", fontsize=7,
            color="0.4", transform=ax.get_yaxis_transform())
    ax.set_ylim(0.0, 1.02)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("P(true goal)")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)


def plot_method_legibility(method: str, curves: dict[str, dict[str, np.ndarray]], goals: int
                           ) -> Figure:
    """P(true goal) over time per trajectory (``curves``: id -> ``times_s``, ``position``,
    ``pointing``) of one method, with ``goals`` goals in the set."""
    plt = matplotlib_pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True)
    colours = plt.get_cmap("tab10")
    for ax, (key, title) in zip(axes, OBSERVERS):
        for k, (tid, curve) in enumerate(curves.items()):
            ax.plot(curve["times_s"], curve[key], "-", lw=1.4, color=colours(k % 10),
                    label=f"trajectory {tid}")
        _axes_style(ax, goals, title)
    axes[1].legend(fontsize=7, loc="lower right", ncol=2)
    fig.suptitle(f"{method}: how soon an observer infers the touch point among {goals} goals "
                 f"(dashed: {THRESHOLD:g})", fontsize=10)
    fig.tight_layout()
    return fig


def plot_legibility_summary(curves: dict[str, dict[str, dict[str, np.ndarray]]], goals: int
                            ) -> Figure:
    """Per method (``curves``: method -> id -> curve), the median over its trajectories of
    P(true goal) over time, for both observers."""
    plt = matplotlib_pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True)
    colours = distinct_colors(len(curves))
    styles = ["-", "--", "-.", ":"]
    for ax, (key, title) in zip(axes, OBSERVERS):
        for k, (method, by_trajectory) in enumerate(curves.items()):
            times = next(iter(by_trajectory.values()))["times_s"]
            same = [c[key] for c in by_trajectory.values() if len(c[key]) == len(times)]
            ax.plot(times, np.median(same, axis=0), styles[(k // 10) % 4], lw=1.6,
                    color=colours[k], label=f"{method} ({len(same)} trajectories)")
        _axes_style(ax, goals, title)
    fig.suptitle(f"Median P(true goal) over the trajectories, per method ({goals} goals; "
                 f"dashed: {THRESHOLD:g})", fontsize=10)
    fig.tight_layout()
    # below both panels, not over the curves (issue 64: it hid the pointing panel's)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=7, loc="upper center", ncol=LEGEND_COLUMNS,
               bbox_to_anchor=(0.5, 0.0), frameon=False)
    return fig
