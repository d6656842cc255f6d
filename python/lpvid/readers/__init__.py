"""Measured FRFs from the files engineers have: UFF 58, CSV, MATLAB frd/idfrd structs.

An experiment is described by a small TOML manifest (format: the docstring
of :meth:`lpvid.FrfData.from_files`, and docs/data.md) listing, per
scheduling value, the files measured there. :func:`read_experiment` reads
it into plain arrays; :meth:`lpvid.FrfData.from_files` makes an
:class:`~lpvid.FrfData` of them.

Modules, one concern each: :mod:`~lpvid.readers.manifest` (the TOML file),
:mod:`~lpvid.readers.uff`, :mod:`~lpvid.readers.table` (CSV) and
:mod:`~lpvid.readers.matlab` (one reader per format),
:mod:`~lpvid.readers.records` (what readers return, shared checks),
:mod:`~lpvid.readers.pairing` (which record is which output/input pair),
:mod:`~lpvid.readers.lines` (one frequency axis), :mod:`~lpvid.readers.sigma`
(sigma from coherence, variance or a relative level) and
:mod:`~lpvid.readers.experiment` (all of it for one manifest).

Errors are :class:`FileError`, a ValueError that names the manifest, the
file and the record.
"""

from lpvid.readers.experiment import Experiment, read_experiment, read_file
from lpvid.readers.records import FileError, Record
from lpvid.readers.sigma import sigma_from_coherence, sigma_from_variance, sigma_relative

__all__ = [
    "Experiment",
    "FileError",
    "Record",
    "read_experiment",
    "read_file",
    "sigma_from_coherence",
    "sigma_from_variance",
    "sigma_relative",
]
