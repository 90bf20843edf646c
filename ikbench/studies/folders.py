"""Where the studies write: one table of output folders, from which every command's default
``--output`` and the names a method run may not take are derived (issue 45).

Ad-hoc runs go under :data:`RUNS` (git ignores it); ``ikbench reproduce`` writes
:data:`RESULTS`. A study either writes a folder of its own inside the output directory
(:data:`WITHIN`: ``OUTPUT/compare/``, ``OUTPUT/ik/<robot>/``) or takes the output directory
itself, which then defaults to ``runs/<folder>`` (:data:`OWN`: ``runs/letters``). A method
run writes ``OUTPUT/<method>/``, so none may be named after any of these folders
(:data:`RESERVED_NAMES`).
"""

from __future__ import annotations

#: Where ad-hoc runs go by default (git ignores it).
RUNS = "runs"
#: Where ``ikbench reproduce`` writes the committed results.
RESULTS = "results"
#: study -> the folder it writes inside the output directory (``OUTPUT/<folder>/``).
WITHIN: dict[str, str] = {"compare": "compare", "cartesian": "cartesian", "ik": "ik",
                          "recommend": "recommend", "ablation": "ablation"}
#: study -> its default output directory under :data:`RUNS` (it writes there directly).
OWN: dict[str, str] = {"letters": "letters", "sweep": "sweep", "batch": "batch",
                       "dataset": "dataset", "legibility": "legibility",
                       "experiment": "experiment"}
#: Folders of the results directory that ``ikbench reproduce``'s plan names itself (the
#: throughput study, ``bench --batches``, writes ``results/scale/``).
PLANNED: tuple[str, ...] = ("scale",)
#: Folders other commands write into an output directory; no method run may take them.
RESERVED_NAMES: tuple[str, ...] = tuple(dict.fromkeys([*WITHIN.values(), *OWN.values(),
                                                       *PLANNED]))


def default_output(study: str) -> str:
    """The default ``--output`` of ``study`` (``run``, ``compare``, ``letters``, ...)."""
    return f"{RUNS}/{OWN[study]}" if study in OWN else RUNS
