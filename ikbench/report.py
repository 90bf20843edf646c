"""``ikbench.report``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.report`` gives the module :mod:`ikbench.studies.report` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.studies import report as _module
from ikbench.studies.report import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
