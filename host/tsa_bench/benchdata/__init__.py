"""The bench as data, below everything that uses it: calibrations, limits, the bench config.

:mod:`.limits` holds the safety limits a bench sets and a protocol may only tighten;
:mod:`.config` the :class:`BenchConfig` a bench file describes, with its sensor calibrations.
Reading and validating a bench file is :mod:`tsa_bench.bench`.
"""

from tsa_bench.benchdata.config import BenchConfig, PositionCalibration, ResistanceCalibration
from tsa_bench.benchdata.limits import Limits

__all__ = ["BenchConfig", "Limits", "PositionCalibration", "ResistanceCalibration"]
