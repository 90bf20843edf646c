"""``ikbench.sweep``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.sweep`` gives the module :mod:`ikbench.studies.sweep` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.studies import sweep as _module
from ikbench.studies.sweep import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
