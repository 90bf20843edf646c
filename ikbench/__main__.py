"""``python -m ikbench``: the ikbench command line."""

import sys

from ikbench.cli import main

sys.exit(main())
