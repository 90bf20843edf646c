"""``ikbench.commands``: a module path of ikbench 0.1, kept for old imports.

``import ikbench.commands`` gives the module :mod:`ikbench.cli.commands` itself (the same
module object); new code imports that.
"""

import sys

from ikbench.cli import commands as _module
from ikbench.cli.commands import *  # noqa: F403  (its names, for type checkers)

sys.modules[__name__] = _module
