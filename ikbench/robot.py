"""``ikbench.robot``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.robot`` gives the module :mod:`ikbench.core.robot` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.core import robot as _module
from ikbench.core.robot import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
