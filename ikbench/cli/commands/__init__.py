"""CLI subcommands, one module each, described by what they declare.

Every module here is the subcommand of its name, declaring:

- ``HELP``: one line, its entry in ``ikbench --help``;
- ``DESCRIPTION``: the paragraph of its ``--help`` (a string, or a function returning it
  where the paragraph names what only its libraries know, e.g. the methods);
- ``arguments(parser)``: adds its options to its ``argparse.ArgumentParser``;
- ``run(args)``: does the work with the parsed ``argparse.Namespace``; returns an exit code
  (None: 0);
- optionally ``DEFAULTS``: values ``run`` reads that no option of its own sets.

:func:`ikbench.cli.add_command` builds the parser from these; :mod:`ikbench.cli` discovers
the modules automatically. Import heavy libraries (torch, pinocchio, matplotlib) and the
studies inside the functions, not at module level, so ``--help`` stays fast.
"""
