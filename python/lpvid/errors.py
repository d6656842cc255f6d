"""The exceptions and warnings lpvid raises, and its logger.

- :class:`SingularModelError` (an ``ArithmeticError``): a frozen model is
  singular or its response overflows at an evaluation point.
- :class:`ConvergenceWarning` (a ``UserWarning``): a fit stopped at its
  iteration limit while its cost was still falling, or the chosen model of
  :func:`lpvid.identify` is unstable between the scheduling points.
- ``logging.getLogger("lpvid")`` receives the progress of
  :func:`lpvid.identify` (INFO) and of every fit step (DEBUG).
"""

from __future__ import annotations

import logging

from lpvid._core import SingularModelError

__all__ = ["ConvergenceWarning", "SingularModelError", "logger"]

#: The logger of the package: progress at INFO, every fit step at DEBUG.
logger = logging.getLogger("lpvid")


class ConvergenceWarning(UserWarning):
    """A result that may not be what the method promises: read its message.

    Raised (as a warning) when a fit stops at its iteration limit with its
    cost still falling, and when :func:`lpvid.identify` chooses a model
    whose frozen models are unstable between the scheduling points.
    """
