"""`python -m tsa_bench.cli ...`: the same as the `tsa-bench` command."""

from tsa_bench.cli import main

main()
