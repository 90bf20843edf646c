"""``ikbench.bench``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.bench`` gives the module :mod:`ikbench.studies.bench` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.studies import bench as _module
from ikbench.studies.bench import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
