"""Trajectory methods: ``Method.solve(robot, task) -> Solution``, registered by name.

- :mod:`ikbench.methods.base`: :class:`Method`, :class:`Solution` and :func:`option`, the
  settings field that is also a CLI option;
- :mod:`ikbench.methods.registry`: the built-in methods and the ``ikbench.methods``
  entry-point group; a method whose library is missing is listed as unavailable;
- :mod:`ikbench.methods.ours` (the paper's Adam) and :mod:`ikbench.methods.ours_lm`
  (the same objective by Levenberg-Marquardt). Methods from other libraries live in
  :mod:`ikbench.baselines` (the checkout's top-level ``baselines/`` folder).
"""

from ikbench.methods.base import Method, Solution
from ikbench.methods.options import MethodOption, option
from ikbench.methods.registry import (
    available_methods,
    get_method,
    method_status,
    register,
)

__all__ = ["Method", "MethodOption", "Solution", "available_methods", "get_method",
           "method_status", "option", "register"]
