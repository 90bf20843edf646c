"""``ikbench.batch``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.batch`` gives the module :mod:`ikbench.studies.batch` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.studies import batch as _module
from ikbench.studies.batch import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
