"""Progress messages of the long calls: the callback's type, its check, and where a message goes.

:func:`lpvid.identify`, :func:`lpvid.resampled` and :func:`lpvid.select`
take a ``progress`` callable; each message goes to the ``lpvid`` logger at
INFO and to that callable.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from lpvid.errors import logger

Progress = Callable[[str], Any]


def check_progress(progress: Any) -> Progress | None:
    """``progress`` if it is None or callable, else a TypeError naming the argument.

    Checked before any work: a ``progress=True`` would otherwise fail at the
    first message, after the work before it.
    """
    if progress is not None and not callable(progress):
        raise TypeError(
            f"progress: expected a callable taking one str (e.g. print) or None, "
            f"got {type(progress).__name__}"
        )
    return progress


def say(progress: Progress | None, message: str) -> None:
    """Send ``message`` to the ``lpvid`` logger (INFO) and to ``progress``."""
    logger.info(message)
    if progress is not None:
        progress(message)
