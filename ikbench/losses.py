"""``ikbench.losses``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.losses`` gives the module :mod:`ikbench.core.losses` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.core import losses as _module
from ikbench.core.losses import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
