"""Motion profiles shared by the plan compiler (duration estimates) and the simulated device."""

from tsa_bench.motion.trapezoid import TrapezoidProfile

__all__ = ["TrapezoidProfile"]
