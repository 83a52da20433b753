"""The one error every importer raises, and the list of formats named in its messages."""

from __future__ import annotations

#: what `tsa-bench import` reads, as named in error messages
SUPPORTED = ("CSV/TSV/text (any common delimiter, decimal comma, with or without a header), "
             "Excel .xlsx, MATLAB .mat (v5 and v7.3), LabVIEW .tdms")


class ImportFileError(ValueError):
    """A source file that cannot become a run file; the message says where and what."""
