"""``ikbench.run``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.run`` gives the module :mod:`ikbench.studies.run` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.studies import run as _module
from ikbench.studies.run import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
