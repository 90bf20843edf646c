"""CLI subcommands, one module each.

Every module here defines ``register(subparsers)``, which adds its parser and sets
``func`` (called with the parsed ``argparse.Namespace``; returns an exit code or None).
:mod:`ikbench.cli` discovers the modules automatically. Import heavy libraries (torch,
pinocchio, matplotlib) inside the handler, not at module level, so ``--help`` stays fast.
"""

from __future__ import annotations

import argparse
from typing import TypeAlias

#: The type of ``register``'s argument (what ``ArgumentParser.add_subparsers`` returns).
Subparsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"
