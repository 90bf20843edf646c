"""``ikbench.letters``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.letters`` gives the module :mod:`ikbench.core.letters` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.core import letters as _module
from ikbench.core.letters import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
