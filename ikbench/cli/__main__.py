"""``python -m ikbench.cli``: the ikbench command line."""

import sys

from ikbench.cli import main

sys.exit(main())
