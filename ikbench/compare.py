"""``ikbench.compare``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.compare`` gives the module :mod:`ikbench.paper.comparison` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.paper import comparison as _module
from ikbench.paper.comparison import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
