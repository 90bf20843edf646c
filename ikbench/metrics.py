"""``ikbench.metrics``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.metrics`` gives the module :mod:`ikbench.core.metrics` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.core import metrics as _module
from ikbench.core.metrics import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
