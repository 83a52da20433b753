"""Bench files (configs/bench/*.yaml) read and validated into a :class:`~tsa_bench.benchdata.BenchConfig`."""

from tsa_bench.bench.config import load_bench, parse_bench
from tsa_bench.bench.errors import BenchConfigError

__all__ = ["BenchConfigError", "load_bench", "parse_bench"]
