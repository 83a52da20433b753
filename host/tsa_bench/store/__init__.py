"""Run storage: the HDF5 run file (docs/run-format.md), written and read back."""

from tsa_bench.store.hdf5 import FORMAT, FORMAT_VERSION, RunWriter
from tsa_bench.store.reader import REQUIRED_COLUMNS, RunFileError, read_run

__all__ = ["FORMAT", "FORMAT_VERSION", "RunWriter", "REQUIRED_COLUMNS", "RunFileError", "read_run"]
