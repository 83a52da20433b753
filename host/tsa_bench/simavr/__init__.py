"""Firmware in the loop: the real firmware ELF in simavr, with the rig emulated.

The C harness lives in ``firmware/sim/``; this package starts it, serves it the
simulated plant (one plant for every simulated backend) and stops it.
"""

from tsa_bench.simavr.launcher import SimavrBench, SimavrError
from tsa_bench.simavr.plant_server import PlantServer

__all__ = ["PlantServer", "SimavrBench", "SimavrError"]
