"""``ikbench.ablation``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.ablation`` gives the module :mod:`ikbench.studies.ablation` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.studies import ablation as _module
from ikbench.studies.ablation import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
