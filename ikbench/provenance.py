"""``ikbench.provenance``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.provenance`` gives the module :mod:`ikbench.core.provenance` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.core import provenance as _module
from ikbench.core.provenance import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
