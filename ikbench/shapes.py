"""``ikbench.shapes``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.shapes`` gives the module :mod:`ikbench.core.shapes` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.core import shapes as _module
from ikbench.core.shapes import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
