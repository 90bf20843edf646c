"""``ikbench.reproduce``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.reproduce`` gives the module :mod:`ikbench.paper.reproduce` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.paper import reproduce as _module
from ikbench.paper.reproduce import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
