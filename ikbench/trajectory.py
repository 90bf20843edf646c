"""``ikbench.trajectory``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.trajectory`` gives the module :mod:`ikbench.core.trajectory` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.core import trajectory as _module
from ikbench.core.trajectory import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
