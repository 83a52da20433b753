"""Output files created exclusively, never through a planted link, whole or not at all
(:mod:`tsa_bench.outputs.files`)."""

from tsa_bench.outputs.files import (
    OutputExists, create_new, open_new, publish, refuse_existing, reserve_free_name, same_file, temp_name, writing,
)

__all__ = ["OutputExists", "create_new", "open_new", "publish", "refuse_existing", "reserve_free_name", "same_file",
           "temp_name", "writing"]
