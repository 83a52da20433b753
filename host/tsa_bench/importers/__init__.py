"""Measured data from other labs -> run files: `tsa-bench import` (docs/importing.md).

One module per concern: :mod:`.detect` (which format), :mod:`.text`, :mod:`.spreadsheet`,
:mod:`.matlab`, :mod:`.tdms` (readers into a :class:`.table.SourceTable`),
:mod:`.headers` (names and units in headers), :mod:`.columns` (which column goes where,
in which unit), :mod:`.values` (cell checks), :mod:`.adjust` (constants, sign, offset,
scale declared by the user; impossible values), :mod:`.clock` (time order, sample rate),
:mod:`.segments` (segments for imported runs), :mod:`.writer` (the run file) and
:mod:`.pipeline` (:func:`import_file`, the whole import).
"""

from tsa_bench.importers.errors import SUPPORTED, ImportFileError
from tsa_bench.importers.pipeline import ImportOptions, ImportSummary, import_file

__all__ = ["SUPPORTED", "ImportFileError", "ImportOptions", "ImportSummary", "import_file"]
