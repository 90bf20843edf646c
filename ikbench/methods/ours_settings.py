"""Settings of the paper's Adam optimiser (``ours``), shared by its trajectory solvers.

:class:`AdamSettings` is read by the goal-point solver (:mod:`ikbench.methods.ours`, which
re-exports it) and the 6-D pose-path solver (:mod:`ikbench.methods.ours_frames`); it lives
here so that neither of those imports the other for it.
"""

from __future__ import annotations

from dataclasses import dataclass

from ikbench.core.losses import PAPER_WEIGHTS_TEXT, check_weights
from ikbench.methods.options import check_choice, check_positive, check_seed, option
from ikbench.methods.ours_init import INITS

DTYPES = ("float32", "float64")
STOPS = ("paper", "none")


@dataclass
class AdamSettings:
    """Settings of the paper's optimiser (CLI options from the fields made with ``option``).

    Attributes:
        lr: Adam learning rate.
        max_iterations: iteration cap.
        dtype: ``"float32"`` (paper) or ``"float64"``.
        weights: loss weights: a complete dict keyed L0..L6, or changes such as
            ``"c1=20,c6=5"`` on top of the task's (else the paper's) weights; None: none.
        stop_below: the stopping rule's loss threshold.
        median_window: the stopping rule's number of previous losses.
        history_seed: the loss history's initial value.
        progress_every: report progress every this many iterations.
        init: initial logits, ``"random"`` or ``"interpolation"``.
        seed: seed of the random initialisation.
        stop: ``"paper"`` (the stopping rule) or ``"none"`` (all ``max_iterations``).
    """

    lr: float = option(0.1, help="Adam learning rate")
    max_iterations: int = option(15000, help="iteration cap")
    dtype: str = option("float32", choices=DTYPES,
                        help="floating-point type of the optimisation")
    weights: dict | str | None = option(
        None, type=str, show_default=PAPER_WEIGHTS_TEXT,
        help="loss weights to change, e.g. c1=20,c6=5 (letters start from their own)")
    stop_below: float = 10.0
    median_window: int = 10
    history_seed: float = 1000.0
    progress_every: int = 250
    init: str = option("random", choices=INITS,
                       help="initial logits: random (the authors' code, reproduces Table 1) "
                       "or interpolation (the paper's text)")
    seed: int = option(0, help="seed of the random initialisation, in [0, 2^63)")
    stop: str = option("paper", choices=STOPS,
                       help="paper (the stopping rule: loss < 10 and above the median of the "
                       "last 10) or none (run all --max-iterations, keep the lowest loss; the "
                       "paper's letter setting)")

    def __post_init__(self):
        check_choice(self, "dtype", DTYPES)
        check_choice(self, "init", INITS)
        check_choice(self, "stop", STOPS)
        check_positive(self, "lr")
        check_positive(self, "max_iterations", integer=True)
        check_seed(self)
        check_weights(self.weights)
