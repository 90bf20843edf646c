"""``ikbench.task``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.task`` gives the module :mod:`ikbench.core.task` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.core import task as _module
from ikbench.core.task import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
