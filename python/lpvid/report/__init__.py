"""What an identification leaves behind: the Markdown report, its figures and the model files.

The public functions of :mod:`lpvid.report.markdown` are re-exported here
(``lpvid.report.write_report`` and the others).

Modules
-------
markdown
    The reports of :func:`lpvid.identify` and :func:`lpvid.select`, key numbers.
figures
    Which figures a report has, drawn here or in worker processes.
"""

from lpvid.report.markdown import (
    REPORT_ENTRIES,
    FigurePool,
    key_numbers,
    select_numbers,
    write_report,
    write_select_report,
)

__all__ = [
    "FigurePool",
    "REPORT_ENTRIES",
    "key_numbers",
    "select_numbers",
    "write_report",
    "write_select_report",
]
