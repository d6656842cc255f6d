"""The ``lpvid`` command line: ``lpvid demo``, ``lpvid fit`` and ``lpvid select``.

Modules
-------
commands
    The parser and ``lpvid demo`` / ``lpvid fit``; its ``main`` (re-exported
    here, ``lpvid.cli:main``) is the entry point.
select_command
    ``lpvid select``.
_common
    What the commands share: one-line misuse errors, data files, bases, folders.
"""

from lpvid.cli.commands import main

__all__ = ["main"]
