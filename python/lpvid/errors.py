"""The exceptions and warnings lpvid raises, and its logger.

Every public exception and warning class of lpvid is defined (or, for the
one the compiled core raises, re-exported) here; the modules that raise them
import them from here. This module imports no other lpvid module but the
compiled core, so that any module may import it.

The hierarchy. Each class subclasses a built-in exception, so that code
catching the built-in (``except ValueError``) catches it too::

    ArithmeticError
    └── SingularModelError     lpvid._core (Rust), re-exported here
    ValueError
    ├── FileError              also lpvid.readers.FileError
    └── CoherenceError         also lpvid.initial.CoherenceError
    UserWarning
    └── ConvergenceWarning

- :class:`SingularModelError` (an ``ArithmeticError``): a frozen model is
  singular or its response overflows at an evaluation point. Defined by the
  compiled core (``lpvid._core``), which raises it while evaluating a
  model's response (:meth:`lpvid.LpvModel.frf`, :func:`lpvid.vnls`, the
  fits, :func:`lpvid.covariance`).
- :class:`FileError` (a ``ValueError``): a measured-data file, one record
  in it, or a manifest that cannot be used; the message names the file and
  the record. Raised by the readers (:mod:`lpvid.readers`) and so by
  :meth:`lpvid.FrfData.from_files`.
- :class:`CoherenceError` (a ``ValueError``): no coherent state coordinates
  can be built for a set of local LTI models. Raised by the coherent forms
  (:mod:`lpvid.initial.coherent`) and by :func:`lpvid.smile` when no form
  works.
- :class:`ConvergenceWarning` (a ``UserWarning``): a result that may not be
  what the method promises. Issued (with :func:`warnings.warn`) when a fit
  (:func:`lpvid.fit_nls`, :func:`lpvid.fit_l21`, :func:`lpvid.l21_path`,
  :func:`lpvid.fit_time`) stopped at its iteration limit while its cost was
  still falling, when :func:`lpvid.covariance` leaves out directions besides
  the similarity transforms, and when the chosen model of
  :func:`lpvid.identify` is unstable between the scheduling points.
- ``logging.getLogger("lpvid")`` receives the progress of
  :func:`lpvid.identify` (INFO) and of every fit step (DEBUG).

The command line's misuse error (``lpvid.cli._common.Misuse``) is not here: it
is private to the ``lpvid`` commands, which turn it into a one-line message
and exit code 2, and it never reaches a caller of the library.
"""

from __future__ import annotations

import logging

from lpvid._core import SingularModelError

__all__ = ["CoherenceError", "ConvergenceWarning", "FileError", "SingularModelError", "logger"]

#: The logger of the package: progress at INFO, every fit step at DEBUG.
logger = logging.getLogger("lpvid")


class ConvergenceWarning(UserWarning):
    """A result that may not be what the method promises: read its message.

    Raised (as a warning) when a fit stops at its iteration limit with its
    cost still falling, and when :func:`lpvid.identify` chooses a model
    whose frozen models are unstable between the scheduling points.
    """


class FileError(ValueError):
    """A file, or one record in it, that cannot be used; the message names both."""


class CoherenceError(ValueError):
    """A coherent form cannot be built for these local models."""
