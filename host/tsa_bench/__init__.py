"""tsa-bench: bench acquisition for twisted string actuators (TSAs) of supercoiled polymer strings."""

__version__ = "0.1.0"
