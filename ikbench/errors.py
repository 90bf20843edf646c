"""``ikbench.errors``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.errors`` gives the module :mod:`ikbench.core.errors` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.core import errors as _module
from ikbench.core.errors import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
