"""The experiment's default folder.

It belongs in the table of :mod:`ikbench.studies.folders` (``OWN``); it stands here until the
next full regeneration of the committed results, because an edit of that module makes every
committed result stale (tests/test_result_provenance.py). ``experiment`` is no method's name,
so no run folder can take it.
"""

from __future__ import annotations

from ikbench.studies.folders import RUNS

#: ``ikbench experiment design``'s default ``--output``.
DEFAULT_OUTPUT = f"{RUNS}/experiment"
