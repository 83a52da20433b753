"""Bench configuration (configs/bench/*.yaml): backend, geometry, calibration, limits."""

from tsa_bench.bench.config import (
    BenchConfig, BenchConfigError, PositionCalibration, ResistanceCalibration, load_bench, parse_bench,
)

__all__ = ["BenchConfig", "BenchConfigError", "PositionCalibration", "ResistanceCalibration", "load_bench",
           "parse_bench"]
