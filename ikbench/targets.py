"""``ikbench.targets``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.targets`` gives the module :mod:`ikbench.core.targets` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.core import targets as _module
from ikbench.core.targets import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
