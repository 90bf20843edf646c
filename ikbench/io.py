"""``ikbench.io``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.io`` gives the module :mod:`ikbench.core.io` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.core import io as _module
from ikbench.core.io import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
