"""The pointing experiment's figures (matplotlib, Agg): hit rates per cell, the incongruent
cues' split, confusion matrices and reaction times. Each function returns a Figure; the
caller saves it (``ikbench.core.io.atomic_savefig``)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ikbench.render.arm_plots import matplotlib_pyplot

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: One colour per condition.
COLORS = {"G": "tab:green", "P": "tab:blue", "GP": "tab:purple", "I": "tab:red"}


def _errors(rates: pd.Series, low: pd.Series, high: pd.Series) -> np.ndarray:
    return np.vstack([(rates - low).to_numpy(), (high - rates).to_numpy()])  # (2, n)


def hit_rates(cells: pd.DataFrame, chance: float) -> Figure:
    """Hit rate per cell with Wilson 95 % intervals, and the chance level.

    Args:
        cells: :func:`ikbench.experiment.analysis.cell_table` (its "cell" rows are drawn).
        chance: the chance level 1 / n_goals.
    """
    plt = matplotlib_pyplot()
    part = cells[cells["level"] == "cell"].reset_index(drop=True)
    fig, ax = plt.subplots(figsize=(1.0 + 0.9 * len(part), 4.0))
    x = np.arange(len(part))
    for condition, group in part.groupby("condition", sort=False):
        ax.errorbar(x[group.index], group["hit_rate"],
                    yerr=_errors(group["hit_rate"], group["hit_ci_low"], group["hit_ci_high"]),
                    fmt="o", capsize=4, color=COLORS.get(str(condition), "k"),
                    label=str(condition))
    ax.axhline(chance, color="0.4", linestyle="--", lw=1)
    ax.text(len(part) - 0.5, chance + 0.015,
            f"chance 1/{round(1 / chance)} = {100 * chance:.0f} %", ha="right", va="bottom",
            fontsize=8, color="0.3")
    ax.set_xticks(x, part["cell"])
    ax.set_xlim(-0.5, len(part) - 0.5)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("hit rate (answered trials)")
    ax.set_title("Hit rate per cell, Wilson 95 % CI", fontsize=10)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(title="condition", fontsize=8, loc="center left", bbox_to_anchor=(1.0, 0.5))
    fig.tight_layout()
    return fig


def incongruent(cells: pd.DataFrame) -> Figure:
    """Under I, per fraction: the shares of answers that follow the gaze, the pointing, or
    neither, with Wilson 95 % intervals."""
    plt = matplotlib_pyplot()
    part = cells[(cells["level"] == "cell") & (cells["condition"] == "I")].reset_index()
    kinds = (("follows_gaze", "follows gaze", "tab:red"),
             ("hit", "follows pointing", "tab:blue"), ("other", "other", "0.5"))
    fig, ax = plt.subplots(figsize=(1.5 + 1.6 * len(part), 4.0))
    x = np.arange(len(part))
    for i, (prefix, label, color) in enumerate(kinds):
        rate = part[f"{prefix}_rate"]
        ax.errorbar(x + (i - 1) * 0.22, rate,
                    yerr=_errors(rate, part[f"{prefix}_ci_low"], part[f"{prefix}_ci_high"]),
                    fmt="o", capsize=4, color=color, label=label)
    ax.set_xticks(x, [f"{c}\n(stop at {100 * f:.0f} %)" for c, f in
                      zip(part["cell"], part["fraction"])])
    ax.set_xlim(-0.6, len(part) - 0.4)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("share of answered trials")
    ax.set_title("Incongruent cues: whom do answers follow? (Wilson 95 % CI)", fontsize=10)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=8, loc="center left", bbox_to_anchor=(1.0, 0.5))
    fig.tight_layout()
    return fig


def confusion(tables: Mapping[str, pd.DataFrame]) -> Figure:
    """One heat map of target x answer counts per cell, counts annotated."""
    plt = matplotlib_pyplot()
    names = list(tables)
    columns = min(4, max(1, len(names)))
    rows = -(-len(names) // columns)
    fig, axes = plt.subplots(rows, columns, figsize=(3.1 * columns, 3.1 * rows),
                             squeeze=False)
    for ax in axes.flat[len(names):]:
        ax.set_visible(False)
    for ax, name in zip(axes.flat, names):
        table = tables[name]
        counts = table.to_numpy()
        ax.imshow(counts, cmap="Blues", vmin=0, vmax=max(1, counts.max()))
        for (i, j), value in np.ndenumerate(counts):
            if value:
                ax.text(j, i, str(value), ha="center", va="center", fontsize=7,
                        color="white" if value > 0.6 * counts.max() else "black")
        ax.set_xticks(range(len(table.columns)), [str(c) for c in table.columns], fontsize=7)
        ax.set_yticks(range(len(table.index)), [str(t) for t in table.index], fontsize=7)
        ax.set_xlabel("answer", fontsize=8)
        ax.set_ylabel("target", fontsize=8)
        ax.set_title(name, fontsize=9)
    fig.suptitle("Confusion: target x answer (answered trials; colour scaled per panel)",
                 fontsize=10)
    fig.tight_layout()
    return fig


def reaction_times(answered: pd.DataFrame, cells: Sequence[str]) -> Figure:
    """Boxes of the reaction time [s] of answered trials per cell."""
    plt = matplotlib_pyplot()
    data = [answered.loc[answered["cell"] == c, "reaction_s"].dropna().to_numpy()
            for c in cells]
    fig, ax = plt.subplots(figsize=(1.0 + 0.9 * len(cells), 4.0))
    boxes = ax.boxplot(data, patch_artist=True, widths=0.6, flierprops={"markersize": 3},
                       medianprops={"color": "k"})
    for patch, cell in zip(boxes["boxes"], cells):
        condition = cell.rstrip("0123456789")
        patch.set_facecolor(COLORS.get(condition, "0.8"))
        patch.set_alpha(0.5)
    ax.set_xticks(range(1, len(cells) + 1), list(cells))
    ax.set_ylabel("reaction time [s]")
    ax.set_title("Reaction time per cell (answered trials)", fontsize=10)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    return fig
