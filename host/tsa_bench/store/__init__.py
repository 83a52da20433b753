"""Run storage: the HDF5 run file (docs/run-format.md)."""

from tsa_bench.store.hdf5 import FORMAT, FORMAT_VERSION, RunWriter

__all__ = ["FORMAT", "FORMAT_VERSION", "RunWriter"]
