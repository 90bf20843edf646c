"""``ikbench.kinematics``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.kinematics`` gives the module :mod:`ikbench.core.kinematics` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.core import kinematics as _module
from ikbench.core.kinematics import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
